"""The demo's waypoints file, checked before anything moves.

:func:`read_waypoints` checks the file's shape (known keys, step kinds, types,
required fields); :func:`check_names` checks it against a loaded facility
(bodies, joints, the robot's sites and cameras, vector lengths). Each error
names the file and the element (``steps[3] 'approach'.position``).

A waypoints file may come from a stranger: every number is finite and in a
documented range (``DURATION_MAX`` s for each duration, wait and hold time,
``HINGE_STEPS_MAX`` hinge steps, ``STEPS_MAX`` steps, positions within
``POSITION_MAX`` m, ...), so no value can make the demo step for hours, render an
image larger than the model's offscreen buffer or divide by zero.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import mujoco

from ..errors import FacilityError
from ..facility.fiducials import TAG_COUNT
from ..facility.values import ANGLE_MAX, LENGTH_MAX, TIMESTEP_RANGE
from ..schema import Source, load
from ..untrusted import excerpt

Check = Callable[[Any, str, "Waypoints"], None]

DURATION_MAX = 600.0
"""s simulated: the longest duration, wait, hold or settle time of one step (and the
final wait); the demo's own are under 2 s."""
STEPS_MAX = 1_000
"""Most steps a waypoints file may hold (the published demo has 28)."""
HINGE_STEPS_MAX = 1_000
"""Most poses of one hinge step (the published one has 8)."""
POSITION_MAX = 1_000.0
"""m: the largest coordinate of a position, a tool or world offset, a volume."""
JOINT_MAX = 1_000.0
"""rad or m: the largest joint value (q, arm, set, IK seeds)."""
SPEED_MAX = 100.0
"""The largest speed factor of a step (of the robot's vmax) and the largest vmax."""
IMAGE_MAX = 16_384
"""px: the largest perception image side (MuJoCo's offscreen buffer's own limit)."""
PIXELS_MAX = IMAGE_MAX * IMAGE_MAX


class Waypoints:
    """Where errors point: the file and, for a file read here, the key's line."""

    def __init__(self, path: Path | None, source: Source | None = None):
        self.path = path
        self.source = source or Source(path or "waypoints", error=FacilityError)

    def fail(self, where: str, message: str) -> FacilityError:
        return self.source.fail(where, message)  # type: ignore[return-value]


def _number(
    value: Any,
    where: str,
    w: Waypoints,
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
) -> float:
    """A finite float in [low, high] (``(low, high]`` with ``low_open``)."""
    x = math.nan
    if not isinstance(value, bool) and isinstance(value, (int, float)):
        try:
            x = float(value)
        except OverflowError:  # an integer of 400 digits
            pass
    if not math.isfinite(x):
        raise w.fail(where, f"'{excerpt(str(value), 40)}' is not a number")
    if (x <= low if low_open else x < low) or x > high:
        lo = "above" if low_open else "from"
        raise w.fail(where, f"{x:g} is out of range ({lo} {low:g} to {high:g})")
    return x


def ranged(low: float, high: float, low_open: bool = False) -> Check:
    """A check of one number in [low, high] (``(low, high]`` with ``low_open``)."""

    def check(value: Any, where: str, w: Waypoints) -> None:
        _number(value, where, w, low=low, high=high, low_open=low_open)

    return check


number = ranged(-POSITION_MAX, POSITION_MAX)
positive = ranged(0.0, POSITION_MAX, low_open=True)
duration = ranged(0.0, DURATION_MAX, low_open=True)
"""A step's duration or settle time (s): above 0 and at most DURATION_MAX."""
seconds = ranged(0.0, DURATION_MAX)
"""A wait or a hold (s): 0 .. DURATION_MAX."""
speed = ranged(0.0, SPEED_MAX, low_open=True)
degrees = ranged(-360.0, 360.0)


def count(high: int, low: int = 0) -> Check:
    """A check of a whole number in [low, high]."""

    def check(value: Any, where: str, w: Waypoints) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            shown = excerpt(str(value), 40)
            raise w.fail(where, f"'{shown}' is not a whole number from {low} to {high}")

    return check


def flag(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, bool):
        raise w.fail(where, f"'{value}' is not true or false")


def name(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, str) or not value:
        raise w.fail(where, f"'{value}' is not a name")


def numbers(
    n: int | None = None,
    low: float = -POSITION_MAX,
    high: float = POSITION_MAX,
    *,
    low_open: bool = False,
    nonzero: bool = False,
) -> Check:
    """A check of a list of numbers (``n`` of them), each in [low, high]; ``nonzero``: a
    direction or a quaternion, which must not be all zeros (it is normalised)."""

    def check(value: Any, where: str, w: Waypoints) -> None:
        if not isinstance(value, list) or (n is not None and len(value) != n):
            raise w.fail(where, f"needs a list of {n} numbers" if n else "needs a list of numbers")
        if n is None and len(value) > JOINTS_MAX:
            raise w.fail(where, f"has {len(value)} numbers; at most {JOINTS_MAX}")
        xs = [
            _number(v, f"{where}[{i}]", w, low=low, high=high, low_open=low_open)
            for i, v in enumerate(value)
        ]
        if nonzero and math.hypot(*xs) < 1e-9:
            raise w.fail(where, "is all zeros; it needs a direction")

    return check


JOINTS_MAX = 1_000
"""Most numbers in a list of joint values (q, arm, seed, vmax, ik_weights)."""
joints = numbers(None, -JOINT_MAX, JOINT_MAX)
axis = numbers(3, nonzero=True)


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
        _number(v, f"{where}.{k}", w, low=-JOINT_MAX, high=JOINT_MAX)


OPENING_MAX = 1.0
"""m: the widest gripper opening a step may ask for."""


def action(value: Any, where: str, w: Waypoints) -> None:
    if value not in ("open", "close"):
        try:
            _number(value, where, w, low=0.0, high=OPENING_MAX)
        except FacilityError:
            shown = excerpt(str(value), 40)
            message = f"'{shown}' is not open, close or an opening (0 .. {OPENING_MAX:g} m)"
            raise w.fail(where, message) from None


def check_spec(value: Any, where: str, w: Waypoints) -> None:
    _mapping(value, where, w, {"joint_above_deg": _joint_above, "bag_lifted": number})


def _joint_above(value: Any, where: str, w: Waypoints) -> None:
    if not (isinstance(value, list) and len(value) == 2 and isinstance(value[0], str)):
        raise w.fail(where, "needs [joint name, degrees]")
    degrees(value[1], f"{where}[1]", w)


def placements(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, Mapping) or not value:
        raise w.fail(where, "needs a mapping of component to {xyz, yaw}")
    keys = {"xyz": numbers(3, -LENGTH_MAX, LENGTH_MAX), "yaw": ranged(-ANGLE_MAX, ANGLE_MAX)}
    for comp, pose in value.items():
        _mapping(pose, f"{where}.{comp}", w, keys, ("xyz", "yaw"))


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
        bad = excerpt(unknown[0], 60)
        raise w.fail(_join(where, bad), f"unknown key; valid: {', '.join(keys)}")
    for key in required:
        if key not in value:
            raise w.fail(_join(where, key), "is required")
    for key, v in value.items():
        keys[key](v, _join(where, key), w)


def _join(where: str, key: str) -> str:
    """A key below ``where`` (a top-level key is its own name: its line is found)."""
    return f"{where}.{key}" if where else key


COMMON: dict[str, Check] = {
    "name": name,
    "kind": name,
    "contacts": pairs,
    "carried": flag,
    "settle": flag,
    "settle_timeout": duration,
    "speed": speed,
    "snapshot": flag,
    "check": check_spec,
    "duration": duration,
}
KINDS: dict[str, tuple[dict[str, Check], tuple[str, ...]]] = {
    "joints": (
        {"q": joints, "arm": joints, "set": joint_values, "relative_to": name}, ()
    ),
    "pose": (
        {
            "position": numbers(3),
            "frame": name,
            "z": axis,
            "x": axis,
            "x_sign_free": flag,
            "orientation_xyzw": numbers(4, nonzero=True),
            "site": name,
            "joint_space": flag,
            "seed": joints,
            "relative_to": name,
        },
        ("position",),
    ),
    "relative": ({"tool": numbers(3), "world": numbers(3)}, ()),
    "hinge": (
        {
            "joint": name,
            "steps": count(HINGE_STEPS_MAX, 1),
            "step_deg": degrees,
            "hold_orientation": flag,
            "step_time": duration,
        },
        ("joint",),
    ),
    "gripper": ({"action": action, "seconds": seconds}, ("action",)),
    "look": (
        {"camera": name, "min_pixels": count(PIXELS_MAX), "border_px": count(IMAGE_MAX)}, ()
    ),
    "localize": (
        {"component": name, "camera": name, "min_tags": count(TAG_COUNT)}, ("component",)
    ),
    "wait": ({"seconds": seconds}, ("seconds",)),
}


def image_size(value: Any, where: str, w: Waypoints) -> None:
    """[height, width] in pixels: whole numbers, 1 .. IMAGE_MAX."""
    if not isinstance(value, list) or len(value) != 2:
        raise w.fail(where, "needs [height, width] (pixels)")
    for i, v in enumerate(value):
        count(IMAGE_MAX, 1)(v, f"{where}[{i}]", w)


TOP: dict[str, Check] = {
    "robot": section(
        {
            "site": name,
            "vmax": numbers(None, 0.0, SPEED_MAX, low_open=True),
            "ik_weights": numbers(None, 0.0, 1e6, nonzero=True),
        }
    ),
    "bag": section({"body": name, "geom": name}, ("body", "geom")),
    "stowage": section(
        {"body": name, "inside": numbers(3, 0.0, POSITION_MAX, low_open=True)}, ("body", "inside")
    ),
    "perception": section({"size": image_size}),
    "view": section(
        {"lookat": numbers(3), "distance": positive, "azimuth": degrees, "elevation": degrees}
    ),
    "final_wait": seconds,
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
    _mapping(spec, "", w, TOP, ("bag", "stowage", "steps"))
    steps = spec["steps"]
    if not isinstance(steps, list) or not steps:
        raise w.fail("steps", "needs a non-empty list of steps")
    if len(steps) > STEPS_MAX:
        raise w.fail("steps", f"has {len(steps)} steps; at most {STEPS_MAX}")
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
        if "z" in step and _parallel(step["z"], step["x"]):
            raise w.fail(f"{at}.x", "is parallel to z; the tool axes need two directions")
    return dict(spec)


def _parallel(z: list[float], x: list[float]) -> bool:
    """Whether two (checked, non-zero) directions are parallel: no frame between them."""
    cross = (
        z[1] * x[2] - z[2] * x[1],
        z[2] * x[0] - z[0] * x[2],
        z[0] * x[1] - z[1] * x[0],
    )
    return math.hypot(*cross) <= 1e-6 * math.hypot(*z) * math.hypot(*x)


def read_waypoints(path: str | Path) -> dict:
    """A waypoints file, its shape checked (:func:`check_shape`)."""
    data, source = load(Path(path), "waypoints file")
    source.error = FacilityError
    return check_shape(data, Path(path), source)


def _check_model(fac: Any) -> None:
    """The facility's timestep is one a recipe may give: every duration above becomes
    ``seconds / timestep`` steps (a hand-edited scene.xml could make that endless)."""
    dt = float(fac.model.opt.timestep)
    low, high = TIMESTEP_RANGE
    if not low <= dt <= high:
        raise FacilityError(
            f"timestep {dt:g} s is out of range ({low:g} to {high:g})",
            file=Path(fac.folder) / "scene.xml",
            element="option timestep",
        )


def check_names(spec: Mapping, path: Path | None, fac: Any) -> None:
    """Every name and vector length in ``spec`` against the loaded facility ``fac``
    (a :class:`urdf2mjcf.runner.load.Facility`)."""
    w = Waypoints(path)
    m, robot = fac.model, fac.robot
    _check_model(fac)
    n = len(robot.joints)
    obj = mujoco.mjtObj

    def exists(kind: mujoco.mjtObj, value: str, where: str) -> None:
        if mujoco.mj_name2id(m, kind, value) < 0:
            raise w.fail(where, f"the facility has no {kind.name[6:].lower()} named '{value}'")

    def length(value: list, want: int, where: str) -> None:
        if len(value) != want:
            raise w.fail(where, f"has {len(value)} values; the robot needs {want}")

    size = spec.get("perception", {}).get("size")
    g = m.vis.global_
    if size and (size[0] > g.offheight or size[1] > g.offwidth):
        message = f"{size[0]} x {size[1]} is larger than the model's offscreen buffer, "
        raise w.fail("perception.size", message + f"{g.offheight} x {g.offwidth}")
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
