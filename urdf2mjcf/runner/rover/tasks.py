"""What each rover does, one command per step: closed loops on the odometry
(``Straight``, ``Turn``, ``Hold``) and an arm motion (``ArmWave``); and their kinds.

:data:`TASKS` maps each kind a task plan names (``straight``, ``turn``, ``hold``,
``arm_wave``) to its registered class, as :mod:`urdf2mjcf.runner.steps` does for the
demo's steps: ``keys`` and ``required`` are its schema, read from the kind's
declaration in :mod:`urdf2mjcf.runner.task_kinds` (each key's type, range, default and
meaning, declared once), :meth:`TaskKind.check` checks a task against one rover of
the bundle (an arm joint index against its arm joints), :meth:`TaskKind.build` makes
the task from a checked mapping and :meth:`DriveKind.run` runs it on rovers at once.
``rover-drive --distance/--turn/--arm`` and ``--plan`` (:mod:`.plan_file`) both make
their tasks here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..checks import Check, Waypoints
from ..task_kinds import (  # noqa: F401  (the limits, importable where they were)
    ACCEL_MAX,
    AMPLITUDE_MAX,
    ARM_WAVE,
    DISTANCE_MAX,
    HOLD,
    HOLD_MAX,
    PERIOD_RANGE,
    RATE_MAX,
    SPEED_MAX,
    STRAIGHT,
    TURN,
    TURN_MAX,
    Param,
)
from ..task_kinds import TaskKind as Declared
from ..task_kinds import keys_table as _keys_table
from .roles import Rover
from .state import SimState


class Task:
    """A closed loop on the odometry: ``command`` gives (v m/s, yaw rate rad/s) each step."""

    done: bool = False

    def start(self, sim: SimState, rover: Rover) -> None:
        pass

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        """(v m/s, yaw rate rad/s); v None: brake."""
        raise NotImplementedError


def speed_profile(remaining: float, elapsed: float, top: float, accel: float) -> float:
    """Trapezoidal speed: ramp up at ``accel``, cruise at ``top``, brake to stop at the goal."""
    return max(0.0, min(top, accel * (elapsed + 0.05), math.sqrt(2 * accel * max(0.0, remaining))))


@dataclass
class Straight(Task):
    """Drive ``distance`` m (wheel odometry; negative: backwards), holding the start heading
    with the IMU (a rover's heading hold), then stop."""

    distance: float
    speed: float = STRAIGHT.default("speed")
    accel: float = STRAIGHT.default("accel")
    hold_heading: bool = STRAIGHT.default("hold_heading")
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
        v = sign * speed_profile(remaining, sim.d.time - self._t0, self.speed, self.accel)
        w = -self.heading_gain * (odo.turned_imu - self._h0) if self.hold_heading else 0.0
        return v, w


@dataclass
class Turn(Task):
    """Turn in place by ``angle`` rad (positive: left), measured by the IMU (``imu=True``)
    or by the wheels, then stop."""

    angle: float
    rate: float = math.radians(TURN.default("rate_deg"))
    """rad/s: the plan's ``rate_deg``, 30 deg/s unless given."""
    accel: float = 1.0
    imu: bool = TURN.default("imu")
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
        return 0.0, sign * speed_profile(remaining, sim.d.time - self._t0, self.rate, self.accel)


@dataclass
class Hold(Task):
    """Stand still for ``duration`` s."""

    duration: float = HOLD.default("duration")

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

    joint: int = ARM_WAVE.default("joint")
    amplitude: float = ARM_WAVE.default("amplitude")
    period: float = ARM_WAVE.default("period")

    def targets(self, home: np.ndarray, t: float) -> np.ndarray:
        q = home.copy()
        ease = min(1.0, t / self.period)
        q[self.joint] += ease * self.amplitude * math.sin(2 * math.pi * t / self.period)
        return q


# -- the kinds a task plan names ------------------------------------------------------


@dataclass(frozen=True)
class Key:
    """One key of a task kind, read from its declared :class:`~..task_kinds.Param`."""

    param: Param

    @property
    def check(self) -> Check:
        return self.param.check

    @property
    def default(self) -> Any:
        return self.param.default


def _keys(kind: Declared) -> dict[str, Key]:
    return {p.name: Key(p) for p in kind.params}


def _required(kind: Declared) -> tuple[str, ...]:
    return tuple(p.name for p in kind.params if p.required)


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
    keys = _keys(STRAIGHT)
    required = _required(STRAIGHT)

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
    keys = _keys(TURN)
    required = _required(TURN)

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
    keys = _keys(HOLD)
    required = _required(HOLD)

    def least_seconds(self, spec: Mapping) -> float:
        return float(self.value(spec, "duration"))

    def build(self, spec: Mapping) -> Hold:
        return Hold(float(self.value(spec, "duration")))


@register
class ArmWaveKind(TaskKind):
    kind = "arm_wave"
    arm = True
    keys = _keys(ARM_WAVE)
    required = _required(ARM_WAVE)

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
    return _keys_table(("drive", "arm"))
