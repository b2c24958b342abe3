"""Inverse kinematics of the robot's joints with mink (differential IK on MuJoCo).

Each call iterates mink's quadratic program to convergence on mink's own copy of
the data (``mink.Configuration``), never moving the running simulation:

* a ``FrameTask`` on the site (position and orientation, or position only);
* a ``DampingTask`` with cost ``1/sqrt(weight)`` per joint: a joint with a small
  weight moves only when the others cannot (the rail, in the demo);
* a ``PostureTask`` towards the seed ``q0``: among the solutions it prefers the
  one nearest the seed, so a dense path stays on its branch;
* the joints' ranges as inequality constraints (a joint stops at its limit and
  the others take over), and every other degree of freedom of the model (the
  mockups, the free CTB, the gripper) frozen by a ``DofFreezingTask``.

Poses are (position, 3x3 rotation) of a site in the world.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mink
import mujoco
import numpy as np

SOLVER = "daqp"
"""qpsolvers backend: a small dense active-set solver, installed from a wheel."""


@dataclass
class IKResult:
    q: np.ndarray
    ok: bool
    pos_err: float  # m
    rot_err: float  # rad
    iterations: int


def rot_err(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The rotation vector taking ``R`` to ``R_target`` (world frame)."""
    q_t, q_c, q_e, qc_inv = np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4)
    mujoco.mju_mat2Quat(q_t, np.ascontiguousarray(R_target).ravel())
    mujoco.mju_mat2Quat(q_c, np.ascontiguousarray(R).ravel())
    mujoco.mju_negQuat(qc_inv, q_c)
    mujoco.mju_mulQuat(q_e, q_t, qc_inv)
    v = np.zeros(3)
    mujoco.mju_quat2Vel(v, q_e, 1.0)
    return v


class _JointBox(mink.Limit):
    """The ranges of the IK's own joints only (mink's ConfigurationLimit takes every
    limited joint of the model, mockups included, whose state may sit past its range)."""

    def __init__(
        self,
        m: mujoco.MjModel,
        dof_adr: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        gain: float = 0.95,
    ) -> None:
        self.P = np.eye(m.nv)[np.asarray(dof_adr)]
        self.lower, self.upper, self.gain = np.asarray(lower), np.asarray(upper), gain

    def set_q(self, q: np.ndarray) -> None:
        self.q = q

    def compute_qp_inequalities(
        self, configuration: mink.Configuration, dt: float
    ) -> mink.Constraint:
        del configuration, dt
        G = np.vstack([self.P, -self.P])
        h = self.gain * np.concatenate([self.upper - self.q, self.q - self.lower])
        return mink.Constraint(G=G, h=np.maximum(h, 0.0))


class ArmIK:
    """IK of one site over a set of joints (hinge or slide) of a model."""

    def __init__(
        self,
        m: mujoco.MjModel,
        site: int,
        qpos_adr: np.ndarray,
        dof_adr: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        *,
        weights: np.ndarray | None = None,
        damping: float = 1e-3,
        posture: float = 1e-2,
    ):
        self.m, self.site = m, site
        self.qpos_adr, self.dof_adr = np.asarray(qpos_adr), np.asarray(dof_adr)
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        w = np.ones(len(self.dof_adr)) if weights is None else np.asarray(weights, float)
        self.config = mink.Configuration(m)
        self.frame = mink.FrameTask(
            m.site(site).name, "site", position_cost=1.0, orientation_cost=1.0, lm_damping=1e-2
        )
        cost = np.zeros(m.nv)
        cost[self.dof_adr] = np.sqrt(damping / w)
        self.damping = mink.DampingTask(m, cost)
        cost = np.zeros(m.nv)
        cost[self.dof_adr] = posture
        self.posture = mink.PostureTask(m, cost)
        others = sorted(set(range(m.nv)) - {int(i) for i in self.dof_adr})
        self.freeze = [mink.DofFreezingTask(m, others)] if others else []
        self.box = _JointBox(m, self.dof_adr, self.lower, self.upper)

    def solve(
        self,
        d: mujoco.MjData,
        pos: np.ndarray,
        rot: np.ndarray | None,
        *,
        q0: np.ndarray | None = None,
        tol_pos: float = 1e-4,
        tol_rot: float = 1e-3,
        max_iter: int = 300,
        max_step: float = 0.2,
    ) -> IKResult:
        """Joint positions putting the site at ``pos`` (and ``rot`` unless None), starting
        from ``q0`` or the data's current state; the other joints as in ``d``."""
        full = d.qpos.copy()
        q = (d.qpos[self.qpos_adr] if q0 is None else np.asarray(q0, float)).copy()
        full[self.qpos_adr] = np.clip(q, self.lower, self.upper)
        self.posture.set_target(full)
        self.frame.set_orientation_cost(1.0 if rot is not None else 0.0)
        pos = np.asarray(pos, float)
        target_rot = np.eye(3) if rot is None else np.asarray(rot, float)
        self.frame.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(target_rot), pos)
        )
        cfg, ep, er = self.config, np.inf, 0.0
        for it in range(max_iter + 1):  # the last pass only measures the result
            cfg.update(full)
            ep = float(np.linalg.norm(pos - cfg.data.site_xpos[self.site]))
            if rot is not None:
                R = cfg.data.site_xmat[self.site].reshape(3, 3)
                er = float(np.linalg.norm(rot_err(rot, R)))
            ok = ep < tol_pos and er < tol_rot
            if ok or it == max_iter:
                return IKResult(full[self.qpos_adr].copy(), ok, ep, er, it)
            self.box.set_q(full[self.qpos_adr])
            v = mink.solve_ik(
                cfg,
                [self.frame, self.damping, self.posture],
                1.0,
                SOLVER,
                limits=[self.box],
                constraints=self.freeze,
            )
            dq = v[self.dof_adr]
            n = float(np.linalg.norm(dq))
            if n > max_step:
                dq *= max_step / n
            full[self.qpos_adr] = np.clip(full[self.qpos_adr] + dq, self.lower, self.upper)
        raise AssertionError("unreachable")


def solve(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    site: int,
    pos: np.ndarray,
    rot: np.ndarray | None,
    qpos_adr: np.ndarray,
    dof_adr: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    q0: np.ndarray | None = None,
    weights: np.ndarray | None = None,
    **kw: Any,
) -> IKResult:
    """One IK solution with a fresh :class:`ArmIK` (callers solving many poses keep one)."""
    ik = ArmIK(m, site, qpos_adr, dof_adr, lower, upper, weights=weights)
    return ik.solve(d, pos, rot, q0=q0, **kw)


def site_pose(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    site: int,
    q: np.ndarray | None = None,
    qpos_adr: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """A site's world pose at joint positions ``q`` (on a scratch copy) or now."""
    if q is None:
        return d.site_xpos[site].copy(), d.site_xmat[site].reshape(3, 3).copy()
    scratch = mujoco.MjData(m)
    scratch.qpos[:] = d.qpos
    scratch.qpos[qpos_adr] = q
    mujoco.mj_kinematics(m, scratch)
    return scratch.site_xpos[site].copy(), scratch.site_xmat[site].reshape(3, 3).copy()
