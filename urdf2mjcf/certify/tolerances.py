"""How close a model must be to its description for the certificate to pass.

Our conversions write every number with ``repr`` (doubles round-trip), so the
figures of a model we wrote are floating-point rounding: over example-robot-data
and the wild corpus the worst link frame is off by ~1e-15 m and ~1e-15 rad, and
masses agree to the last bit (fused bodies add masses: ~1e-16 relative). The
defaults leave many orders of magnitude of headroom above that rounding while
still catching a change anyone could make by hand (a body moved by 1 mm, an
axis turned by 0.1 degree, a mass changed in its 7th digit). The collision and
lint thresholds are those of :mod:`~urdf2mjcf.certify.collision` and
:mod:`~urdf2mjcf.certify.checks`.

Settable as ``urdf2mjcf verify --tolerance NAME=VALUE`` (``NAME`` a field
below) and through the API (``Tolerances(frame_position_m=1e-4)``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from ..errors import InputError
from . import checks as _checks
from . import collision as _collision

# The collision and lint sections' defaults are the tolerances' defaults
_HAUSDORFF_MM = float(_collision.HAUSDORFF_MM)
_HAUSDORFF_REL = float(_collision.HAUSDORFF_REL)
_VOLUME_RATIO = tuple(_collision.VOLUME_RATIO)
_INERTIA_FACTOR = float(_checks.INERTIA_FACTOR)
_PENETRATION_M = float(_checks.PENETRATION_M)
_ENERGY_GROWTH = float(_checks.ENERGY_GROWTH)


def _tol(default: float, unit: str, doc: str, high: float = 1e6) -> Any:
    return field(default=default, metadata={"unit": unit, "doc": doc, "high": high})


@dataclass(frozen=True)
class Tolerances:
    """Largest figure each check accepts (a figure above it fails the certificate)."""

    frame_position_m: float = _tol(1e-6, "m", "link frame position, worst link and configuration")
    frame_rotation_rad: float = _tol(
        1e-6, "rad", "link frame rotation angle, worst link and configuration"
    )
    joint_axis_rad: float = _tol(1e-6, "rad", "angle between a joint's axes at home")
    joint_anchor_m: float = _tol(1e-6, "m", "distance between a joint's anchors at home")
    joint_limit: float = _tol(1e-9, "rad or m", "difference of a joint limit")
    mimic: float = _tol(1e-9, "1 or rad", "difference of a mimic multiplier or offset")
    mass_relative: float = _tol(
        1e-9, "1", "body mass (and total mass) relative to the description's", high=1.0
    )
    com_m: float = _tol(1e-6, "m", "whole-robot centre of mass at home")
    dynamics_relative: float = _tol(
        1e-6, "1", "mass matrix and gravity torques relative to pinocchio's", high=1.0
    )
    collision_hausdorff_mm: float = _tol(
        _HAUSDORFF_MM, "mm", "one-sided Hausdorff distance of a link's collision geometry"
    )
    collision_hausdorff_rel: float = _tol(
        _HAUSDORFF_REL,
        "1",
        "the same, relative to the link's size (bounding-box diagonal): the larger applies",
    )
    collision_volume_ratio_min: float = _tol(
        float(_VOLUME_RATIO[0]), "1", "least collision volume / source mesh volume"
    )
    collision_volume_ratio_max: float = _tol(
        float(_VOLUME_RATIO[1]), "1", "largest collision volume / source mesh volume"
    )
    inertia_factor: float = _tol(
        _INERTIA_FACTOR, "1", "declared inertia against the mesh's at the declared mass"
    )
    penetration_m: float = _tol(_PENETRATION_M, "m", "geom interpenetration at home")
    energy_growth: float = _tol(
        _ENERGY_GROWTH, "1", "relative energy growth over a passive second from home"
    )

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"tolerance {f.name} must be a number, got {value!r}")
            if not (math.isfinite(value) and 0 <= value <= f.metadata["high"]):
                raise ValueError(
                    f"tolerance {f.name} must be a finite number from 0 to "
                    f"{f.metadata['high']:g}, got {value!r}"
                )

    @classmethod
    def names(cls) -> list[str]:
        return [f.name for f in dataclasses.fields(cls)]

    def with_values(self, pairs: Iterable[tuple[str, float]]) -> Tolerances:
        """These tolerances with ``(name, value)`` pairs set; an InputError names an
        unknown tolerance or a value out of range."""
        known = set(self.names())
        changes: dict[str, float] = {}
        for name, value in pairs:
            if name not in known:
                raise InputError(
                    f"unknown tolerance '{name}'; known: {', '.join(self.names())}",
                    element="--tolerance",
                )
            changes[name] = float(value)
        try:
            return dataclasses.replace(self, **changes)
        except ValueError as exc:
            raise InputError(str(exc), element="--tolerance") from None

    def to_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)


def markdown_table() -> str:
    """The tolerances as docs/cli.md shows them (a test checks the doc holds this)."""
    rows = ["| name | default | unit | what |", "|---|---|---|---|"]
    for f in dataclasses.fields(Tolerances):
        rows.append(f"| `{f.name}` | {f.default:g} | {f.metadata['unit']} | {f.metadata['doc']} |")
    return "\n".join(rows)


if __name__ == "__main__":  # python -m urdf2mjcf.certify.tolerances: the table for docs/cli.md
    print(markdown_table())  # noqa: T201 - a command: the table on stdout
