"""What each rover does, one command per step: closed loops on the odometry
(``Straight``, ``Turn``, ``Hold``) and an arm motion (``ArmWave``); and their kinds.

:data:`TASKS` maps each kind a task plan names (``straight``, ``turn``, ``hold``,
``arm_wave``) to its registered class, as :mod:`urdf2mjcf.runner.steps` does for the
demo's steps: ``keys`` (each key's check, allowed values, default and meaning) and
``required`` are its schema, :meth:`TaskKind.check` checks a task against one rover of
the bundle (an arm joint index against its arm joints), :meth:`TaskKind.build` makes
the task from a checked mapping and :meth:`DriveKind.run` runs it on rovers at once.
``rover-drive --distance/--turn/--arm`` and ``--plan`` (:mod:`.plan_file`) both make
their tasks here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np

from ..checks import DURATION_MAX, JOINTS_MAX, Check, Waypoints, count, flag, ranged
from .roles import Rover
from .state import SimState

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
TURN_RATE_DEG = 30.0
"""deg/s: a turn's top rate unless it says (``Turn.rate``, the plan's ``rate_deg`` and
``rover-drive --rate`` all take it from here)."""
HOLD_MAX = 100.0
"""s: the longest hold (under ``sim.TASK_TIMEOUT``, 120 s, so a hold always ends)."""
AMPLITUDE_MAX = 3.0
"""rad: the largest arm swing either way."""
PERIOD_RANGE = (0.5, DURATION_MAX)
"""s: an arm swing's period (a shorter one only shakes the position servos)."""


class Task:
    """A closed loop on the odometry: ``command`` gives (v m/s, yaw rate rad/s) each step."""

    done: bool = False

    def start(self, sim: SimState, rover: Rover) -> None:
        pass

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        """(v m/s, yaw rate rad/s); v None: brake."""
        raise NotImplementedError


def _profile(remaining: float, elapsed: float, top: float, accel: float) -> float:
    """Trapezoidal speed: ramp up at ``accel``, cruise at ``top``, brake to stop at the goal."""
    return max(0.0, min(top, accel * (elapsed + 0.05), math.sqrt(2 * accel * max(0.0, remaining))))


@dataclass
class Straight(Task):
    """Drive ``distance`` m (wheel odometry; negative: backwards), holding the start heading
    with the IMU (a rover's heading hold), then stop."""

    distance: float
    speed: float = 0.5
    accel: float = 0.5
    hold_heading: bool = True
    heading_gain: float = 1.5
    tolerance: float = 0.002

    def start(self, sim: SimState, rover: Rover) -> None:
        odo = sim.odometry[rover.name]
        self._d0, self._t0, self._h0 = odo.distance, sim.d.time, odo.turned_imu
        self._stopping = False
        self.done = False

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        odo = sim.odometry[rover.name]
        sign = 1.0 if self.distance >= 0 else -1.0
        remaining = abs(self.distance) - sign * (odo.distance - self._d0)
        if remaining <= self.tolerance:
            self._stopping = True
        if self._stopping:
            self.done = sim.wheel_speed(rover) < 0.01
            return None, 0.0
        v = sign * _profile(remaining, sim.d.time - self._t0, self.speed, self.accel)
        w = -self.heading_gain * (odo.turned_imu - self._h0) if self.hold_heading else 0.0
        return v, w


@dataclass
class Turn(Task):
    """Turn in place by ``angle`` rad (positive: left), measured by the IMU (``imu=True``)
    or by the wheels, then stop."""

    angle: float
    rate: float = math.radians(TURN_RATE_DEG)
    """rad/s."""
    accel: float = 1.0
    imu: bool = True
    tolerance: float = math.radians(0.3)

    def start(self, sim: SimState, rover: Rover) -> None:
        odo = sim.odometry[rover.name]
        self._a0 = odo.turned_imu if self.imu else odo.turned
        self._t0 = sim.d.time
        self._stopping = False
        self.done = False

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        odo = sim.odometry[rover.name]
        turned = (odo.turned_imu if self.imu else odo.turned) - self._a0
        sign = 1.0 if self.angle >= 0 else -1.0
        remaining = abs(self.angle) - sign * turned
        if remaining <= self.tolerance:
            self._stopping = True
        if self._stopping:
            self.done = sim.wheel_speed(rover) < 0.01
            return None, 0.0
        return 0.0, sign * _profile(remaining, sim.d.time - self._t0, self.rate, self.accel)


@dataclass
class Hold(Task):
    """Stand still for ``duration`` s."""

    duration: float = 1.0

    def start(self, sim: SimState, rover: Rover) -> None:
        self._t_end = sim.d.time + self.duration
        self.done = False

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        self.done = sim.d.time >= self._t_end - 1e-9
        return None, 0.0


@dataclass
class ArmWave:
    """Swing one arm joint (index in the roles' arm_joints) about its home target:
    ``amplitude`` rad, ``period`` s, eased in over the first period."""

    joint: int = 0
    amplitude: float = 0.4
    period: float = 6.0

    def targets(self, home: np.ndarray, t: float) -> np.ndarray:
        q = home.copy()
        ease = min(1.0, t / self.period)
        q[self.joint] += ease * self.amplitude * math.sin(2 * math.pi * t / self.period)
        return q


# -- the kinds a task plan names ------------------------------------------------------


@dataclass(frozen=True)
class Key:
    """One key of a task kind: its check, what it allows and its default (shown in the
    docs' table, generated from these), and what it means."""

    check: Check
    allowed: str
    meaning: str
    default: Any = None
    """None: the key is required."""


def default_of(task: type, field: str) -> Any:
    """A task dataclass's default for ``field``: the one declaration the plan's keys and
    the command line's options take theirs from."""
    (found,) = [f for f in fields(task) if f.name == field]
    return found.default


def _number(
    low: float, high: float, unit: str, meaning: str, default: Any = None, *, low_open: bool = False
) -> Key:
    allowed = f"above {low:g}, up to {high:g} {unit}" if low_open else f"{low:g} .. {high:g} {unit}"
    return Key(ranged(low, high, low_open), allowed, meaning, default)


def _flag(meaning: str, default: bool) -> Key:
    return Key(flag, "true, false", meaning, default)


class TaskKind:
    """A kind of rover task: its schema, its check against a rover and its making."""

    kind: ClassVar[str]
    arm: ClassVar[bool] = False
    """An arm motion (the plan's ``arm``, beside every drive task), not a drive task."""
    keys: ClassVar[dict[str, Key]] = {}
    required: ClassVar[tuple[str, ...]] = ()

    @property
    def checks(self) -> dict[str, Check]:
        return {key: k.check for key, k in self.keys.items()}

    def value(self, spec: Mapping, key: str) -> Any:
        """``spec``'s value of ``key``, or the key's default."""
        return spec[key] if key in spec else self.keys[key].default

    def check(self, spec: Mapping, at: str, rover: Rover, w: Waypoints) -> None:
        """Raise ``w.fail`` where the (shape-checked) task asks what ``rover`` lacks."""

    def build(self, spec: Mapping) -> Any:
        raise NotImplementedError


class DriveKind(TaskKind):
    """A closed loop on the odometry, run on every named rover at once."""

    def build(self, spec: Mapping) -> Task:
        raise NotImplementedError

    def least_seconds(self, spec: Mapping) -> float:
        """Simulated seconds the (checked) task takes at the least: its distance at its top
        speed, its angle at its top rate, its hold."""
        raise NotImplementedError

    def run(
        self,
        sim: Any,
        spec: Mapping,
        names: Sequence[str],
        arm: Mapping | None = None,
        timeout: float | None = None,
    ) -> dict[str, Any]:
        """Run the task on the rovers ``names`` of ``sim`` (a RoverSim, untyped here: ``sim``
        imports this module) at the same time, each with the arm motion ``arm`` (a checked
        mapping) if given, for at most ``timeout`` simulated seconds (None: the sim's
        bound on one task); their reports, as ``RoverSim.run`` gives them."""
        waves = {n: TASKS[arm["kind"]].build(arm) for n in names} if arm else None
        limit = {} if timeout is None else {"timeout": timeout}
        return sim.run({n: self.build(spec) for n in names}, arm=waves, **limit)


TASKS: dict[str, TaskKind] = {}
"""Kind -> its registered class, in the order the docs list them."""


def register(cls: type[TaskKind]) -> type[TaskKind]:
    TASKS[cls.kind] = cls()
    return cls


@register
class StraightKind(DriveKind):
    kind = "straight"
    keys = {
        "distance": _number(
            -DISTANCE_MAX, DISTANCE_MAX, "m", "drive straight this far (negative: backwards)"
        ),
        "speed": _number(
            0.0, SPEED_MAX, "m/s", "top speed", default_of(Straight, "speed"), low_open=True
        ),
        "accel": _number(
            0.0,
            ACCEL_MAX,
            "m/s²",
            "speed-up and braking",
            default_of(Straight, "accel"),
            low_open=True,
        ),
        "hold_heading": _flag(
            "hold the start heading with the IMU", default_of(Straight, "hold_heading")
        ),
    }
    required = ("distance",)

    def least_seconds(self, spec: Mapping) -> float:
        return abs(float(spec["distance"])) / float(self.value(spec, "speed"))

    def build(self, spec: Mapping) -> Straight:
        return Straight(
            float(spec["distance"]),
            speed=float(self.value(spec, "speed")),
            accel=float(self.value(spec, "accel")),
            hold_heading=bool(self.value(spec, "hold_heading")),
        )


@register
class TurnKind(DriveKind):
    kind = "turn"
    keys = {
        "angle_deg": _number(-TURN_MAX, TURN_MAX, "deg", "turn in place (positive: left)"),
        "rate_deg": _number(0.0, RATE_MAX, "deg/s", "top turn rate", TURN_RATE_DEG, low_open=True),
        "imu": _flag(
            "measure the turn with the IMU (false: with the wheels)", default_of(Turn, "imu")
        ),
    }
    required = ("angle_deg",)

    def least_seconds(self, spec: Mapping) -> float:
        return abs(float(spec["angle_deg"])) / float(self.value(spec, "rate_deg"))

    def build(self, spec: Mapping) -> Turn:
        return Turn(
            math.radians(float(spec["angle_deg"])),
            rate=math.radians(float(self.value(spec, "rate_deg"))),
            imu=bool(self.value(spec, "imu")),
        )


@register
class HoldKind(DriveKind):
    kind = "hold"
    keys = {
        "duration": _number(
            0.0, HOLD_MAX, "s", "stand still, wheels held", default_of(Hold, "duration")
        )
    }

    def least_seconds(self, spec: Mapping) -> float:
        return float(self.value(spec, "duration"))

    def build(self, spec: Mapping) -> Hold:
        return Hold(float(self.value(spec, "duration")))


@register
class ArmWaveKind(TaskKind):
    kind = "arm_wave"
    arm = True
    keys = {
        "joint": Key(
            count(JOINTS_MAX),
            "0 .. the rover's arm joints - 1",
            "arm joint (roles order)",
            default_of(ArmWave, "joint"),
        ),
        "amplitude": _number(
            -AMPLITUDE_MAX,
            AMPLITUDE_MAX,
            "rad",
            "swing about the home target",
            default_of(ArmWave, "amplitude"),
        ),
        "period": _number(
            *PERIOD_RANGE,
            "s",
            "one swing, eased in over the first",
            default_of(ArmWave, "period"),
        ),
    }

    def check(self, spec: Mapping, at: str, rover: Rover, w: Waypoints) -> None:
        joint, n = self.value(spec, "joint"), len(rover.arm)
        if joint >= n:
            joints = f"0 .. {n - 1}" if n else "none"
            message = f"{joint} is not an arm joint of rover '{rover.name}' (joints {joints})"
            raise w.fail(f"{at}.joint", message)

    def build(self, spec: Mapping) -> ArmWave:
        return ArmWave(
            joint=int(self.value(spec, "joint")),
            amplitude=float(self.value(spec, "amplitude")),
            period=float(self.value(spec, "period")),
        )


DRIVES: dict[str, DriveKind] = {k: t for k, t in TASKS.items() if isinstance(t, DriveKind)}
"""The drive task kinds (a plan's ``tasks``), each with its ``run``."""


def keys_table() -> list[str]:
    """The task kinds' keys as a Markdown table (docs/mira3d.md shows it; a test checks)."""
    rows = ["| kind | key | values | default | meaning |", "|---|---|---|---|---|"]
    for kind, task in TASKS.items():
        for key, k in task.keys.items():
            default = (
                "required"
                if k.default is None
                else str(k.default).lower()
                if isinstance(k.default, bool)
                else f"{k.default:g}"
            )
            rows.append(f"| `{kind}` | `{key}` | {k.allowed} | {default} | {k.meaning} |")
    return rows
