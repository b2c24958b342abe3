"""The demo's waypoints file, checked before anything moves.

:func:`read_waypoints` checks the file's shape (known keys, step kinds, types,
required fields); :func:`check_names` checks it against a loaded facility
(bodies, joints, the robot's sites and cameras, vector lengths). Each error
names the file and the element (``steps[3] 'approach'.position``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import mujoco

from ..errors import FacilityError
from ..schema import Source, load

Check = Callable[[Any, str, "Waypoints"], None]


class Waypoints:
    """Where errors point: the file and, for a file read here, the key's line."""

    def __init__(self, path: Path | None, source: Source | None = None):
        self.path = path
        self.source = source or Source(path or "waypoints", error=FacilityError)

    def fail(self, where: str, message: str) -> FacilityError:
        return self.source.fail(where, message)  # type: ignore[return-value]


def _number(value: Any, where: str, w: Waypoints, *, low: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise w.fail(where, f"'{value}' is not a number")
    if low is not None and value < low:
        raise w.fail(where, f"must be >= {low:g}")
    return float(value)


def number(value: Any, where: str, w: Waypoints) -> None:
    _number(value, where, w)


def positive(value: Any, where: str, w: Waypoints) -> None:
    if _number(value, where, w) <= 0:
        raise w.fail(where, "must be > 0")


def nonnegative(value: Any, where: str, w: Waypoints) -> None:
    _number(value, where, w, low=0)


def count(value: Any, where: str, w: Waypoints) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise w.fail(where, f"'{value}' is not a whole number >= 0")


def flag(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, bool):
        raise w.fail(where, f"'{value}' is not true or false")


def name(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, str) or not value:
        raise w.fail(where, f"'{value}' is not a name")


def numbers(n: int | None = None) -> Check:
    def check(value: Any, where: str, w: Waypoints) -> None:
        if not isinstance(value, list) or (n is not None and len(value) != n):
            raise w.fail(where, f"needs a list of {n} numbers" if n else "needs a list of numbers")
        for i, v in enumerate(value):
            _number(v, f"{where}[{i}]", w)

    return check


def pairs(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, list):
        raise w.fail(where, "needs a list of [body glob, body glob] pairs")
    for i, p in enumerate(value):
        if not (isinstance(p, list) and len(p) == 2 and all(isinstance(s, str) for s in p)):
            raise w.fail(f"{where}[{i}]", "needs a pair of body-name globs [a, b]")


def joint_values(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, Mapping) or not value:
        raise w.fail(where, "needs a mapping of joint name to value")
    for k, v in value.items():
        _number(v, f"{where}.{k}", w)


def action(value: Any, where: str, w: Waypoints) -> None:
    if value not in ("open", "close"):
        try:
            _number(value, where, w)
        except FacilityError:
            raise w.fail(where, f"'{value}' is not open, close or an opening (m)") from None


def check_spec(value: Any, where: str, w: Waypoints) -> None:
    _mapping(value, where, w, {"joint_above_deg": _joint_above, "bag_lifted": number})


def _joint_above(value: Any, where: str, w: Waypoints) -> None:
    if not (isinstance(value, list) and len(value) == 2 and isinstance(value[0], str)):
        raise w.fail(where, "needs [joint name, degrees]")
    _number(value[1], f"{where}[1]", w)


def placements(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, Mapping) or not value:
        raise w.fail(where, "needs a mapping of component to {xyz, yaw}")
    for comp, pose in value.items():
        _mapping(pose, f"{where}.{comp}", w, {"xyz": numbers(3), "yaw": number}, ("xyz", "yaw"))


def section(keys: dict[str, Check], required: tuple[str, ...] = ()) -> Check:
    def check(value: Any, where: str, w: Waypoints) -> None:
        _mapping(value, where, w, keys, required)

    return check


def _mapping(
    value: Any, where: str, w: Waypoints, keys: dict[str, Check], required: tuple[str, ...] = ()
) -> None:
    if not isinstance(value, Mapping):
        raise w.fail(where, "needs a mapping of keys to values")
    unknown = sorted(str(k) for k in value if k not in keys)
    if unknown:
        raise w.fail(f"{where}.{unknown[0]}", f"unknown key; valid: {', '.join(keys)}")
    for key in required:
        if key not in value:
            raise w.fail(f"{where}.{key}", "is required")
    for key, v in value.items():
        keys[key](v, f"{where}.{key}", w)


COMMON: dict[str, Check] = {
    "name": name,
    "kind": name,
    "contacts": pairs,
    "carried": flag,
    "settle": flag,
    "settle_timeout": positive,
    "speed": positive,
    "snapshot": flag,
    "check": check_spec,
    "duration": positive,
}
KINDS: dict[str, tuple[dict[str, Check], tuple[str, ...]]] = {
    "joints": (
        {"q": numbers(), "arm": numbers(), "set": joint_values, "relative_to": name}, ()
    ),
    "pose": (
        {
            "position": numbers(3),
            "frame": name,
            "z": numbers(3),
            "x": numbers(3),
            "x_sign_free": flag,
            "orientation_xyzw": numbers(4),
            "site": name,
            "joint_space": flag,
            "seed": numbers(),
            "relative_to": name,
        },
        ("position",),
    ),
    "relative": ({"tool": numbers(3), "world": numbers(3)}, ()),
    "hinge": (
        {
            "joint": name,
            "steps": count,
            "step_deg": number,
            "hold_orientation": flag,
            "step_time": positive,
        },
        ("joint",),
    ),
    "gripper": ({"action": action, "seconds": nonnegative}, ("action",)),
    "look": ({"camera": name, "min_pixels": count, "border_px": count}, ()),
    "localize": ({"component": name, "camera": name, "min_tags": count}, ("component",)),
    "wait": ({"seconds": nonnegative}, ("seconds",)),
}
TOP: dict[str, Check] = {
    "robot": section({"site": name, "vmax": numbers(), "ik_weights": numbers()}),
    "bag": section({"body": name, "geom": name}, ("body", "geom")),
    "stowage": section({"body": name, "inside": numbers(3)}, ("body", "inside")),
    "perception": section({"size": numbers(2)}),
    "view": section(
        {"lookat": numbers(3), "distance": positive, "azimuth": number, "elevation": number}
    ),
    "final_wait": nonnegative,
    "nominal": placements,
    "contacts": pairs,
    "steps": lambda v, where, w: None,  # checked step by step below
}


def _step_at(i: int, step: Any) -> str:
    label = step.get("name") if isinstance(step, Mapping) else None
    return f"steps[{i}]" + (f" '{label}'" if isinstance(label, str) else "")


def check_shape(spec: Any, path: Path | None, source: Source | None = None) -> dict:
    """``spec`` (a waypoints file's data) checked for keys, kinds and types; ``source``:
    the file's key lines (:func:`urdf2mjcf.schema.load`), for errors that name them."""
    w = Waypoints(path, source)
    if not isinstance(spec, Mapping):
        raise w.fail("waypoints", "a waypoints file is a mapping with steps, bag and stowage")
    _mapping(spec, "waypoints", w, TOP, ("bag", "stowage", "steps"))
    steps = spec["steps"]
    if not isinstance(steps, list) or not steps:
        raise w.fail("steps", "needs a non-empty list of steps")
    seen: set[str] = set()
    for i, step in enumerate(steps):
        at = _step_at(i, step)
        if not isinstance(step, Mapping):
            raise w.fail(at, "a step is a mapping with name and kind")
        for key in ("name", "kind"):
            if key not in step:
                raise w.fail(f"{at}.{key}", "is required")
            name(step[key], f"{at}.{key}", w)
        if step["kind"] not in KINDS:
            raise w.fail(f"{at}.kind", f"unknown kind '{step['kind']}'; valid: {', '.join(KINDS)}")
        if step["name"] in seen:
            raise w.fail(f"{at}.name", "another step has this name")
        seen.add(step["name"])
        keys, required = KINDS[step["kind"]]
        _mapping(step, at, w, {**COMMON, **keys}, required)
        if ("z" in step) != ("x" in step):
            raise w.fail(at, "give both tool axes z and x, or neither")
    return dict(spec)


def read_waypoints(path: str | Path) -> dict:
    """A waypoints file, its shape checked (:func:`check_shape`)."""
    data, source = load(Path(path), "waypoints file")
    source.error = FacilityError
    return check_shape(data, Path(path), source)


def check_names(spec: Mapping, path: Path | None, fac: Any) -> None:
    """Every name and vector length in ``spec`` against the loaded facility ``fac``
    (a :class:`urdf2mjcf.runner.load.Facility`)."""
    w = Waypoints(path)
    m, robot = fac.model, fac.robot
    n = len(robot.joints)
    obj = mujoco.mjtObj

    def exists(kind: mujoco.mjtObj, value: str, where: str) -> None:
        if mujoco.mj_name2id(m, kind, value) < 0:
            raise w.fail(where, f"the facility has no {kind.name[6:].lower()} named '{value}'")

    def length(value: list, want: int, where: str) -> None:
        if len(value) != want:
            raise w.fail(where, f"has {len(value)} values; the robot needs {want}")

    rs = spec.get("robot", {})
    site = rs.get("site", "grasp")
    if site not in robot.sites:
        raise w.fail("robot.site", f"'{site}' is not a site role; roles: {', '.join(robot.sites)}")
    for key in ("vmax", "ik_weights"):
        if key in rs:
            length(rs[key], n, f"robot.{key}")
    exists(obj.mjOBJ_BODY, spec["bag"]["body"], "bag.body")
    exists(obj.mjOBJ_GEOM, spec["bag"]["geom"], "bag.geom")
    exists(obj.mjOBJ_BODY, spec["stowage"]["body"], "stowage.body")
    for i, step in enumerate(spec["steps"]):
        at = _step_at(i, step)
        for key, want in (("q", n), ("seed", n), ("arm", n - 2)):
            if key in step:
                length(step[key], want, f"{at}.{key}")
        for joint in step.get("set", {}):
            if joint not in robot.joint_names:
                valid = ", ".join(robot.joint_names)
                message = f"'{joint}' is not a joint of the robot; joints: {valid}"
                raise w.fail(f"{at}.set.{joint}", message)
        frame = step.get("frame", "world")
        if frame not in ("world", "handle"):
            exists(obj.mjOBJ_BODY, frame, f"{at}.frame")
        if step["kind"] == "hinge":
            exists(obj.mjOBJ_JOINT, step["joint"], f"{at}.joint")
        if "joint_above_deg" in step.get("check", {}):
            exists(obj.mjOBJ_JOINT, step["check"]["joint_above_deg"][0], f"{at}.check")
        if "site" in step and step["site"] not in robot.sites:
            roles = ", ".join(robot.sites)
            raise w.fail(f"{at}.site", f"'{step['site']}' is not a site role; roles: {roles}")
        camera = step.get("camera", "wrist")
        if "relative_to" in step and step["relative_to"] not in spec.get("nominal", {}):
            message = f"'{step['relative_to']}' has no nominal placement (top-level 'nominal')"
            raise w.fail(f"{at}.relative_to", message)
        if step["kind"] == "localize":
            comps = sorted(c for c in fac.manifest["components"] if c != "robot")
            if step["component"] not in comps:
                message = f"'{step['component']}' is not a component; components: "
                raise w.fail(f"{at}.component", message + ", ".join(comps))
        if step["kind"] in ("look", "localize") and camera not in robot.cameras:
            roles = ", ".join(robot.cameras)
            raise w.fail(f"{at}.camera", f"'{camera}' is not a camera role; roles: {roles}")
