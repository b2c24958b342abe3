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
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco

from ..errors import FacilityError
from ..limits import TIMESTEP_RANGE
from ..schema import Source, load
from .checks import (  # noqa: F401  (the limits: documented as waypoints.*)
    DURATION_MAX,
    HINGE_STEPS_MAX,
    IMAGE_MAX,
    JOINT_MAX,
    JOINTS_MAX,
    POSITION_MAX,
    SPEED_MAX,
    STEPS_MAX,
    Check,
    Waypoints,
    check_mapping,
    check_spec,
    count,
    degrees,
    duration,
    flag,
    name,
    numbers,
    pairs,
    placements,
    positive,
    seconds,
    section,
    speed,
)
from .steps import STEPS
from .task_kinds import HINGE, POSE

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
    kind: (step.keys, step.required) for kind, step in STEPS.items()
}
"""Step kind -> (its keys, the required ones): the registered step classes' schemas."""


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


SECONDS_MAX = 600.0
"""s simulated: the durations, waits, holds and settle times a waypoints file writes,
all its steps and its final wait together (a hinge step's ``step_time`` once per hinge
step); each is also at most ``DURATION_MAX``. The demo's own write 12.6 s."""
_TIMED = (duration, seconds)


def _written_seconds(step: Mapping, keys: Mapping[str, Check]) -> float:
    """The simulated seconds ``step`` (checked) writes: its durations, waits, holds and
    settle times; a hinge step's time per hinge step times its steps."""
    total = 0.0
    for key, value in step.items():
        if keys.get(key) in _TIMED:
            steps = step.get("steps", HINGE.default("steps"))
            total += float(value) * (steps if key == "step_time" else 1)
    return total


def _step_at(i: int, step: Any) -> str:
    label = step.get("name") if isinstance(step, Mapping) else None
    return f"steps[{i}]" + (f" '{label}'" if isinstance(label, str) else "")


def check_shape(spec: Any, path: Path | None, source: Source | None = None) -> dict:
    """``spec`` (a waypoints file's data) checked for keys, kinds and types; ``source``:
    the file's key lines (:func:`urdf2mjcf.schema.load`), for errors that name them."""
    w = Waypoints(path, source)
    if not isinstance(spec, Mapping):
        raise w.fail("waypoints", "a waypoints file is a mapping with steps, bag and stowage")
    check_mapping(spec, "", w, TOP, ("bag", "stowage", "steps"))
    steps = spec["steps"]
    if not isinstance(steps, list) or not steps:
        raise w.fail("steps", "needs a non-empty list of steps")
    if len(steps) > STEPS_MAX:
        raise w.fail("steps", f"has {len(steps)} steps; at most {STEPS_MAX}")
    seen: set[str] = set()
    total = 0.0
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
        check_mapping(step, at, w, {**COMMON, **keys}, required)
        if ("z" in step) != ("x" in step):
            raise w.fail(at, "give both tool axes z and x, or neither")
        if "z" in step and _parallel(step["z"], step["x"]):
            raise w.fail(f"{at}.x", "is parallel to z; the tool axes need two directions")
        total = _add_seconds(total, _written_seconds(step, {**COMMON, **keys}), at, w)
    _add_seconds(total, float(spec.get("final_wait", 0.0)), "final_wait", w)
    return dict(spec)


def _add_seconds(total: float, seconds: float, at: str, w: Waypoints) -> float:
    """``total + seconds``; an error naming ``at`` when it passes :data:`SECONDS_MAX`."""
    total += seconds
    if total > SECONDS_MAX:
        raise w.fail(
            at,
            f"brings the times the file writes to {total:g} s; a waypoints file may "
            f"write at most {SECONDS_MAX:g} s simulated",
        )
    return total


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
    if "vmax" not in rs and robot.vmax is None:
        raise w.fail("robot.vmax", "is required: the facility's robot roles give no vmax")
    exists(obj.mjOBJ_BODY, spec["bag"]["body"], "bag.body")
    exists(obj.mjOBJ_GEOM, spec["bag"]["geom"], "bag.geom")
    exists(obj.mjOBJ_BODY, spec["stowage"]["body"], "stowage.body")
    for i, step in enumerate(spec["steps"]):
        at = _step_at(i, step)
        STEPS[step["kind"]].check(step, at, fac, w)
        frame = step.get("frame", POSE.default("frame"))
        if frame not in ("world", "handle"):
            exists(obj.mjOBJ_BODY, frame, f"{at}.frame")
        if "joint_above_deg" in step.get("check", {}):
            exists(obj.mjOBJ_JOINT, step["check"]["joint_above_deg"][0], f"{at}.check")
        if "site" in step and step["site"] not in robot.sites:
            roles = ", ".join(robot.sites)
            raise w.fail(f"{at}.site", f"'{step['site']}' is not a site role; roles: {roles}")
        if "relative_to" in step and step["relative_to"] not in spec.get("nominal", {}):
            message = f"'{step['relative_to']}' has no nominal placement (top-level 'nominal')"
            raise w.fail(f"{at}.relative_to", message)
