"""Drive the robot through its actuators only, at the model's own timestep.

Joint-space moves follow a quintic time scaling (zero velocity and
acceleration at both ends) whose duration keeps every joint under its
velocity limit; Cartesian paths are a dense list of IK solutions timed the
same way along the path. The controller steps through a :class:`~.sim.Sim`: its
targets are written as the Sim's control before every physics step, a ``monitor``
callback (the judge) sees the state right after it, then the Sim's hooks.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .load import Facility
from .sim import Sim


def quintic(s: np.ndarray | float) -> np.ndarray | float:
    """Smooth 0 -> 1 time scaling: 10 s^3 - 15 s^4 + 6 s^5."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


PEAK = 1.875  # quintic peak speed / mean speed


def path_duration(path: np.ndarray, vmax: np.ndarray, minimum: float = 0.5) -> float:
    """Time for a quintic traversal of a joint path (rows) under ``vmax`` per joint."""
    length = np.abs(np.diff(path, axis=0)).sum(axis=0) if len(path) > 1 else np.zeros(path.shape[1])
    return max(minimum, float(np.max(PEAK * length / vmax)))


class Controller:
    """Position targets for the robot's actuators; time advances only by stepping."""

    def __init__(
        self,
        fac: Facility,
        vmax: np.ndarray,
        monitor: Callable[[], None] | None = None,
        *,
        sim: Sim | None = None,
    ):
        """``sim``: the Sim of ``fac`` to step through (None: a new one of ``fac``)."""
        self.fac = fac
        if sim is None:
            sim = Sim(fac.model, fac.data, fac.manifest, folder=fac.folder)
        self.sim = sim
        if self.sim.m is not fac.model or self.sim.d is not fac.data:
            raise ValueError("the Sim must hold the facility's own model and data")
        self.m, self.d = fac.model, fac.data
        self.r = fac.robot
        self.vmax = np.asarray(vmax, float)
        self._monitor: Callable[[], None] | None = None
        self.monitor = monitor
        self.target = self.d.qpos[self.r.qpos].copy()
        self.gripper = float(self.d.ctrl[self.r.gripper_actuator])
        self.sim.control.append(self._command)

    @property
    def monitor(self) -> Callable[[], None] | None:
        """Called right after every physics step, before the hooks (the demo's judge)."""
        return self._monitor

    @monitor.setter
    def monitor(self, value: Callable[[], None] | None) -> None:
        if self._monitor is not None:
            self.sim.monitor.remove(self._monitor)
        self._monitor = value
        if value is not None:
            self.sim.monitor.insert(0, value)

    @property
    def on_step(self) -> list[Callable[[], None]]:
        """The Sim's hooks, called after every physics step (recorders, live views)."""
        return self.sim.on_step

    @on_step.setter
    def on_step(self, hooks: list[Callable[[], None]]) -> None:
        self.sim.on_step = hooks

    @property
    def dt(self) -> float:
        return self.sim.dt

    def step(self, n: int = 1) -> None:
        self.sim.step(n)

    def _command(self) -> None:
        """The Sim's control: the servo targets, before every physics step."""
        d = self.d
        d.ctrl[self.r.actuators] = self.target
        d.ctrl[self.r.gripper_actuator] = self.gripper

    def _step(self) -> None:
        self.sim.step()

    def _track(self, targets: np.ndarray) -> None:
        """Step once per row of ``targets`` (joint targets, computed for the whole
        move at once: per-step numpy calls cost more than the physics step)."""
        targets = np.clip(targets, self.r.lower, self.r.upper)
        for row in targets:
            self.target = row
            self._step()

    def wait(self, seconds: float) -> None:
        self.step(int(round(seconds / self.dt)))

    def follow(self, path: np.ndarray, duration: float | None = None) -> float:
        """Follow a joint path (rows = waypoints, first = current target) with a quintic
        time scaling along its arc length; returns the duration."""
        path = np.atleast_2d(np.asarray(path, float))
        if not np.allclose(path[0], self.target):
            path = np.vstack([self.target, path])
        seg = np.abs(np.diff(path, axis=0)) / self.vmax
        cum = np.concatenate([[0.0], np.cumsum(seg.max(axis=1))])
        T = duration or path_duration(path, self.vmax)
        n = max(1, int(round(T / self.dt)))
        total = cum[-1]
        s = np.asarray(quintic(np.arange(1, n + 1) / n))
        if total <= 0:
            q = np.broadcast_to(path[-1], (n, path.shape[1]))
        else:
            u = s * total
            i = np.minimum(np.searchsorted(cum, u, side="right") - 1, len(path) - 2)
            w = (u - cum[i]) / np.maximum(cum[i + 1] - cum[i], 1e-12)
            q = path[i] + w[:, None] * (path[i + 1] - path[i])
        self._track(q)
        return T

    def play(self, times: np.ndarray, q: np.ndarray) -> float:
        """Follow a timed joint trajectory (a planned move: ``q[i]`` at ``times[i]`` s,
        from the current target), its samples linearly interpolated at every physics
        step; returns its duration."""
        times = np.asarray(times, float)
        q = np.atleast_2d(np.asarray(q, float))
        n = max(1, int(round(float(times[-1]) / self.dt)))
        t = np.minimum(np.arange(1, n + 1) * self.dt, float(times[-1]))
        self._track(np.column_stack([np.interp(t, times, q[:, j]) for j in range(q.shape[1])]))
        return float(times[-1])

    def move_to(self, q: np.ndarray, duration: float | None = None) -> float:
        return self.follow(np.vstack([self.target, np.asarray(q, float)]), duration)

    def set_gripper(self, opening: float, seconds: float = 1.0) -> None:
        """Ramp the gripper target to ``opening`` (per finger, m) and wait ``seconds``."""
        start = self.gripper
        n = max(1, int(round(seconds / self.dt)))
        ramp = max(1, n // 2)
        for k in range(1, n + 1):
            self.gripper = start + (opening - start) * float(quintic(min(1.0, k / ramp)))
            self._step()

    def settle(self, *, tol: float = 2e-3, vtol: float = 0.02, timeout: float = 2.0) -> bool:
        """Step until the robot is within ``tol`` of its target and slower than ``vtol``."""
        for _ in range(int(timeout / self.dt)):
            err = np.abs(self.d.qpos[self.r.qpos] - self.target).max()
            vel = np.abs(self.d.qvel[self.r.dofs]).max()
            if err < tol and vel < vtol:
                return True
            self._step()
        return False
