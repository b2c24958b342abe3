"""The actuator file (``--actuator-config FILE``): joint-name patterns to gains.

A YAML mapping with five optional sections::

    defaults:                  # design parameters of the default gains
      bandwidth_hz: 10         # (see passes/actuators.py for what each means)
      damping_ratio: 1.0
      sag_tolerance: 0.002     # rad
      sag_tolerance_linear: 0.001  # m
      drift_tolerance: 0.01    # rad/s or m/s
    classes:                   # named settings; each becomes an MJCF default class
      shoulder: {kp: 1.0e5, kv: 2000, forcerange: 330, armature: 0.1, damping: 10}
    joints:                    # fnmatch pattern -> settings, applied in file order
      "shoulder_*": {class: shoulder}
      "wrist_*": {type: position, kp: 1.0e4}
      rail: {type: velocity, kv: 500}
      "*_passive": {type: none, damping: 2}
    gravcomp: ["base_link", "arm_*"]   # or true (every moving link), or {pattern: 0.5}
    collision:                 # what collision meshes become (read by the collision pass)
      default: auto            # decompose, hull, primitive or auto, for every link
      links: {forearm: primitive}   # exact link names
      contacts: keep           # keep (no exclusion) or resolve (the contacts pass)


Keys of a ``joints`` entry or a class:

* ``type``: ``position``, ``velocity``, ``motor`` (alias ``effort``) or
  ``none`` (no actuator, even if ros2_control declares one);
* ``kp`` (N m/rad or N/m), ``kv`` (N m s/rad or N s/m): servo gains, >= 0;
* ``forcerange``: a positive number L for [-L, L], or ``[lo, hi]``; ``0`` for
  no force limit;
* ``ctrlrange``: ``[lo, hi]`` in the actuator's command unit;
* ``armature`` (kg m^2 or kg), ``damping``, ``frictionloss``: joint
  properties, >= 0;
* ``bandwidth_hz`` (> 0), ``damping_ratio`` (> 0): per-joint design parameters;
* ``class``: a name from ``classes`` (joints entries only); the entry's own
  keys override the class's.

Patterns are ``fnmatch`` patterns, case-sensitive, over URDF joint (and, for
``gravcomp``, link) names. Every joint a ``joints`` pattern matches is
actuated unless the merged ``type`` is ``none``; the type comes from the
entries, else from the URDF, else ``position``. Fixed joints are skipped; a
mimic follower takes the joint keys (armature, damping, frictionloss) but no
actuator. Entries apply in file order: a later entry overrides the keys it
sets. A pattern that matches nothing is a warning, not an error, so one file
can serve variants of a robot. Numbers may be written ``1e5`` (PyYAML reads that as a string;
it is accepted). Anything else -- bad YAML, an unknown section or key, a value
of the wrong kind, an unknown class -- raises :class:`~urdf2mjcf.errors.InputError`
naming the file and the key.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ... import schema, untrusted
from ...errors import InputError
from ...ir import COLLISION_SHAPES, CONTACTS

ACTUATOR_TYPES = ("position", "velocity", "motor", "none")
_TYPE_ALIASES = {"effort": "motor"}
RESERVED_CLASSES = ("main", "visual", "collision")
"""Default class names emit already uses (``main`` is MuJoCo's root class)."""

DESIGN_KEYS = (
    "bandwidth_hz",
    "damping_ratio",
    "sag_tolerance",
    "sag_tolerance_linear",
    "drift_tolerance",
)
_SECTIONS = ("defaults", "classes", "joints", "gravcomp", "collision")
MAX_MAGNITUDE = 1e12
"""Largest magnitude of any number in the file (gains, ranges, armature): far above
any real actuator (kp of 1e12 N m/rad), far below what overflows MuJoCo's arithmetic."""


@dataclass(frozen=True)
class ActuatorSpec:
    """What one source says about one joint's actuator; None means "not said"."""

    type: str | None = None
    """``position``, ``velocity``, ``motor`` or ``none``."""
    kp: float | None = None
    kv: float | None = None
    forcerange: tuple[float, float] | None = None
    """N m or N; ``(0, 0)`` means explicitly unlimited."""
    ctrlrange: tuple[float | None, float | None] | None = None
    """Command range; an end may be None (ros2_control gave only ``min`` or ``max``)."""
    armature: float | None = None
    damping: float | None = None
    frictionloss: float | None = None
    actuator_class: str | None = None
    bandwidth_hz: float | None = None
    damping_ratio: float | None = None

    def over(self, base: ActuatorSpec) -> ActuatorSpec:
        """``base`` with every field this spec sets replaced."""
        changes = {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if getattr(self, f.name) is not None
        }
        return dataclasses.replace(base, **changes)


@dataclass(frozen=True)
class ActuatorFile:
    """A parsed, validated actuator file."""

    path: Path
    defaults: Mapping[str, float] = field(default_factory=dict)
    """Design parameters (:data:`DESIGN_KEYS`) replacing the config's."""
    classes: Mapping[str, ActuatorSpec] = field(default_factory=dict)
    joints: tuple[tuple[str, ActuatorSpec], ...] = ()
    """(pattern, settings with its class expanded under them), in file order."""
    gravcomp: bool | tuple[tuple[str, float], ...] = False
    """True: every moving link; else (link pattern, fraction) pairs."""
    collision_default: str | None = None
    """``collision: default``: the collision shape of every link (None: not said)."""
    collision_links: Mapping[str, str] = field(default_factory=dict)
    """``collision: links``: link name -> collision shape."""
    collision_contacts: str | None = None
    """``collision: contacts``: ``keep`` or ``resolve`` (:data:`CONTACTS`; None: not said)."""


def load(path: Path) -> ActuatorFile:
    """Read and validate an actuator file."""
    # regular files only, within the yaml size limit (a FIFO would block, /dev/zero fill memory)
    try:
        raw = untrusted.read_file(path, "yaml", what="file")
    except InputError as exc:
        raise InputError(f"cannot read actuator file: {exc.detail}", file=path) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError("actuator file is not UTF-8 text", file=path) from None
    return parse(text, Path(path))


def parse(text: str, path: Path) -> ActuatorFile:
    """Validate the YAML ``text`` of the actuator file ``path``."""
    try:
        data, lines = schema.parse(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc)
        shown = untrusted.excerpt(problem)
        raise InputError(f"not valid YAML{where}: {shown}", file=path) from None
    if data is None:
        return ActuatorFile(path)
    r = _Reader(path, lines)
    top = r.mapping(data, "the document")
    r.only(top, _SECTIONS, "the document")
    defaults = r.mapping(top.get("defaults", {}), "defaults")
    r.only(defaults, DESIGN_KEYS, "defaults")
    defaults = {k: r.number(v, f"defaults: {k}", positive=True) for k, v in defaults.items()}
    classes: dict[str, ActuatorSpec] = {}
    for name, body in r.mapping(top.get("classes", {}), "classes").items():
        if name in RESERVED_CLASSES:
            raise r.fail(
                f"class name {name!r} is reserved (used by the MJCF defaults); choose another",
                f"classes: {name}",
            )
        classes[str(name)] = r.spec(body, f"classes: {name}", allow_class=False)
        classes[str(name)] = dataclasses.replace(classes[str(name)], actuator_class=str(name))
    joints: list[tuple[str, ActuatorSpec]] = []
    for pattern, body in r.mapping(top.get("joints", {}), "joints").items():
        spec = r.spec(body, f"joints: {pattern}", allow_class=True)
        if spec.actuator_class is not None:
            if spec.actuator_class not in classes:
                known = untrusted.excerpt(", ".join(sorted(classes)), 120) or "none defined"
                raise r.fail(
                    f"unknown class {_show(spec.actuator_class)} (classes: {known})",
                    f"joints: {pattern}: class",
                )
            spec = spec.over(classes[spec.actuator_class])
        joints.append((str(pattern), spec))
    gravcomp = r.gravcomp(top.get("gravcomp", False))
    collision = r.mapping(top.get("collision", {}), "collision")
    r.only(collision, ("default", "links", "contacts"), "collision")
    default = collision.get("default")
    shape_default = r.shape(default, "collision: default") if default is not None else None
    shape_links = {
        name: r.shape(value, f"collision: links: {name}")
        for name, value in r.mapping(collision.get("links", {}), "collision: links").items()
    }
    contacts = collision.get("contacts")
    if contacts is not None and contacts not in CONTACTS:
        raise r.fail(
            f"unknown value {_show(contacts)}; valid: {', '.join(CONTACTS)}", "collision: contacts"
        )
    return ActuatorFile(
        path, defaults, classes, tuple(joints), gravcomp, shape_default, shape_links, contacts
    )


class _Reader:
    """Validation helpers that name the file, the key and its line in every error
    (:class:`urdf2mjcf.schema.Source`, as for recipes and waypoints files)."""

    def __init__(self, path: Path, lines: dict[schema.Key, int] | None = None):
        self.path = path
        self.source = schema.Source(path, lines or {})

    def fail(self, message: str, where: str) -> InputError:
        return self.source.fail(where, message)  # type: ignore[return-value]

    def mapping(self, value: Any, where: str) -> dict:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.fail(f"expected a mapping, got {_kind(value)}", where)
        for key in value:
            if not isinstance(key, (str, int, float)) or isinstance(key, bool):
                raise self.fail(f"key {_show(key)} must be a name", where)
        return {str(k): v for k, v in value.items()}

    def only(self, value: dict, allowed: tuple[str, ...], where: str) -> None:
        for key in value:
            if key not in allowed:
                raise self.fail(
                    f"unknown key {_show(key)}; valid keys: {', '.join(allowed)}", where
                )

    def real(self, value: Any, where: str) -> float:
        """A finite number of any sign, at most :data:`MAX_MAGNITUDE` (strings such as
        ``1e5`` included)."""
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.fail(f"expected a number, got {_kind(value)}", where)
        try:
            x = untrusted.parse_number(value)  # the one number reader: decimal text only
        except untrusted.BadNumber as exc:
            raise self.fail(f"expected a number: {exc}", where) from None
        if abs(x) > MAX_MAGNITUDE:
            raise self.fail(
                f"{x:g} is out of range (at most {MAX_MAGNITUDE:g} in magnitude)", where
            )
        return x

    def number(self, value: Any, where: str, *, positive: bool = False) -> float:
        """A finite number >= 0 (> 0 when ``positive``)."""
        x = self.real(value, where)
        if positive and not x > 0:
            raise self.fail(f"must be > 0, got {x!r}", where)
        if x < 0:
            raise self.fail(f"must be >= 0, got {x!r}", where)
        return x

    def pair(self, value: Any, where: str) -> tuple[float, float]:
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise self.fail(f"expected [lo, hi], got {_show(value)}", where)
        lo, hi = (self.real(v, where) for v in value)
        if not lo < hi:
            raise self.fail(f"expected lo < hi, got [{lo!r}, {hi!r}]", where)
        return lo, hi

    def spec(self, body: Any, where: str, *, allow_class: bool) -> ActuatorSpec:
        body = self.mapping(body, where)
        allowed = (
            ("type", "kp", "kv", "forcerange", "ctrlrange", "armature", "damping")
            + ("frictionloss", "bandwidth_hz", "damping_ratio")
            + (("class",) if allow_class else ())
        )
        self.only(body, allowed, where)
        values: dict[str, Any] = {}
        for key, value in body.items():
            at = f"{where}: {key}"
            if key == "type":
                kind = _TYPE_ALIASES.get(str(value), str(value))
                if kind not in ACTUATOR_TYPES or not isinstance(value, str):
                    valid = ", ".join((*ACTUATOR_TYPES, *_TYPE_ALIASES))
                    raise self.fail(f"unknown type {_show(value)}; valid: {valid}", at)
                values["type"] = kind
            elif key == "class":
                if not isinstance(value, str) or not value:
                    raise self.fail(f"expected a class name, got {_show(value)}", at)
                values["actuator_class"] = value
            elif key == "forcerange":
                if isinstance(value, (list, tuple)):
                    values["forcerange"] = self.pair(value, at)
                else:
                    limit = self.number(value, at)
                    values["forcerange"] = (-limit, limit) if limit > 0 else (0.0, 0.0)
            elif key == "ctrlrange":
                values["ctrlrange"] = self.pair(value, at)
            elif key in ("bandwidth_hz", "damping_ratio"):
                values[key] = self.number(value, at, positive=True)
            else:
                values[key] = self.number(value, at)
        return ActuatorSpec(**values)

    def shape(self, value: Any, where: str) -> str:
        """A collision shape name (:data:`~urdf2mjcf.ir.COLLISION_SHAPES`)."""
        if not isinstance(value, str) or value not in COLLISION_SHAPES:
            valid = ", ".join(COLLISION_SHAPES)
            raise self.fail(f"unknown collision shape {_show(value)}; valid: {valid}", where)
        return value

    def gravcomp(self, value: Any) -> bool | tuple[tuple[str, float], ...]:
        where = "gravcomp"
        if isinstance(value, bool):
            return value
        if isinstance(value, str):
            value = [value]
        if isinstance(value, (list, tuple)):
            out = []
            for item in value:
                if not isinstance(item, str) or not item:
                    raise self.fail(f"expected link-name patterns, got {_show(item)}", where)
                out.append((item, 1.0))
            return tuple(out)
        if isinstance(value, dict):
            out = []
            for pattern, fraction in self.mapping(value, where).items():
                f = self.number(fraction, f"{where}: {pattern}")
                if f > 1.0:
                    raise self.fail(
                        f"fraction must be in [0, 1], got {f!r}", f"gravcomp: {pattern}"
                    )
                out.append((pattern, f))
            return tuple(out)
        raise self.fail(
            f"expected true/false, a list of link patterns or {{pattern: fraction}}, "
            f"got {_kind(value)}",
            where,
        )


def _kind(value: Any) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, (list, tuple)):
        return "a list"
    return _show(value)


def _show(value: Any) -> str:
    """A value from the file as an error line may quote it: short, one line, printable."""
    return untrusted.excerpt(repr(value), 60)
