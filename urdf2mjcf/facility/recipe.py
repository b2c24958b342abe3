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
key is one of its flags (or a top-level field such as ``gravcomp``), a dotted
key any field (``jitter.ctb_yaw=0.1``). A key the recipe does not know is an
error naming the valid ones.
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
SECTIONS = ("components", "flags", "placements", "ctb", "jitter", "simulation", "rocks")
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


def _names(keys: Any) -> str:
    return ", ".join(sorted(str(k) for k in keys))


def _pose(value: Any, path: Path | None, key: str) -> Pose2D:
    if not isinstance(value, Mapping) or "xyz" not in value:
        raise fail(path, key, "a pose needs xyz: [x, y, z] (and optionally yaw)")
    unknown = set(value) - {"xyz", "yaw"}
    if unknown:
        raise fail(path, key, f"unknown key(s) {_names(unknown)}; valid: xyz, yaw")
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


def _set_flag(flags: Any, name: str, text: str, path: Path | None, where: str) -> None:
    """A --set of a flag: one the recipe declares, a boolean flag only true or false."""
    known = flags if isinstance(flags, Mapping) else {}
    if name not in known:
        valid = _names(known) or "none (the recipe has no flags)"
        raise fail(path, where, f"unknown flag '{name}'; the recipe's flags: {valid}")
    if isinstance(known[name], bool) and not isinstance(_parse_scalar(text), bool):
        raise fail(path, where, f"'{text}' is not true or false")


def apply_sets(data: dict, sets: Mapping[str, str], path: Path | None) -> dict:
    """``--set`` edits: a bare key is a flag (or a top-level field), a dotted key any field."""
    data = copy.deepcopy(data)
    for key, text in sets.items():
        where = f"--set {key}"
        value = _parse_scalar(text)
        parts = key.split(".")
        if len(parts) == 1 and (key not in TOP_KEYS or key in (data.get("flags") or {})):
            parts = ["flags", key]
        if parts[0] not in TOP_KEYS or not all(parts):
            valid = f"a flag, or a field under {', '.join(TOP_KEYS)}"
            raise fail(path, where, f"unknown key '{parts[0]}'; valid: {valid}")
        if len(parts) == 1 and key in SECTIONS:
            raise fail(path, where, f"'{key}' is a section; set one of its fields ({key}.NAME)")
        if parts[0] == "flags":
            if len(parts) != 2:
                raise fail(path, where, "a flag is one name (hatch_4040=true)")
            _set_flag(data.get("flags"), parts[1], text, path, where)
        target = data
        for part in parts[:-1]:
            target = target.setdefault(part, {})
            if not isinstance(target, dict):
                raise fail(path, where, f"'{part}' is not a section")
        target[parts[-1]] = value
    return data


def _section(data: Mapping, key: str, path: Path | None) -> dict:
    """An optional mapping section (absent or empty: {})."""
    value = data.get(key)
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise fail(path, key, f"'{value}' is not a mapping of keys to values")
    return {str(k): v for k, v in value.items()}


def _text(data: Mapping, key: str, path: Path | None, *, required: bool = False) -> str | None:
    value = data.get(key)
    if value is None or value == "":
        if required:
            raise fail(path, key, "is required")
        return None
    if not isinstance(value, str):
        raise fail(path, key, f"'{value}' is not text")
    return value


def _flags(data: Mapping, path: Path | None) -> dict:
    flags = _section(data, "flags", path)
    for name, value in flags.items():
        if not isinstance(value, (str, bool, int, float)):
            message = "a flag is one value: true, false, a number or a name"
            raise fail(path, f"flags.{name}", message)
    return flags


def _component(spec: Any, path: Path | None, where: str) -> dict:
    if not isinstance(spec, Mapping) or not {"asset", "standalone"} <= set(spec):
        raise fail(path, where, "needs asset and standalone (and optionally flag, prefix, roles)")
    unknown = set(spec) - set(COMPONENT_KEYS)
    if unknown:
        valid = ", ".join(COMPONENT_KEYS)
        raise fail(path, where, f"unknown key(s) {_names(unknown)}; valid: {valid}")
    out = {}
    for key in COMPONENT_KEYS:
        if key in spec:
            value = spec[key]
            optional = key in ("flag", "roles")
            if not (isinstance(value, str) or (optional and value is None)):
                raise fail(path, f"{where}.{key}", f"'{value}' is not text")
            out[key] = value
    return out


def parse_recipe(data: Any, path: Path | None) -> Recipe:
    if not isinstance(data, Mapping):
        raise fail(path, "recipe", "a recipe is a mapping of keys to values")
    unknown = set(data) - set(TOP_KEYS)
    if unknown:
        raise fail(path, _names(unknown), f"unknown key; valid: {', '.join(TOP_KEYS)}")
    name = _text(data, "name", path, required=True)
    xacro = _text(data, "xacro", path, required=True)
    description = _text(data, "description", path) or ""
    actuator_config = _text(data, "actuator_config", path)
    gravcomp = data.get("gravcomp", False)
    if not isinstance(gravcomp, bool):
        raise fail(path, "gravcomp", f"'{gravcomp}' is not true or false")
    flags = _flags(data, path)
    placements = {
        where: _pose(value, path, f"placements.{where}")
        for where, value in _section(data, "placements", path).items()
    }
    ctb = _pose(data["ctb"], path, "ctb") if data.get("ctb") else None
    jitter = {}
    for key, value in _section(data, "jitter", path).items():
        if key not in JITTER_KEYS:
            raise fail(path, f"jitter.{key}", f"unknown key; valid: {', '.join(JITTER_KEYS)}")
        jitter[key] = number(value, path, f"jitter.{key}")
        if jitter[key] < 0:
            raise fail(path, f"jitter.{key}", "a jitter range is >= 0")
    simulation = _section(data, "simulation", path)
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
    components = {
        cname: _component(spec, path, f"components.{cname}")
        for cname, spec in _section(data, "components", path).items()
    }
    return Recipe(
        name=str(name),
        components=components,
        path=path,
        xacro=str(xacro),
        flags=flags,
        placements=placements,
        ctb=ctb,
        jitter=jitter,
        simulation=simulation,
        actuator_config=actuator_config,
        gravcomp=gravcomp,
        description=description,
        rocks=parse_rocks(data.get("rocks"), path),
    )


def read_yaml(path: Path, what: str) -> Any:
    """A YAML file's data; an InputError naming the file (and the line) when it is
    missing, unreadable, not text or not YAML."""
    try:
        return yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror}", file=path) from None
    except UnicodeDecodeError:
        raise InputError(f"cannot read {what}: not a text file", file=path) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"{what} is not valid YAML: {problem}", file=path, element=where) from None


def load_recipe(path: Path, sets: Mapping[str, str] | None = None) -> Recipe:
    data = read_yaml(path, "recipe")
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise fail(Path(path), "recipe", "a recipe is a mapping of keys to values")
    return parse_recipe(apply_sets(dict(data), sets or {}, path), Path(path))
