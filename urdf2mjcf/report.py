"""What a conversion did: returned by :func:`urdf2mjcf.convert`."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .ir import Model, Note


@dataclass(frozen=True)
class Report:
    source: Path
    output: Path | None
    """The MJCF file written (None for in-memory compilation)."""
    robot: str
    links: int
    joints: int
    bodies: int
    geoms: int
    meshes: int
    files: tuple[Path, ...]
    """Every file written, assets included."""
    notes: tuple[Note, ...]
    model: Model | None = field(default=None, repr=False, compare=False)
    """The final intermediate representation (inertials, geoms, assets per link)."""
    compiled: Any = field(default=None, repr=False, compare=False)
    """The ``mujoco.MjModel`` that validation compiled from the files written
    (``scene.xml``, or the robot with ``scene=False``); None without validation."""
    certificate: Any = field(default=None, repr=False, compare=False)
    """The :class:`~urdf2mjcf.certify.Certificate` of the files written against the
    description (None when not computed: ``--no-validate`` without ``--verify``)."""

    def of_kind(self, kind: str) -> tuple[Note, ...]:
        return tuple(n for n in self.notes if n.kind == kind)

    @property
    def warnings(self) -> tuple[Note, ...]:
        return self.of_kind("warning")

    @property
    def repaired(self) -> tuple[Note, ...]:
        return self.of_kind("repaired")

    @property
    def estimated(self) -> tuple[Note, ...]:
        return self.of_kind("estimated")

    @property
    def decomposed(self) -> tuple[Note, ...]:
        """Decompositions computed by CoACD in this run (cache misses)."""
        return self.of_kind("decomposed")

    @property
    def primitive(self) -> tuple[Note, ...]:
        """Collision meshes that became fitted primitives (their deviation in each)."""
        return self.of_kind("primitive")

    @property
    def cached(self) -> tuple[Note, ...]:
        """Decompositions taken from the disk cache."""
        return self.of_kind("cached")

    def to_dict(self) -> dict:
        return {
            "source": str(self.source),
            "output": str(self.output) if self.output else None,
            "robot": self.robot,
            "links": self.links,
            "joints": self.joints,
            "bodies": self.bodies,
            "geoms": self.geoms,
            "meshes": self.meshes,
            "files": [str(f) for f in self.files],
            "notes": [
                {"kind": n.kind, "element": n.element, "message": n.message} for n in self.notes
            ],
            "motion_limits": self.motion_limits(),
            "certificate": (
                self.certificate.to_dict()
                if self.certificate is not None
                else {"computed": False, "why": "no validation (--no-validate) and no --verify"}
            ),
        }

    def motion_limits(self) -> dict[str, dict[str, float]]:
        """URDF 1.2's acceleration, deceleration and jerk limits by joint: what MuJoCo does
        not enforce, kept for planners (rad/s^2 and rad/s^3, or m/s^2 and m/s^3)."""
        return motion_limits(self.model)

    def summary(self) -> str:
        lines = [
            f"{self.robot}: {self.links} links, {self.joints} joints -> {self.bodies} bodies, "
            f"{self.geoms} geoms, {self.meshes} meshes"
        ]
        counts = {
            k: len(self.of_kind(k))
            for k in (
                "repaired", "estimated", "decomposed", "cached", "decimated", "excluded", "warning"
            )
        }
        extra = ", ".join(f"{v} {k}" for k, v in counts.items() if v)
        if extra:
            lines.append(f"  {extra}")
        shapes = self.collision_shapes()
        if shapes:
            lines.append(f"  collision: {shapes}")
        return "\n".join(lines)

    def collision_shapes(self) -> str:
        """``3 primitives (2 capsule, 1 box), 1 hull, 2 decomposed``: what the distinct
        collision meshes became; empty when none became primitives (a set of several
        primitives counts as its types joined by ``+``)."""
        primitive = self.of_kind("primitive")
        if not primitive:
            return ""
        kinds = Counter(n.message.split(" ", 1)[0] for n in primitive)
        ordered = sorted(kinds.items(), key=lambda kc: (-kc[1], kc[0]))  # most first
        listed = ", ".join(f"{c} {k}" for k, c in ordered)
        hulls = len(self.of_kind("hull"))
        parts = len(self.of_kind("decomposed")) + len(self.of_kind("cached"))
        words = [f"{len(primitive)} primitive{'s' if len(primitive) != 1 else ''} ({listed})"]
        if hulls:
            words.append(f"{hulls} hull{'s' if hulls != 1 else ''}")
        if parts:
            words.append(f"{parts} decomposed")
        return ", ".join(words)


MOTION_KEYS = ("acceleration", "deceleration", "jerk")
"""URDF 1.2's motion limits of a joint's ``<limit>``, which MuJoCo does not enforce."""


def motion_limits(model: Model | None) -> dict[str, dict[str, float]]:
    """Joint name -> the URDF 1.2 motion limits its description states (only those given;
    joints without any left out), in the model's joint order."""
    if model is None:
        return {}
    out = {}
    for joint in model.robot.joints:
        limit = joint.limit
        if limit is None:
            continue
        given = {k: v for k in MOTION_KEYS if (v := getattr(limit, k)) is not None}
        if given:
            out[joint.name] = given
    return out
