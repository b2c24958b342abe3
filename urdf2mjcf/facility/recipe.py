"""Facility recipes: which top-level xacro, its flags, where things stand,
how uncertain their poses are, and how to simulate.

A recipe is a YAML file (see ``recipes/imetro.yaml``)::

    name: imetro
    xacro: facility/worlds/imetro/urdf/imetro_facility.urdf.xacro
    flags: {robot: imetro, hatch_4060: true, hatch_4040: false, ...}
    placements:                       # component -> pose on the floor
      trainer: {xyz: [-1.2, 1.6, 0], yaw: -1.5708}
    ctb: {xyz: [0.8, 0.8, 0.13], yaw: 1.5708}
    jitter:                           # uniform +- ranges, applied with --seed
      position: 0.02                  # m, mockups
      yaw: 0.0175                     # rad, mockups
      ctb_position: 0.05
      ctb_yaw: 0.2618
    simulation: {timestep: 0.002, integrator: implicitfast, solver: Newton}
    actuator_config: facility/robots/imetro_robot/config/actuators.yaml
    rocks: {count: 24, seed: 3, area: [-30, 30, -30, 30]}   # optional, see scatter.py

A relative path names the user's own file beside the recipe if there is
one, else ours under the facility root (the folder holding ``facility/`` and
``recipes/``; see ``root.py``). ``--set KEY=VALUE`` edits a recipe: a bare
key is a flag, a dotted key any field (``jitter.ctb_yaw=0.1``).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ..errors import InputError
from .scatter import parse_rocks
from .values import fail, number

COMPONENT_KEYS = ("asset", "standalone", "flag", "prefix", "roles")
TOP_KEYS = (
    "components",
    "name",
    "description",
    "xacro",
    "flags",
    "placements",
    "ctb",
    "jitter",
    "simulation",
    "actuator_config",
    "gravcomp",
    "rocks",
)
JITTER_KEYS = ("position", "yaw", "ctb_position", "ctb_yaw")
SIMULATION_KEYS = ("timestep", "integrator", "solver", "cone", "iterations", "impratio")
SIMULATION_CHOICES = {
    "integrator": ("Euler", "RK4", "implicit", "implicitfast"),
    "solver": ("PGS", "CG", "Newton"),
    "cone": ("pyramidal", "elliptic"),
}


@dataclass(frozen=True)
class Pose2D:
    """A pose on the floor: position (m) and yaw about +z (rad)."""

    xyz: tuple[float, float, float]
    yaw: float = 0.0


@dataclass(frozen=True)
class Recipe:
    name: str
    path: Path | None
    """The YAML file (None for a recipe built in code)."""
    xacro: str
    flags: Mapping[str, Any]
    placements: Mapping[str, Pose2D]
    ctb: Pose2D | None
    jitter: Mapping[str, float] = field(default_factory=dict)
    simulation: Mapping[str, Any] = field(default_factory=dict)
    actuator_config: str | None = None
    gravcomp: bool = False
    description: str = ""
    components: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    """Component name -> {asset, standalone, flag, prefix, roles}; empty: the iMETRO table."""
    rocks: Mapping[str, Any] = field(default_factory=dict)
    """A seeded scatter of rocks (``urdf2mjcf.facility.scatter``); empty: none."""


def _pose(value: Any, path: Path | None, key: str) -> Pose2D:
    if not isinstance(value, Mapping) or "xyz" not in value:
        raise fail(path, key, "a pose needs xyz: [x, y, z] (and optionally yaw)")
    unknown = set(value) - {"xyz", "yaw"}
    if unknown:
        raise fail(path, key, f"unknown key(s) {', '.join(sorted(unknown))}; valid: xyz, yaw")
    xyz = value["xyz"]
    if not isinstance(xyz, (list, tuple)) or len(xyz) != 3:
        raise fail(path, f"{key}.xyz", "needs three numbers")
    return Pose2D(
        tuple(number(v, path, f"{key}.xyz") for v in xyz),  # type: ignore[arg-type]
        number(value.get("yaw", 0.0), path, f"{key}.yaw"),
    )


def _parse_scalar(text: str) -> Any:
    """A --set value as YAML would read it (true, 0.5, [1, 2], text)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def apply_sets(data: dict, sets: Mapping[str, str], path: Path | None) -> dict:
    """``--set`` edits: bare keys are flags, dotted keys address any field."""
    data = copy.deepcopy(data)
    for key, text in sets.items():
        value = _parse_scalar(text)
        parts = key.split(".")
        if len(parts) == 1:
            parts = ["flags", key]
        target = data
        for part in parts[:-1]:
            target = target.setdefault(part, {})
            if not isinstance(target, dict):
                raise fail(path, key, f"'{part}' is not a section")
        target[parts[-1]] = value
    return data


def parse_recipe(data: Any, path: Path | None) -> Recipe:
    if not isinstance(data, Mapping):
        raise fail(path, "recipe", "a recipe is a mapping of keys to values")
    unknown = set(data) - set(TOP_KEYS)
    if unknown:
        raise fail(path, ", ".join(sorted(unknown)), f"unknown key; valid: {', '.join(TOP_KEYS)}")
    for required in ("name", "xacro"):
        if not data.get(required):
            raise fail(path, required, "is required")
    flags = dict(data.get("flags") or {})
    placements = {
        name: _pose(value, path, f"placements.{name}")
        for name, value in (data.get("placements") or {}).items()
    }
    ctb = _pose(data["ctb"], path, "ctb") if data.get("ctb") else None
    jitter = {}
    for key, value in (data.get("jitter") or {}).items():
        if key not in JITTER_KEYS:
            raise fail(path, f"jitter.{key}", f"unknown key; valid: {', '.join(JITTER_KEYS)}")
        jitter[key] = number(value, path, f"jitter.{key}")
        if jitter[key] < 0:
            raise fail(path, f"jitter.{key}", "a jitter range is >= 0")
    simulation = dict(data.get("simulation") or {})
    for key, value in simulation.items():
        where = f"simulation.{key}"
        if key not in SIMULATION_KEYS:
            raise fail(path, where, f"unknown key; valid: {', '.join(SIMULATION_KEYS)}")
        if key in SIMULATION_CHOICES:
            if str(value) not in SIMULATION_CHOICES[key]:
                valid = ", ".join(SIMULATION_CHOICES[key])
                raise fail(path, where, f"'{value}' is not one of {valid}")
        elif number(value, path, where) <= 0:
            raise fail(path, where, "must be > 0")
    components = {}
    for cname, spec in (data.get("components") or {}).items():
        where = f"components.{cname}"
        if not isinstance(spec, Mapping) or not {"asset", "standalone"} <= set(spec):
            raise fail(
                path, where, "needs asset and standalone (and optionally flag, prefix, roles)"
            )
        unknown = set(spec) - set(COMPONENT_KEYS)
        if unknown:
            raise fail(
                path,
                where,
                f"unknown key(s) {', '.join(sorted(unknown))}; valid: {', '.join(COMPONENT_KEYS)}",
            )
        components[str(cname)] = {k: spec.get(k) for k in COMPONENT_KEYS if k in spec}
    return Recipe(
        name=str(data["name"]),
        components=components,
        path=path,
        xacro=str(data["xacro"]),
        flags=flags,
        placements=placements,
        ctb=ctb,
        jitter=jitter,
        simulation=simulation,
        actuator_config=data.get("actuator_config"),
        gravcomp=bool(data.get("gravcomp", False)),
        description=str(data.get("description", "")),
        rocks=parse_rocks(data.get("rocks"), path),
    )


def load_recipe(path: Path, sets: Mapping[str, str] | None = None) -> Recipe:
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise InputError(f"cannot read recipe: {exc.strerror}", file=path) from None
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML: {exc}".splitlines()[0], file=path) from None
    return parse_recipe(apply_sets(data or {}, sets or {}, path), Path(path))
