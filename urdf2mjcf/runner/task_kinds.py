"""One registry of task kinds, each parameter declared once.

A :class:`TaskKind` names its family (``drive``/``arm``: a rover task plan's
``tasks``/``arm``; ``step``: a demo waypoints file's step; ``task``:
``rover-drive --task``; ``command``: the console's ``POST /command`` fields; ``ros2``:
the fields of the rovers' ROS 2 commands) and its
:class:`Param` s: type, unit, range, default, meaning. The plan's and the demo steps'
key checks and defaults, ``rover-drive``'s flag defaults and ranges, the console's
and the ROS 2 rovers' number checks and the docs' tables of plan keys, steps and
commands are read from here
(``tests/runner/test_task_kinds.py`` checks no default is declared twice).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from ..limits import TAG_COUNT
from ..untrusted import BadNumber, excerpt, read_number
from .checks import (
    DURATION_MAX,
    HINGE_STEPS_MAX,
    IMAGE_MAX,
    JOINTS_MAX,
    PIXELS_MAX,
    Check,
    action,
    axis,
    count,
    degrees,
    duration,
    flag,
    joint_values,
    joints,
    numbers,
    ranged,
    seconds,
)
from .checks import (
    name as a_name,
)

Family = Literal["step", "drive", "arm", "task", "command", "ros2"]

DISTANCE_MAX = 1_000.0
"""m: the longest drive (it must also end within ``sim.TASK_TIMEOUT``
simulated seconds, 120 s: at 0.5 m/s, about 55 m)."""
SPEED_MAX = 10.0
"""m/s: the fastest drive asked for (the wheel servos' limits cap the real speed)."""
ACCEL_MAX = 10.0
"""m/s^2: the largest speed-up or braking of a drive."""
TURN_MAX = 3_600.0
"""deg: the largest turn in place (ten turns)."""
RATE_MAX = 360.0
"""deg/s: the fastest turn asked for."""
HOLD_MAX = 100.0
"""s: the longest hold (under ``sim.TASK_TIMEOUT``, 120 s, so a hold always ends)."""
AMPLITUDE_MAX = 3.0
"""rad: the largest arm swing either way."""
PERIOD_RANGE = (0.5, DURATION_MAX)
"""s: an arm swing's period (a shorter one only shakes the position servos)."""
NUMBER_MAX = 1e6
"""Magnitude of a commanded number, at most (then clipped to the actuator's range)."""


@dataclass(frozen=True)
class Param:
    """One typed parameter: ``default`` None means required, unless ``optional``."""

    name: str
    type: type
    unit: str
    doc: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    default: Any = None
    allowed_text: str | None = None
    """The values in words, where the range alone does not say them."""
    given: Check | None = None
    """The YAML check, where the shared one of its kind is meant (the demo's ``seconds``
    and ``duration``: the waypoints file's time bound finds them by identity)."""
    optional: bool = False
    """May be left out, with no default: left out, the kind does without it (a pose step
    without ``frame`` is in the world)."""

    @property
    def required(self) -> bool:
        return self.default is None and not self.optional

    @property
    def allowed(self) -> str:
        if self.allowed_text is not None:
            return self.allowed_text
        if self.type is bool:
            return "true, false"
        low, high = (f"{int(x)}" if self.type is int else f"{x:g}" for x in (self.low, self.high))  # type: ignore[arg-type]
        text = f"above {low}, up to {high}" if self.low_open else f"{low} .. {high}"
        return f"{text} {self.unit}".rstrip()

    @property
    def check(self) -> Check:
        """The YAML check of a value of this parameter."""
        if self.given is not None:
            return self.given
        if self.type is bool:
            return flag
        assert self.low is not None and self.high is not None
        if self.type is int:
            return count(int(self.high), int(self.low))
        return ranged(self.low, self.high, self.low_open)

    def number(self, value: Any) -> float | str:
        """``value`` (a JSON or ROS message field: a number, never its text) as this
        parameter's number, or why it is refused, in the words of the one number reader
        (:func:`urdf2mjcf.untrusted.read_number`)."""
        if isinstance(value, str):
            return f"'{excerpt(value, 40)}' is not a number"
        assert self.low is not None and self.high is not None
        try:
            x = read_number(value, low=self.low, high=self.high, low_open=self.low_open)
        except BadNumber as exc:
            return str(exc)
        if self.high_open and x == self.high:
            return f"{x:g} is out of range ({self.allowed})"
        return x

    def within(self, x: float) -> bool:
        """Whether the number ``x`` is in this parameter's range."""
        assert self.low is not None and self.high is not None
        above = x > self.low if self.low_open else x >= self.low
        below = x < self.high if self.high_open else x <= self.high
        return above and below


@dataclass(frozen=True)
class TaskKind:
    name: str
    family: Family
    params: tuple[Param, ...]
    doc: str

    def param(self, name: str) -> Param:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"{self.name} has no parameter {name!r}")

    def default(self, name: str) -> Any:
        return self.param(name).default


KINDS: dict[str, TaskKind] = {}
"""Name -> kind, in the order the docs list them."""


def register(kind: TaskKind) -> TaskKind:
    if kind.name in KINDS:
        raise ValueError(f"task kind {kind.name!r} registered twice")
    KINDS[kind.name] = kind
    return kind


def family(name: Family) -> dict[str, TaskKind]:
    return {k: t for k, t in KINDS.items() if t.family == name}


def _num(name: str, low: float, high: float, unit: str, doc: str, default: Any = None,
         *, low_open: bool = False) -> Param:  # fmt: skip
    return Param(name, float, unit, doc, low, high, low_open=low_open, default=default)


STRAIGHT = register(TaskKind("straight", "drive", (
    _num("distance", -DISTANCE_MAX, DISTANCE_MAX, "m",
         "drive straight this far (negative: backwards)"),
    _num("speed", 0.0, SPEED_MAX, "m/s", "top speed", 0.5, low_open=True),
    _num("accel", 0.0, ACCEL_MAX, "m/s²", "speed-up and braking", 0.5, low_open=True),
    Param("hold_heading", bool, "", "hold the start heading with the IMU", default=True),
), "drive straight on the wheel odometry, heading held by the IMU"))  # fmt: skip

TURN = register(TaskKind("turn", "drive", (
    _num("angle_deg", -TURN_MAX, TURN_MAX, "deg", "turn in place (positive: left)"),
    _num("rate_deg", 0.0, RATE_MAX, "deg/s", "top turn rate", 30.0, low_open=True),
    Param("imu", bool, "", "measure the turn with the IMU (false: with the wheels)",
          default=True),
), "turn in place"))  # fmt: skip

HOLD = register(TaskKind("hold", "drive", (
    _num("duration", 0.0, HOLD_MAX, "s", "stand still, wheels held", 1.0),
), "stand still"))  # fmt: skip

ARM_WAVE = register(TaskKind("arm_wave", "arm", (
    Param("joint", int, "", "arm joint (roles order)", 0, JOINTS_MAX, default=0,
          allowed_text="0 .. the rover's arm joints - 1"),
    _num("amplitude", -AMPLITUDE_MAX, AMPLITUDE_MAX, "rad", "swing about the home target", 0.4),
    _num("period", *PERIOD_RANGE, "s", "one swing, eased in over the first", 6.0),
), "swing one arm joint about its home target during every drive task"))  # fmt: skip

DELIVER = register(
    TaskKind(
        "deliver",
        "task",
        (),
        (
            "collect regolith at the pile, deliver it to the printer, print a path "
            "(``rover-drive --task deliver``)"
        ),
    )
)

WHEELS = register(TaskKind("wheels", "command", (
    _num("left", -NUMBER_MAX, NUMBER_MAX, "rad/s", "left wheels' speed"),
    _num("right", -NUMBER_MAX, NUMBER_MAX, "rad/s", "right wheels' speed"),
), "POST /command {wheels: {left, right}}: both wheel speeds, clipped to the servos'"))  # fmt: skip

ARM = register(TaskKind("arm", "command", (
    _num("joint", -NUMBER_MAX, NUMBER_MAX, "rad", "an arm joint's target, by name"),
), "POST /command {arm: {JOINT: rad}}: arm targets, clipped to the joints' ranges"))  # fmt: skip


CMD_VEL = register(TaskKind("cmd_vel", "ros2", (
    _num("linear_x", -NUMBER_MAX, NUMBER_MAX, "m/s", "`linear.x`: the forward speed"),
    _num("angular_z", -NUMBER_MAX, NUMBER_MAX, "rad/s",
         "`angular.z`: the yaw rate (positive: left)"),
), "`/<rover>/cmd_vel` (geometry_msgs/Twist): through the wheels, clipped to the servos'; "
   "a message out of range is dropped, with a warning"))  # fmt: skip

ESTOP = register(TaskKind("estop", "ros2", (
    Param("data", bool, "", "true latches the emergency stop, false releases it"),
), "`/<rover>/estop` (std_msgs/Bool): the console's emergency stop"))  # fmt: skip


def _given(name: str, check: Check, type_: type, unit: str, doc: str, default: Any = None,
           allowed: str | None = None, low: float | None = None, high: float | None = None,
           low_open: bool = False, optional: bool = False) -> Param:  # fmt: skip
    return Param(name, type_, unit, doc, low, high, low_open, default=default,
                 allowed_text=allowed, given=check, optional=optional)  # fmt: skip


_CAMERA = _given("camera", a_name, str, "", "the camera role", "wrist", "a camera role")
_RELATIVE_TO = _given("relative_to", a_name, str, "", "a component the target moves with "
                      "(its pose as localized)", allowed="a component", optional=True)

JOINTS = register(TaskKind("joints", "step", (
    _given("q", joints, list, "rad or m", "every joint's target, in the robot's order",
           allowed="a number per joint", optional=True),
    _given("arm", joints, list, "rad", "the arm joints' targets",
           allowed="a number per arm joint", optional=True),
    _given("set", joint_values, dict, "rad or m", "targets of the joints named",
           allowed="{joint: number}", optional=True),
    _RELATIVE_TO,
), "a joint move planned collision-free"))  # fmt: skip

POSE = register(TaskKind("pose", "step", (
    _given("position", numbers(3), list, "m", "the tool site's target position",
           allowed="3 numbers"),
    _given("frame", a_name, str, "", "the frame the target is in: a body, `handle` (the one "
           "`look` found) or the world", "world", allowed="a body, handle or world"),
    _given("z", axis, list, "", "the tool's z axis in that frame",
           allowed="3 numbers, not 0", optional=True),
    _given("x", axis, list, "", "the tool's x axis in that frame",
           allowed="3 numbers, not 0", optional=True),
    _given("x_sign_free", flag, bool, "", "x or -x, whichever is nearer", False),
    _given("orientation_xyzw", numbers(4, nonzero=True), list, "", "the tool's orientation",
           allowed="4 numbers, not 0", optional=True),
    _given("site", a_name, str, "", "the site to place (default: the tool's)",
           allowed="a site", optional=True),
    _given("joint_space", flag, bool, "", "a planned joint move to the IK solution instead "
           "of a Cartesian path", False),
    _given("seed", joints, list, "rad or m", "the IK's start",
           allowed="a number per joint", optional=True),
    _RELATIVE_TO,
), "the tool to a pose: a Cartesian path, or a planned joint move"))  # fmt: skip

RELATIVE = register(TaskKind("relative", "step", (
    _given("tool", numbers(3), list, "m", "an offset in the tool's frame",
           allowed="3 numbers", optional=True),
    _given("world", numbers(3), list, "m", "an offset in the world",
           allowed="3 numbers", optional=True),
), "the tool moved by an offset along a Cartesian path"))  # fmt: skip


HINGE = register(TaskKind("hinge", "step", (
    _given("joint", a_name, str, "", "the hinge joint", allowed="a joint of the facility"),
    _given("steps", count(HINGE_STEPS_MAX, 1), int, "", "poses along the arc", 8,
           f"1 .. {HINGE_STEPS_MAX}", 1, HINGE_STEPS_MAX),
    _given("step_deg", degrees, float, "deg", "the arc's angle per pose", 11.5,
           low=-360.0, high=360.0),
    _given("hold_orientation", flag, bool, "", "keep the tool's orientation", True),
    _given("step_time", duration, float, "s", "the least time per pose", 1.0,
           low=0.0, high=DURATION_MAX, low_open=True),
), "the arc around a hinge joint"))  # fmt: skip

GRIPPER = register(TaskKind("gripper", "step", (
    _given("action", action, str, "m", "open, close or an opening",
           allowed="open, close or an opening in m"),
    _given("seconds", seconds, float, "s", "the gripper's ramp", 1.0,
           low=0.0, high=DURATION_MAX),
), "open or close the gripper"))  # fmt: skip

LOOK = register(TaskKind("look", "step", (
    _CAMERA,
    _given("min_pixels", count(PIXELS_MAX), int, "px", "the handle's least red pixels", 200,
           low=0, high=PIXELS_MAX),
    _given("border_px", count(IMAGE_MAX), int, "px", "the handle's least margin in view", 2,
           low=0, high=IMAGE_MAX),
), "find the red handle in the wrist camera's image; set the handle frame"))  # fmt: skip

LOCALIZE = register(TaskKind("localize", "step", (
    _given("component", a_name, str, "", "the component to locate", allowed="a component"),
    _CAMERA,
    _given("min_tags", count(TAG_COUNT), int, "", "the least tags seen", 1, low=0, high=TAG_COUNT),
), "a component's pose from its AprilTags"))  # fmt: skip

WAIT = register(TaskKind("wait", "step", (
    _given("seconds", seconds, float, "s", "how long to wait", low=0.0,
           high=DURATION_MAX),
), "wait, the arm held"))  # fmt: skip


def keys_table(families: tuple[Family, ...] = ("drive", "arm")) -> list[str]:
    """The kinds' parameters as a Markdown table (docs/mira3d.md shows the plan's)."""
    rows = ["| kind | key | values | default | meaning |", "|---|---|---|---|---|"]
    for name, kind in KINDS.items():
        if kind.family not in families:
            continue
        for p in kind.params:
            d = p.default
            shown = (
                "required"
                if p.required
                else "-"
                if d is None
                else str(d).lower()
                if isinstance(d, bool)
                else f"`{d}`"
                if isinstance(d, str)
                else f"{d:g}"
            )
            rows.append(f"| `{name}` | `{p.name}` | {p.allowed} | {shown} | {p.doc} |")
    return rows
