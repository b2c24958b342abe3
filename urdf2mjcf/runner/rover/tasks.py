"""What each rover does, one command per step: closed loops on the odometry
(``Straight``, ``Turn``, ``Hold``) and an arm motion (``ArmWave``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

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
    rate: float = 0.5
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
