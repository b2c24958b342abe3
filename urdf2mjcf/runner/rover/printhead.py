"""The printer's layer: its printhead (the arm's ``printhead_tip``) moved along a planned
path by damped least-squares inverse kinematics through the arm's position servos, and
material deposited as it goes: pre-allocated bead bodies (mocap, ``bead_<k>``, parked
out of sight) put down under the nozzle every ``spacing`` of the path."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from .roles import Rover, RoverError
from .state import SimState
from .tasks import Task

SIDE = 0.4
"""m: the printed square's side."""
AHEAD = 1.1
"""m ahead of the printer's base: the square's centre."""
NOZZLE = 0.05
"""m: the nozzle's height above the ground while printing."""
SPEED = 0.2
"""m/s along the layer."""
APPROACH = 3.0
"""s to bring the arm from the home pose to the first corner (no material)."""
DWELL = 0.5
"""s the nozzle waits at the first corner before it moves along the layer."""
READY = (-0.7, -0.8, 2.2, -3.0, -1.57, -0.7)
"""rad: a posture with the nozzle ahead and down, where the layer's start is solved from."""
RETRACT = 1.0
"""s to bring the arm back to the layer's start after the layer (then home in ``APPROACH``)."""
IK_EVERY = 10
"""Physics steps between two inverse-kinematics updates of the arm's targets."""
BEAD_R = 0.015
"""m: a bead's radius (the world's ``bead_<k>`` spheres)."""


def square(centre: np.ndarray, yaw: float, side: float = SIDE) -> np.ndarray:
    """The closed square path (5 points, x y) about ``centre`` turned by ``yaw``."""
    h = side / 2
    corners = np.array([[-h, -h], [h, -h], [h, h], [-h, h], [-h, -h]])
    c, s = math.cos(yaw), math.sin(yaw)
    return corners @ np.array([[c, s], [-s, c]]) + centre


def along(path: np.ndarray, s: float) -> np.ndarray:
    """The point ``s`` m along ``path`` (clipped to its ends)."""
    for a, b in zip(path[:-1], path[1:], strict=True):
        seg = float(np.linalg.norm(b - a))
        if s <= seg:
            return a + (b - a) * (s / seg)
        s -= seg
    return path[-1].copy()


def distance_to(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Each point's distance (x y) to the polyline ``path``."""
    best = np.full(len(points), np.inf)
    for a, b in zip(path[:-1], path[1:], strict=True):
        ab = b - a
        s = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(a + s[:, None] * ab - points, axis=1))
    return best


def find_beads(m: mujoco.MjModel) -> np.ndarray:
    """Mocap indices of ``bead_0``, ``bead_1``, ..."""
    out: list[int] = []
    while (b := mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"bead_{len(out)}")) >= 0:
        out.append(int(m.body_mocapid[b]))
    if not out or min(out) < 0:
        raise RoverError("the facility has no printed layer's beads (bead_0 ...)")
    return np.array(out)


class PrintLayer(Task):
    """Print ``path`` (x y, world, at ground level ``ground`` m): approach its start, then
    move the nozzle along it at ``SPEED`` and put a bead under the nozzle (the first when it
    starts along the layer) each time it has gone ``spacing`` m from the last one; fold the
    arm back home. The rover brakes."""

    def __init__(self, path: np.ndarray, beads: np.ndarray, ground: float = 0.0):
        self.path = np.asarray(path, float)
        self.beads = beads
        self.ground = ground
        total = float(np.sum(np.linalg.norm(np.diff(self.path, axis=0), axis=1)))
        self.total = total
        self.spacing = total / (len(beads) - 1)
        self.placed: list[np.ndarray] = []
        self.done = False

    def start(self, sim: SimState, rover: Rover) -> None:
        m = sim.m
        self.done = False
        self._t0 = float(sim.d.time)
        self._site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"{rover.prefix}printhead_tip")
        if self._site < 0:
            raise RoverError(f"{rover.name}: no site '{rover.prefix}printhead_tip'")
        self._scratch = mujoco.MjData(m)
        self._ticks = 0
        self._end: float | None = None
        self._home = np.array(sim.arm_targets[rover.name], float)
        self._dofs = np.array([m.jnt_dofadr[j] for j in self._joints(m, rover)])
        # the arm at the layer's first point, from a posture reaching ahead and down
        first = np.array([*self.path[0], self.ground + NOZZLE])
        self._q = np.array(READY, float)
        for _ in range(60):
            self._ik(sim, rover, first)
        self._first = self._q.copy()
        self._start_tip = sim.d.site_xpos[self._site].copy()

    @staticmethod
    def _joints(m: mujoco.MjModel, rover: Rover) -> list[int]:
        return [int(m.actuator_trnid[a, 0]) for a in rover.arm]

    def _ik(self, sim: SimState, rover: Rover, goal: np.ndarray) -> None:
        """A few damped least-squares steps of the arm's targets towards the nozzle at
        ``goal`` pointing straight down, on a copy of the state."""
        m, s = sim.m, self._scratch
        s.qpos[:] = sim.d.qpos
        jac_p, jac_r = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        for _ in range(3):
            s.qpos[rover.arm_qpos] = self._q
            mujoco.mj_kinematics(m, s)
            mujoco.mj_comPos(m, s)
            err_p = goal - s.site_xpos[self._site]
            z = s.site_xmat[self._site].reshape(3, 3)[:, 2]
            err_r = np.cross(z, np.array([0.0, 0.0, -1.0]))  # the tool's z axis straight down
            mujoco.mj_jacSite(m, s, jac_p, jac_r, self._site)
            jac = np.vstack([jac_p[:, self._dofs], 0.3 * jac_r[:, self._dofs]])
            err = np.concatenate([err_p, 0.3 * err_r])
            lam = 1e-3
            dq = jac.T @ np.linalg.solve(jac @ jac.T + lam * np.eye(6), err)
            self._q = self._q + np.clip(dq, -0.05, 0.05)

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        t = float(sim.d.time) - self._t0
        if t < APPROACH:  # in joint space, to the layer's start solved beforehand
            s = t / APPROACH
            ease = s * s * (3 - 2 * s)
            sim.arm_targets[rover.name][:] = (1 - ease) * self._home + ease * self._first  # type: ignore[index]
            return None, 0.0
        else:
            s = max(0.0, t - APPROACH - DWELL) * SPEED
            goal = np.array([*along(self.path, s), self.ground + NOZZLE])
            tip = sim.d.site_xpos[self._site]
            if self._end is None and t >= APPROACH + DWELL:
                self._deposit(sim, tip)
            if s >= self.total + 0.02 and self._end is None:  # the end: the last bead
                self._deposit(sim, tip, last=True)
                self._end = t
        if self._end is not None:
            # back to the home pose slowly: a snap would throw the rover in 1/6 g
            # the way it came: to the layer's start (the square closes there), then home
            r = min(1.0, (t - self._end) / RETRACT)
            back = min(1.0, max(0.0, (t - self._end - RETRACT) / APPROACH))
            a, b = r * r * (3 - 2 * r), back * back * (3 - 2 * back)
            start = (1 - a) * self._q + a * self._first
            sim.arm_targets[rover.name][:] = (1 - b) * start + b * self._home  # type: ignore[index]
            self.done = back >= 1.0
            return None, 0.0
        self._ticks += 1
        if self._ticks % IK_EVERY == 1:
            self._ik(sim, rover, goal)
        sim.arm_targets[rover.name][:] = self._q  # type: ignore[index]
        return None, 0.0

    def _deposit(self, sim: SimState, tip: np.ndarray, last: bool = False) -> None:
        """A bead under the nozzle once it has gone ``spacing`` from the last one."""
        if len(self.placed) >= len(self.beads):
            return
        here = np.array([tip[0], tip[1], self.ground + BEAD_R])
        if self.placed:
            gone = float(np.linalg.norm(here[:2] - self.placed[-1][:2]))
            if gone < self.spacing and not (last and gone > 0.25 * self.spacing):
                return

        sim.d.mocap_pos[self.beads[len(self.placed)]] = here
        self.placed.append(here)
