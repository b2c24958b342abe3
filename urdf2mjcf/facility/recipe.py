"""Facility recipes: which top-level xacro, which components it can hold, its flags,
where things stand, how uncertain their poses are, and how to simulate.

A recipe is a YAML file (see ``recipes/`` and docs/facility.md)::

    name: my-lab
    xacro: worlds/my_lab.urdf.xacro
    components: components/my_lab.yaml   # or the table itself, as a mapping
    flags: {arm: true, shelf: false}
    placements:                       # component -> pose on the floor
      shelf: {xyz: [1.5, -0.5, 0], yaw: 0.5}
      box: {xyz: [0.8, 0.8, 0.1], yaw: 1.57}
    jitter:                           # uniform +- ranges, applied with --seed
      default: {position: 0.02, yaw: 0.0349}   # m, rad: every placed component
      box: {position: 0.05, yaw: 0.26}         # its own ranges
      arm: false                               # never moves (the reference)
    simulation: {timestep: 0.002, integrator: implicitfast, solver: Newton}
    actuator_config: config/actuators.yaml
    rocks: {count: 24, seed: 3, area: [-30, 30, -30, 30]}   # optional, see scatter.py
    collision:                        # what collision meshes become (optional)
      default: auto                   # decompose (absent: the default), hull, primitive, auto
      links: {gripper_link: hull}     # per link, named as in the facility

The component table maps each component's name to ``{asset, standalone, flag,
prefix, roles, free, attach, calibration, ...}`` (see :class:`Component`); the name
is also the stem of its pose arguments in the xacro (``shelf_x``, ``shelf_y``,
``shelf_z``, ``shelf_yaw``) and its key under ``placements`` and ``jitter``.
A component with ``attach`` (its standalone xacro's arguments; ``$NAME`` is the
recipe flag NAME) is compiled once on its own and attached into the
top-level xacro's world at its placement
(``urdf2mjcf.facility.attach``); one without is part of the top-level xacro. The
builder knows no component by name: everything it does with one comes from this table.

A relative path names the user's own file beside the recipe if there is one, else
ours under the facility root (the folder holding ``facility/`` and ``recipes/``; see
``root.py``). ``--set KEY=VALUE`` edits a recipe: a bare key is one of its flags (or
a top-level field such as ``gravcomp``), a dotted key any field
(``jitter.default.yaw=0.1``). A key the recipe does not know is an error naming the
valid ones; every error names the file, the key and its line.
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ..ir import COLLISION_SHAPES
from ..schema import Refused, Source, load
from ..schema import parse as parse_yaml
from ..untrusted import excerpt, is_folder_name
from .fiducials import Fiducial, check_unique, parse_fiducials
from .noise import parse_noise
from .pose import Pose2D
from .root import data_path
from .scatter import parse_rocks
from .values import (
    ANGLE_MAX,
    IMPRATIO_MAX,
    ITERATIONS_MAX,
    JITTER_POSITION_MAX,
    JITTER_YAW_MAX,
    LENGTH_MAX,
    TIMESTEP_RANGE,
    flag_range,
    number,
    whole,
)

COMPONENT_KEYS = (
    "asset", "standalone", "flag", "prefix", "roles", "free", "fiducials", "mechanisms",
    "attach", "pose", "calibration",
)
OPTIONAL_FILES = ("flag", "roles", "mechanisms", "calibration")
"""Text keys of a component that may also be null (none)."""
ATTACH_ARGS_MAX = 64
"""Arguments of one attached component's standalone xacro."""
TOP_KEYS = (
    "components",
    "name",
    "description",
    "xacro",
    "flags",
    "placements",
    "jitter",
    "simulation",
    "actuator_config",
    "gravcomp",
    "rocks",
    "noise",
    "collision",
)
SECTIONS = (
    "components", "flags", "placements", "jitter", "simulation", "rocks", "noise", "collision"
)
COLLISION_KEYS = ("default", "links")
LINK_NAME_MAX = 255
"""Characters of a link name under ``collision.links``."""
JITTER_KEYS = ("position", "yaw")
JITTER_DEFAULT = "default"
SIMULATION_KEYS = ("timestep", "integrator", "solver", "cone", "iterations", "impratio")
JITTER_MAX = {"position": JITTER_POSITION_MAX, "yaw": JITTER_YAW_MAX}
SIMULATION_RANGES = {  # key: (low, high, low_open); iterations is a whole number
    "timestep": (*TIMESTEP_RANGE, False),
    "impratio": (0.0, IMPRATIO_MAX, True),
}
SIMULATION_CHOICES = {
    "integrator": ("Euler", "RK4", "implicit", "implicitfast"),
    "solver": ("PGS", "CG", "Newton"),
    "cone": ("pyramidal", "elliptic"),
}


@dataclass(frozen=True)
class Component:
    """An asset the facility may contain, and how to compile it on its own."""

    asset: str
    """Package folder name (components/<asset>/ in the output)."""
    standalone: str
    """Standalone xacro (a world link plus the macro), a path as the recipe's others."""
    flag: str | None = None
    """The recipe flag that includes it (None: always, when it has a placement)."""
    prefix: str = ""
    """Prefix of its link and joint names in the facility xacro."""
    roles: str | None = None
    """A robot's roles file (names a runner looks up); a component with roles is a
    robot and is compiled with the recipe's actuator file."""
    free: bool = False
    """A free body (it moves in the simulation): under --seed its offset is drawn after
    those of the fixed components, so adding one never changes theirs."""
    mechanisms: str | None = None
    """A YAML file (a path as the recipe's others) declaring the asset's mechanisms: each
    latch, the joint it holds and its locked and released values, names without the
    prefix; facility.json lists them prefixed (``manifest.py``)."""
    fiducials: tuple[Fiducial, ...] = ()
    """AprilTags on its links (``urdf2mjcf.facility.fiducials``), ids unique in the table."""
    attach: Mapping[str, Any] | None = None
    """The xacro arguments its standalone description is compiled with, when it is
    attached into the world at its placement (``urdf2mjcf.facility.attach``): names to
    values, ``$NAME`` the recipe flag NAME. None: the top-level xacro holds it."""
    pose: Pose2D | None = None
    """Where an attached component stands when the recipe has no placement for it (as a
    xacro argument's default)."""
    calibration: str | None = None
    """A calibration file (``urdf2mjcf calibrate``'s ``calibration.yaml``, a path as the
    recipe's others) applied to the component's own conversion, as ``urdf2mjcf SOURCE
    --calibration FILE``: attached components only (that conversion is what the scene
    holds)."""

    def attach_args(self, flags: Mapping[str, Any]) -> dict[str, str]:
        """:attr:`attach` as xacro arguments, flags substituted. A flag the recipe does not
        set leaves its argument out: the standalone's default, as a xacro argument's."""
        out = {}
        for name, value in (self.attach or {}).items():
            if isinstance(value, str) and value.startswith("$"):
                if value[1:] not in flags:
                    continue
                value = flags[value[1:]]
            out[name] = ("true" if value else "false") if isinstance(value, bool) else str(value)
        return out


Ranges = Mapping[str, float] | None
"""A component's jitter: {position, yaw} (m, rad), or None: it never moves."""


@dataclass(frozen=True)
class Recipe:
    name: str
    path: Path | None
    """The YAML file (None for a recipe built in code)."""
    xacro: str
    flags: Mapping[str, Any]
    placements: Mapping[str, Pose2D]
    jitter: Mapping[str, Ranges] = field(default_factory=dict)
    """``default`` and component names -> ranges (see :func:`jitter_ranges`)."""
    simulation: Mapping[str, Any] = field(default_factory=dict)
    actuator_config: str | None = None
    gravcomp: bool = False
    description: str = ""
    components: Mapping[str, Component] = field(default_factory=dict)
    """Component name -> how to place and compile it; empty: the world has none."""
    rocks: Mapping[str, Any] = field(default_factory=dict)
    """A seeded scatter of rocks (``urdf2mjcf.facility.scatter``); empty: none."""
    noise: Mapping[str, Any] = field(default_factory=dict)
    """Sensor noise per channel (``urdf2mjcf.facility.noise``): settings, or False (off)."""
    collision: Mapping[str, Any] = field(default_factory=dict)
    """What collision meshes become: ``default`` (a shape of ``COLLISION_SHAPES``; absent:
    the converter's default) and ``links`` (facility link name -> shape); empty: the
    converter's default everywhere (see :meth:`link_collision`)."""

    def link_collision(self, links: Collection[str], prefix: str = "") -> dict[str, str]:
        """The ``collision.links`` entries that apply to a description with ``links``: a
        link of that name, or, for a component compiled on its own, the link that is
        that name without the component's ``prefix`` (its name in the facility is
        ``prefix`` + its own)."""
        out: dict[str, str] = {}
        for name, shape in (self.collision.get("links") or {}).items():
            if name in links:
                out[name] = shape
            elif prefix and name.startswith(prefix) and name[len(prefix) :] in links:
                out[name[len(prefix) :]] = shape
        return out

    def jitter_ranges(self, name: str) -> Ranges:
        """A component's jitter ranges: its own, else the default (missing ones are 0)."""
        given = self.jitter.get(name, self.jitter.get(JITTER_DEFAULT) or {})
        if given is None:
            return None
        return {k: float(given.get(k, 0.0)) for k in JITTER_KEYS}

    def enabled(self, name: str) -> bool:
        """Whether the component is in the facility: its flag (if any) is on."""
        comp = self.components.get(name)
        flag = comp.flag if comp else None
        if flag is None:
            return True
        value = self.flags.get(flag, False)
        return value not in (False, "false", "none", None, 0)

    def places(self, name: str) -> bool:
        """Whether the facility will hold the component: placed and enabled."""
        return name in self.placed() and self.enabled(name)

    def placed(self) -> dict[str, Pose2D]:
        """The placements, with the table's default pose of an attached component the
        recipe does not place."""
        out = dict(self.placements)
        for name, comp in self.components.items():
            if name not in out and comp.attach is not None and comp.pose is not None:
                out[name] = comp.pose
        return out


def _names(keys: Any) -> str:
    return ", ".join(sorted(str(k) for k in keys))


def _pose(value: Any, src: Source, key: str) -> Pose2D:
    if not isinstance(value, Mapping) or "xyz" not in value:
        raise src.fail(key, "a pose needs xyz: [x, y, z] (and optionally yaw)")
    unknown = set(value) - {"xyz", "yaw"}
    if unknown:
        raise src.fail(key, f"unknown key(s) {_names(unknown)}; valid: xyz, yaw")
    xyz = value["xyz"]
    if not isinstance(xyz, (list, tuple)) or len(xyz) != 3:
        raise src.fail(f"{key}.xyz", "needs three numbers")
    xyz_m = tuple(
        number(v, src, f"{key}.xyz.{i}", low=-LENGTH_MAX, high=LENGTH_MAX)
        for i, v in enumerate(xyz)
    )
    yaw = number(value.get("yaw", 0.0), src, f"{key}.yaw", low=-ANGLE_MAX, high=ANGLE_MAX)
    return Pose2D(xyz_m, yaw)  # type: ignore[arg-type]


SET_VALUE_MAX = 4096
"""Characters of one ``--set`` value: a flag, a number, a short list or a path."""


def _parse_scalar(text: str, src: Source, where: str) -> Any:
    """A --set value as our YAML reader reads a file's (true, 0.5, [1, 2], text); no
    anchors or aliases (a value on a command line needs none, and an alias bomb would
    expand). Text that is not YAML is text; a key given twice, or a value YAML 1.1 and
    1.2 read differently (``yes``, ``1:30``, ``0x10``), is an error, as in a file."""
    if len(text) > SET_VALUE_MAX or "&" in text or "*" in text:
        return text  # read as text, which every numeric field then refuses
    try:
        return parse_yaml(text)[0]
    except Refused as exc:
        problem = excerpt(exc.problem or "", 120)
        raise src.fail(where, f"'{excerpt(text, 60)}': {problem}") from None
    except yaml.YAMLError:
        return text


def _set_flag(flags: Any, name: str, value: Any, src: Source, where: str) -> None:
    """A --set of a flag: one the recipe declares, a boolean flag only true or false."""
    known = flags if isinstance(flags, Mapping) else {}
    if name not in known:
        valid = _names(known) or "none (the recipe has no flags)"
        raise src.fail(where, f"unknown flag '{excerpt(name, 60)}'; the recipe's flags: {valid}")
    if isinstance(known[name], bool) and not isinstance(value, bool):
        raise src.fail(where, f"'{excerpt(str(value), 60)}' is not true or false")


def apply_sets(data: dict, sets: Mapping[str, str], src: Source) -> dict:
    """``--set`` edits: a bare key is a flag (or a top-level field), a dotted key any field.
    The keys set are marked in ``src``: an error in their values names no line of the file."""
    data = copy.deepcopy(data)
    for key, text in sets.items():
        where = f"--set {key}"
        value = _parse_scalar(text, src, where)
        parts = key.split(".")
        if len(parts) == 1 and (key not in TOP_KEYS or key in (data.get("flags") or {})):
            parts = ["flags", key]
        if parts[0] not in TOP_KEYS or not all(parts):
            valid = f"a flag, or a field under {', '.join(TOP_KEYS)}"
            raise src.fail(where, f"unknown key '{parts[0]}'; valid: {valid}")
        if len(parts) == 1 and key in SECTIONS:
            raise src.fail(where, f"'{key}' is a section; set one of its fields ({key}.NAME)")
        if parts[0] == "flags":
            if len(parts) != 2:
                raise src.fail(where, "a flag is one name (--set NAME=VALUE)")
            _set_flag(data.get("flags"), parts[1], value, src, where)
        target = data
        for part in parts[:-1]:
            target = target.setdefault(part, {})
            if not isinstance(target, dict):
                raise src.fail(where, f"'{part}' is not a section")
        target[parts[-1]] = value
        src.overridden.add(tuple(parts))
    return data


def _flags(data: Mapping, src: Source) -> dict:
    flags = src.mapping(data.get("flags"), "flags")
    for name, value in flags.items():
        if not isinstance(value, (str, bool, int, float)):
            message = "a flag is one value: true, false, a number or a name"
            raise src.fail(f"flags.{name}", message)
        _check_flag_number(name, value, src)
    return flags


def _is_numeric(value: Any) -> bool:
    """Whether a flag's value is a number to the xacro that reads it (text such as
    "-5" or "nan" too), not a name, true or false."""
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, float)):
        return True
    try:
        float(value)
    except (TypeError, ValueError, OverflowError):
        return False
    return True


def _check_flag_number(name: str, value: Any, src: Source) -> None:
    """A numeric flag (a xacro argument) is finite, within its own range if it has one
    (``values.FLAG_RANGES``: a stiffness >= 0, ...), else within +-FLAG_MAX."""
    if _is_numeric(value):
        low, high, low_open = flag_range(name)
        number(value, src, f"flags.{name}", low=low, high=high, low_open=low_open)


def _check_flag_names(flags: Mapping, components: Mapping[str, Component], src: Source) -> None:
    """A flag is a xacro argument: it must not be one the builder sets from another
    section (a simulation option, the rocks, a pose), whose checks it would bypass."""
    poses = {f"{c}_{axis}": c for c in components for axis in ("x", "y", "z", "yaw")}
    for name in flags:
        if name in SIMULATION_KEYS:
            raise src.fail(f"flags.{name}", f"is a simulation option: set simulation.{name}")
        if name == "rocks":
            raise src.fail("flags.rocks", "the rocks are a section: set rocks.count, ...")
        if name in poses:
            message = f"is a pose argument of '{poses[name]}': set placements.{poses[name]}"
            raise src.fail(f"flags.{name}", message)


def _component(spec: Any, src: Source, where: str) -> Component:
    if not isinstance(spec, Mapping) or not {"asset", "standalone"} <= set(spec):
        message = "needs asset and standalone (and optionally flag, prefix, roles, free, fiducials)"
        raise src.fail(where, message)
    src.known(spec, COMPONENT_KEYS, where)
    out: dict[str, Any] = {}
    for key in COMPONENT_KEYS:
        if key not in spec:
            continue
        value = spec[key]
        if key == "free":
            if not isinstance(value, bool):
                raise src.fail(f"{where}.{key}", f"'{value}' is not true or false")
        elif key == "fiducials":
            value = parse_fiducials(value, src, f"{where}.{key}")
        elif key == "attach":
            value = _attach(value, src, f"{where}.{key}")
        elif key == "pose":
            value = _pose(value, src, f"{where}.{key}")
        elif not (isinstance(value, str) or (key in OPTIONAL_FILES and value is None)):
            raise src.fail(f"{where}.{key}", f"'{value}' is not text")
        out[key] = value
    if out.get("calibration") is not None and out.get("attach") is None:
        message = "applies to an attached component's own conversion: give it attach"
        raise src.fail(f"{where}.calibration", message)
    return Component(**out)


_ARG_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")


def _attach(value: Any, src: Source, where: str) -> dict[str, Any]:
    """A component's ``attach``: xacro argument names to one value each (text, a
    number, true or false; ``$NAME`` the recipe's flag NAME)."""
    if value is None:
        value = {}
    args = src.mapping(value, where)
    if len(args) > ATTACH_ARGS_MAX:
        raise src.fail(where, f"at most {ATTACH_ARGS_MAX} arguments")
    for name, arg in args.items():
        if not isinstance(name, str) or not _ARG_NAME.fullmatch(name):
            raise src.fail(where, f"'{excerpt(str(name), 40)}' is not a xacro argument name")
        if not isinstance(arg, (str, bool, int, float)):
            message = "an argument is one value: text, a number, true or false"
            raise src.fail(f"{where}.{name}", message)
        if isinstance(arg, float) and not math.isfinite(arg):
            raise src.fail(f"{where}.{name}", f"'{arg}' is not a finite number")
        if isinstance(arg, str) and len(arg) > SET_VALUE_MAX:
            raise src.fail(f"{where}.{name}", f"longer than {SET_VALUE_MAX} characters")
    return dict(args)


def _components(data: Mapping, src: Source, root: Path | None) -> dict[str, Component]:
    """The recipe's component table: a mapping, or a YAML file holding one (a path as
    the recipe's others), so that the recipes of one world share one table."""
    value = data.get("components")
    table_src = src
    if isinstance(value, str):
        recipe = Path(src.file) if src.file is not None else None
        beside = recipe.resolve().parent if recipe is not None else Path.cwd()
        file = data_path(root, recipe, value) if root is not None else beside / value
        value, table_src = load(file, "component table")
        prefix = ""
    else:
        prefix = "components."
    table = table_src.mapping(value, prefix.rstrip(".") or "components", "a component table")
    out = {name: _component(spec, table_src, prefix + name) for name, spec in table.items()}
    check_unique(((n, c.fiducials) for n, c in out.items()), table_src, prefix)
    return out


def _jitter(data: Mapping, src: Source, components: Mapping[str, Component]) -> dict:
    section = src.mapping(data.get("jitter"), "jitter")
    src.known(section, [JITTER_DEFAULT, *components], "jitter")
    out: dict[str, Ranges] = {}
    for name, value in section.items():
        where = f"jitter.{name}"
        if value is False or value is None:
            if name == JITTER_DEFAULT:
                raise src.fail(where, "the default ranges are a mapping {position, yaw}")
            out[name] = None
            continue
        ranges = src.mapping(value, where, "{position, yaw} or false (never moves)")
        src.known(ranges, JITTER_KEYS, where)
        out[name] = {}
        for key, v in ranges.items():
            # a +- range: >= 0, and bounded so that a pose stays a pose
            x = number(v, src, f"{where}.{key}", low=0.0, high=JITTER_MAX[key])
            out[name][key] = x  # type: ignore[index]
    return out


def _simulation(data: Mapping, src: Source) -> dict:
    simulation = src.mapping(data.get("simulation"), "simulation")
    for key, value in simulation.items():
        where = f"simulation.{key}"
        if key not in SIMULATION_KEYS:
            raise src.fail(where, f"unknown key; valid: {', '.join(SIMULATION_KEYS)}")
        if key in SIMULATION_CHOICES:
            if str(value) not in SIMULATION_CHOICES[key]:
                valid = ", ".join(SIMULATION_CHOICES[key])
                raise src.fail(where, f"'{value}' is not one of {valid}")
        elif key == "iterations":
            whole(value, src, where, low=1, high=ITERATIONS_MAX)
        else:
            low, high, low_open = SIMULATION_RANGES[key]
            number(value, src, where, low=low, high=high, low_open=low_open)
    return simulation


def _shape(value: Any, src: Source, where: str) -> str:
    if not isinstance(value, str) or value not in COLLISION_SHAPES:
        shown = excerpt(str(value), 20)
        raise src.fail(where, f"'{shown}' is not one of {', '.join(COLLISION_SHAPES)}")
    return value


def _collision(data: Mapping, src: Source) -> dict:
    """``collision: {default: SHAPE, links: {LINK: SHAPE}}``: what the conversion makes
    of collision meshes (``urdf2mjcf.passes.collision``); the links are checked against
    the facility when it is built."""
    section = src.mapping(data.get("collision"), "collision")
    src.known(section, COLLISION_KEYS, "collision")
    out: dict[str, Any] = {}
    if section.get("default") is not None:
        out["default"] = _shape(section["default"], src, "collision.default")
    links = src.mapping(section.get("links"), "collision.links", "a mapping of links to shapes")
    if links:
        for name in links:
            if not name or len(name) > LINK_NAME_MAX:
                raise src.fail(f"collision.links.{name}", "is not a link name")
        out["links"] = {n: _shape(v, src, f"collision.links.{n}") for n, v in links.items()}
    return out


def parse_recipe(
    data: Any, path: Path | None | Source, root: Path | None = None
) -> Recipe:
    """A recipe from its data; ``path`` names the file (or is its :class:`Source`, which
    gives errors their lines); ``root`` is where a component table not beside it lies."""
    src = path if isinstance(path, Source) else Source(path)
    path = Path(src.file) if src.file is not None else None
    if not isinstance(data, Mapping):
        raise src.fail("recipe", "a recipe is a mapping of keys to values")
    src.known({str(k): v for k, v in data.items()}, TOP_KEYS)
    name = src.text(data.get("name"), "name", required=True)
    if not is_folder_name(name):  # it names the build folder: build/<name>
        raise src.fail(
            "name",
            f"'{excerpt(str(name))}' is not a plain name: letters, digits, '-', '_' and '.' "
            "(not only dots), at most 255 characters",
        )
    xacro = src.text(data.get("xacro"), "xacro", required=True)
    description = src.text(data.get("description"), "description") or ""
    actuator_config = src.text(data.get("actuator_config"), "actuator_config")
    gravcomp = data.get("gravcomp", False)
    if not isinstance(gravcomp, bool):
        raise src.fail("gravcomp", f"'{gravcomp}' is not true or false")
    flags = _flags(data, src)
    placements = {
        where: _pose(value, src, f"placements.{where}")
        for where, value in src.mapping(data.get("placements"), "placements").items()
    }
    components = _components(data, src, root)
    for where in placements:
        if where not in components:
            valid = _names(components) or "none (the recipe has no components)"
            raise src.fail(f"placements.{where}", f"unknown component; the recipe's: {valid}")
    _check_flag_names(flags, components, src)
    jitter = _jitter(data, src, components)
    simulation = _simulation(data, src)
    return Recipe(
        name=str(name),
        components=components,
        path=path,
        xacro=str(xacro),
        flags=flags,
        placements=placements,
        jitter=jitter,
        simulation=simulation,
        actuator_config=actuator_config,
        gravcomp=gravcomp,
        description=description,
        rocks=parse_rocks(data.get("rocks"), src),
        noise=parse_noise(data.get("noise"), src),
        collision=_collision(data, src),
    )


def read_yaml(path: Path, what: str) -> Any:
    """A YAML file's data; an InputError naming the file (and the line) when it is
    missing, unreadable, not text or not YAML."""
    return load(path, what)[0]


def load_recipe(
    path: Path, sets: Mapping[str, str] | None = None, root: Path | None = None
) -> Recipe:
    """The recipe in ``path`` with the ``--set`` edits ``sets``; ``root``: the facility
    root, where paths the recipe names are looked up when they are not beside it."""
    data, src = load(path, "recipe")
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise src.fail("recipe", "a recipe is a mapping of keys to values")
    return parse_recipe(apply_sets(dict(data), sets or {}, src), src, root)
