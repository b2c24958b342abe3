"""A built facility with its rovers, stepped with wheel and arm commands through the
actuators only; every rover's odometry integrated after every step.

The physics steps through one :class:`~urdf2mjcf.runner.sim.Sim` (``RoverSim.sim``):
the arm targets are its control, the odometry its monitor, ``on_step`` its hooks."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import mujoco
import numpy as np

from ...limits import TIMESTEP_RANGE
from ..load import LoadError, open_facility
from ..sim import Sim
from .odometry import Odometry, rotation_matrix, true_pose, yaw_of
from .report import TaskReport, Track
from .roles import Rover, RoverError, find_rovers
from .tasks import ArmWave, Task

HOLD_GAIN = 10.0
"""Wheel hold (brake): commanded wheel speed per radian of wheel drift, 1/s."""
SETTLE_MAX = 60.0
"""s: the longest settle (``rover-drive --settle``)."""
TASK_TIMEOUT = 120.0
"""s simulated: a task not done by then is an error (every task's step count is bounded)."""


class RoverSim:
    """A built facility with its rovers, stepped with wheel and arm commands."""

    def __init__(self, folder: str | Path, *, keyframe: str | None = "home"):
        self.folder, path, self.manifest, self.m, self.d = open_facility(folder, keyframe=keyframe)
        sim = Sim(self.m, self.d, self.manifest, folder=self.folder, manifest_path=path)
        self.sim = sim
        """The one Sim the rovers step through."""
        try:  # the roles were checked as facility.json was read; the scene may lack a name
            self.rovers = find_rovers(self.m, self.manifest)
        except LoadError as exc:
            raise RoverError(exc.detail, file=path, element="components.*.roles") from None
        dt = float(self.m.opt.timestep)
        low, high = TIMESTEP_RANGE
        if not low <= dt <= high:  # a hand-edited scene: every step count below divides by it
            raise RoverError(
                f"timestep {dt:g} s is out of range ({low:g} to {high:g})",
                file=self.folder / "scene.xml",
                element="option timestep",
            )
        if not self.rovers:
            raise RoverError(
                "the facility has no rover (no component with wheel roles); "
                "rover-drive needs a MIRA3D world (recipes/mira3d-*.yaml)",
                file=path,
                element="components",
            )
        self.home = {n: self.d.ctrl[r.arm].copy() for n, r in self.rovers.items()}
        self.arm_targets = {n: q.copy() for n, q in self.home.items()}
        self.odometry: dict[str, Odometry] = {}
        self._hold: dict[str, np.ndarray] = {}
        self.reset_odometry()
        sim.control.append(self._command_arms)
        sim.monitor.append(self._integrate_odometry)

    @property
    def on_step(self) -> list[Callable[[], None]]:
        """Called after every physics step (a recorder), whatever runs the steps: the
        Sim's hooks."""
        return self.sim.on_step

    @on_step.setter
    def on_step(self, hooks: list[Callable[[], None]]) -> None:
        self.sim.on_step = hooks

    @property
    def dt(self) -> float:
        return self.sim.dt

    def reset_odometry(self, name: str | None = None) -> None:
        """Odometry of ``name`` (or every rover) restarted at its true pose."""
        for n, r in self.rovers.items():
            if name is not None and n != name:
                continue
            pose = true_pose(self.m, self.d, r)
            q = self.d.sensordata[r.orientation : r.orientation + 4]
            self.odometry[n] = Odometry(
                pose.x, pose.y, pose.yaw, self.d.xpos[r.base].copy(), imu_yaw=yaw_of(q)
            )

    def rover(self, name: str | None = None) -> Rover:
        if name is None:
            if len(self.rovers) != 1:
                raise RoverError(f"name a rover: {', '.join(self.rovers)}")
            return next(iter(self.rovers.values()))
        if name not in self.rovers:
            raise RoverError(
                f"no rover '{name}'; rovers: {', '.join(self.rovers)}",
                file=self.folder / "facility.json",
                element="--rover",
            )
        return self.rovers[name]

    def drive(self, rover: Rover, v: float | None, w: float = 0.0) -> None:
        """Wheel velocity commands for a body speed ``v`` (m/s) and yaw rate ``w`` (rad/s);
        ``v=None``: brake (hold the wheels)."""
        if v is None:
            self.brake(rover)
            return
        self._hold.pop(rover.name, None)
        lo, hi = rover.wheel_ctrl
        left = (v - w * rover.track / 2) / rover.radius
        right = (v + w * rover.track / 2) / rover.radius
        # scale both sides together so a saturated command keeps its curvature
        scale = max(1.0, abs(left) / hi, abs(right) / hi)
        self.d.ctrl[rover.left] = np.clip(left / scale, lo, hi)
        self.d.ctrl[rover.right] = np.clip(right / scale, lo, hi)

    def wheels(self, rover: Rover, left: float, right: float) -> None:
        """Wheel velocity commands of each side (rad/s), clipped to the servos' range;
        ends a brake."""
        self._hold.pop(rover.name, None)
        lo, hi = rover.wheel_ctrl
        self.d.ctrl[rover.left] = np.clip(left, lo, hi)
        self.d.ctrl[rover.right] = np.clip(right, lo, hi)

    def brake(self, rover: Rover) -> None:
        """Hold the wheels where they are: a position loop through the velocity servos
        (``HOLD_GAIN`` rad/s per rad), as a motor controller holds a rover on a slope; a
        velocity servo alone lets it creep downhill."""
        if rover.name not in self._hold:
            self._hold[rover.name] = self.d.qpos[rover.wheel_qpos].copy()
        lo, hi = rover.wheel_ctrl
        err = self._hold[rover.name] - self.d.qpos[rover.wheel_qpos]
        n = len(rover.left)
        cmd = np.clip(HOLD_GAIN * err, lo, hi)
        self.d.ctrl[rover.left] = cmd[:n]
        self.d.ctrl[rover.right] = cmd[n:]

    def wheel_speed(self, rover: Rover) -> float:
        """Largest wheel speed (rad/s)."""
        return float(np.max(np.abs(self.d.sensordata[np.r_[rover.left_vel, rover.right_vel]])))

    def step(self, n: int = 1) -> None:
        """Step the physics ``n`` times with the current commands; update every odometry."""
        self.sim.step(n)

    def _command_arms(self) -> None:
        """The Sim's control: every arm at its targets, before every physics step."""
        for name, r in self.rovers.items():
            self.d.ctrl[r.arm] = self.arm_targets[name]

    def _integrate_odometry(self) -> None:
        """The Sim's monitor: every rover's odometry, right after every physics step."""
        dt = self.dt
        for name, r in self.rovers.items():
            self.odometry[name].update(r, self.d, dt)

    def settle(self, seconds: float = 1.0) -> None:
        """Stand still (wheels held, arm at its targets) for ``seconds`` (0 .. SETTLE_MAX);
        odometry restarts."""
        if not 0.0 <= seconds <= SETTLE_MAX:  # also NaN
            raise RoverError(f"settle {seconds} s is not from 0 to {SETTLE_MAX:g} s")
        for _ in range(int(round(seconds / self.dt))):
            for r in self.rovers.values():
                self.brake(r)
            self.step()
        self.reset_odometry()

    def warnings(self) -> dict[str, int]:
        return {
            mujoco.mjtWarning(i).name: int(w.number)
            for i, w in enumerate(self.d.warning)
            if w.number
        }

    def run(
        self,
        tasks: Mapping[str, Task],
        arm: Mapping[str, ArmWave] | None = None,
        timeout: float = TASK_TIMEOUT,
        on_step: Callable[[RoverSim], None] | None = None,
    ) -> dict[str, TaskReport]:
        """Run one task per rover at the same time until all are done; return a report per
        task, taken when that task ended. Rovers without a task, and rovers whose task has
        ended, brake; an arm motion stops (back to the home targets) with its rover's task.
        ``on_step`` is called after every physics step."""
        arm = dict(arm or {})
        t0 = self.d.time
        for name, task in tasks.items():
            task.start(self, self.rover(name))
        track = {n: Track(self, self.rovers[n]) for n in tasks}
        out: dict[str, TaskReport] = {}
        while len(out) < len(tasks):
            if self.d.time - t0 > timeout:
                late = ", ".join(n for n in tasks if n not in out)
                raise RoverError(f"{late}: not done after {timeout:g} s")
            for name, r in self.rovers.items():
                current = tasks.get(name)
                if current is None or name in out:
                    self.brake(r)
                    continue
                self.drive(r, *current.command(self, r))
                if name in arm:
                    self.arm_targets[name] = arm[name].targets(self.home[name], self.d.time - t0)
            self.step()
            for name, task in tasks.items():
                if name in out:
                    continue
                track[name].update(self)
                if task.done:
                    out[name] = track[name].report(self, task, self.d.time - t0)
                    self.arm_targets[name] = self.home[name].copy()
            if on_step is not None:
                on_step(self)
        return out

    def imu_up(self, rover: Rover) -> tuple[float, float]:
        """(magnitude, vertical component in the world) of the accelerometer reading, m/s^2."""
        a = self.d.sensordata[rover.accel : rover.accel + 3]
        q = self.d.sensordata[rover.orientation : rover.orientation + 4]
        world = rotation_matrix(q) @ a
        return float(np.linalg.norm(a)), float(world[2])
