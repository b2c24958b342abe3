"""The deliver task's regolith: free grains in a pile, carried by welds to a rover's base
(``facility/worlds/mira3d_world``, flag ``deliver``), and where their mass is.

A weld's force acts on the base it is welded to, so a carried load weighs on that rover's
wheels. A transfer never jumps: it turns a weld on at the grain's present pose relative to
the base and moves that pose to the grain's hopper slot over ``TRANSFER_TIME``."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..load import LoadError
from .roles import Rover, RoverError
from .state import SimState
from .tasks import Task

HOPPER = np.array([-0.23, 0.0, 0.79])
"""m, base frame: the middle of the hopper's lowest layer, 1 cm above the control box."""
HOPPER_HALF = np.array([0.30, 0.30, 0.15])
"""m: a grain within this box about ``HOPPER`` (its z from the layer up) is in the hopper."""
SLOT = 0.11
"""m between grain centres in the hopper (grains are 0.10 m wide)."""
TRANSFER_TIME = 2.0
"""s from a weld's start pose to the hopper slot (a scoop, or the hand-over)."""
REACH = 3.0
"""m: the farthest a grain may be from the hopper to be scooped or handed over."""


def _name(m: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(m, kind, name)
    if i < 0:
        raise LoadError(f"no {kind.name[6:].lower()} '{name}'")
    return i


@dataclass
class Grains:
    """The pile's grains: body ids, masses and each rover's welds."""

    bodies: np.ndarray
    mass: np.ndarray
    """kg, from the model (``body_mass``)."""
    welds: dict[str, np.ndarray]
    """Equality ids by rover name (``collector``, ``printer``), one per grain."""
    qpos: np.ndarray
    """qpos address of each grain's free joint."""

    @classmethod
    def find(cls, m: mujoco.MjModel) -> Grains:
        body = mujoco.mjtObj.mjOBJ_BODY
        eq = mujoco.mjtObj.mjOBJ_EQUALITY
        ids: list[int] = []
        while mujoco.mj_name2id(m, body, f"regolith_{len(ids)}") >= 0:
            ids.append(_name(m, body, f"regolith_{len(ids)}"))
        if not ids:
            raise RoverError(
                "the facility has no regolith (regolith_0 ...): build a recipe whose "
                "flags set deliver: true (recipes/mira3d-pair.yaml)"
            )
        welds = {
            r: np.array([_name(m, eq, f"regolith_{k}_{r}") for k in range(len(ids))])
            for r in ("collector", "printer")
        }
        bodies = np.array(ids)
        qpos = np.array([m.jnt_qposadr[m.body_jntadr[b]] for b in bodies])
        return cls(bodies, m.body_mass[bodies].copy(), welds, qpos)

    def slot(self, k: int) -> np.ndarray:
        """Grain ``k``'s place in a hopper (base frame): 3 x 3 per layer."""
        layer, i = divmod(k, 9)
        return HOPPER + np.array([SLOT * (i % 3 - 1), SLOT * (i // 3 - 1), SLOT * layer])

    def in_hopper(self, d: mujoco.MjData, rover: Rover) -> np.ndarray:
        """Per grain: whether it lies in ``rover``'s hopper now."""
        rot = d.xmat[rover.base].reshape(3, 3)
        local = (d.xpos[self.bodies] - d.xpos[rover.base]) @ rot - HOPPER
        local[:, 2] -= HOPPER_HALF[2] - 0.05  # the box from the layer's bottom up
        return np.all(np.abs(local) <= HOPPER_HALF, axis=1)

    def held(self, d: mujoco.MjData, rover: str) -> np.ndarray:
        return d.eq_active[self.welds[rover]].astype(bool)


def relative_pose(d: mujoco.MjData, base: int, body: int) -> tuple[np.ndarray, np.ndarray]:
    """``body``'s position and orientation in ``base``'s frame (a weld's relpose)."""
    rot = d.xmat[base].reshape(3, 3)
    pos = (d.xpos[body] - d.xpos[base]) @ rot
    q_inv = np.zeros(4)
    mujoco.mju_negQuat(q_inv, d.xquat[base])
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, q_inv, d.xquat[body])
    return pos, quat


class Transfer(Task):
    """Weld the grains within ``REACH`` of ``rover``'s hopper to its base and bring them
    into the hopper; a grain another rover held is let go by it first (the hand-over). A
    grain out of reach is let go and falls (spilled). The rover brakes meanwhile."""

    def __init__(self, grains: Grains, giver: str | None):
        self.grains, self.giver = grains, giver
        self.taken: list[int] = []
        self.dropped: list[int] = []

    def start(self, sim: SimState, rover: Rover) -> None:
        m, d, g = sim.m, sim.d, self.grains
        self.done = False
        self._t0 = float(d.time)
        self._from: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        hopper = d.xpos[rover.base] + d.xmat[rover.base].reshape(3, 3) @ HOPPER
        candidates = np.flatnonzero(g.held(d, self.giver)) if self.giver else range(len(g.bodies))
        for k in candidates:
            k = int(k)
            if self.giver:
                d.eq_active[g.welds[self.giver][k]] = 0
            if np.linalg.norm(d.xpos[g.bodies[k]] - hopper) > REACH:
                self.dropped.append(k)
                continue
            eq = g.welds[rover.name][k]
            pos, quat = relative_pose(d, rover.base, int(g.bodies[k]))
            m.eq_data[eq, 3:6] = pos
            m.eq_data[eq, 6:10] = quat
            d.eq_active[eq] = 1
            self._from[k] = (pos, quat)
            self.taken.append(k)

    def command(self, sim: SimState, rover: Rover) -> tuple[float | None, float]:
        s = min(1.0, (float(sim.d.time) - self._t0) / TRANSFER_TIME)
        ease = s * s * (3 - 2 * s)  # starts and ends at rest
        for k, (pos, quat) in self._from.items():
            eq = self.grains.welds[rover.name][k]
            sim.m.eq_data[eq, 3:6] = (1 - ease) * pos + ease * self.grains.slot(k)
            q = (1 - ease) * quat + ease * np.array([1.0, 0.0, 0.0, 0.0])
            sim.m.eq_data[eq, 6:10] = q / np.linalg.norm(q)
        # half a second more for the grains to come to rest in their slots
        self.done = float(sim.d.time) - self._t0 >= TRANSFER_TIME + 0.5
        return None, 0.0


def supported_weight(m: mujoco.MjModel, d: mujoco.MjData, rover: Rover) -> float:
    """N: the sum of the normal forces on ``rover``'s geoms from everything it touches (the
    ground under its wheels): what its wheels carry."""
    root = int(m.body_rootid[rover.base])
    force = np.zeros(6)
    total = 0.0
    for i in range(d.ncon):
        c = d.contact[i]
        b1, b2 = m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2]
        if (m.body_rootid[b1] == root) != (m.body_rootid[b2] == root):
            mujoco.mj_contactForce(m, d, i, force)
            total += abs(force[0])
    return total
