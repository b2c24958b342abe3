"""Checks of a stranger's waypoints file: numbers, names, lists, mappings.

Each check is ``check(value, where, w)``: it raises ``w.fail(where, message)`` (one
error naming the file and the element) or returns. The demo's step kinds
(:mod:`urdf2mjcf.runner.steps`) declare their keys with these; the file's reader
(:mod:`urdf2mjcf.runner.waypoints`) applies them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ..errors import FacilityError
from ..limits import ANGLE_MAX, LENGTH_MAX
from ..schema import Source
from ..untrusted import NUMBER_TEXT_MAX, BadNumber, excerpt, read_number
from ..untrusted import shown as quoted

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
    """A finite float in [low, high] (``(low, high]`` with ``low_open``): a YAML number,
    not text (:func:`urdf2mjcf.untrusted.read_number`)."""
    if isinstance(value, str):  # "0.5" in quotes, or a number too long to be one
        long = len(value) > NUMBER_TEXT_MAX
        why = f" ({len(value):,} characters; at most {NUMBER_TEXT_MAX})" if long else ""
        raise w.fail(where, f"'{quoted(value)}' is not a number{why}")
    try:
        return read_number(value, low=low, high=high, low_open=low_open)
    except BadNumber as exc:
        raise w.fail(where, str(exc)) from None


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
        raise w.fail(where, f"'{quoted(value)}' is not true or false")


def name(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, str) or not value:
        raise w.fail(where, f"'{quoted(value)}' is not a name")


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
    check_mapping(value, where, w, {"joint_above_deg": _joint_above, "bag_lifted": number})


def _joint_above(value: Any, where: str, w: Waypoints) -> None:
    if not (isinstance(value, list) and len(value) == 2 and isinstance(value[0], str)):
        raise w.fail(where, "needs [joint name, degrees]")
    degrees(value[1], f"{where}[1]", w)


def placements(value: Any, where: str, w: Waypoints) -> None:
    if not isinstance(value, Mapping) or not value:
        raise w.fail(where, "needs a mapping of component to {xyz, yaw}")
    keys = {"xyz": numbers(3, -LENGTH_MAX, LENGTH_MAX), "yaw": ranged(-ANGLE_MAX, ANGLE_MAX)}
    for comp, pose in value.items():
        check_mapping(pose, f"{where}.{comp}", w, keys, ("xyz", "yaw"))


def section(keys: dict[str, Check], required: tuple[str, ...] = ()) -> Check:
    def check(value: Any, where: str, w: Waypoints) -> None:
        check_mapping(value, where, w, keys, required)

    return check


def check_mapping(
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
