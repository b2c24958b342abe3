"""Inverse kinematics: damped least squares on MuJoCo's site Jacobian.

Solved on a scratch copy of the data (``mj_kinematics`` only), never by moving
the running simulation. Joint limits are respected by clamping every step and
by a null-space pull towards the middle of the range for unlimited joints it
does nothing. Poses are (position, 3x3 rotation) of a site in the world.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass
class IKResult:
    q: np.ndarray
    ok: bool
    pos_err: float  # m
    rot_err: float  # rad
    iterations: int


def rot_err(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The rotation vector taking ``R`` to ``R_target`` (world frame)."""
    q_t, q_c, q_e = np.zeros(4), np.zeros(4), np.zeros(4)
    mujoco.mju_mat2Quat(q_t, np.ascontiguousarray(R_target).ravel())
    mujoco.mju_mat2Quat(q_c, np.ascontiguousarray(R).ravel())
    qc_inv = np.zeros(4)
    mujoco.mju_negQuat(qc_inv, q_c)
    mujoco.mju_mulQuat(q_e, q_t, qc_inv)
    v = np.zeros(3)
    mujoco.mju_quat2Vel(v, q_e, 1.0)
    return v


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
    damping: float = 1e-3,
    tol_pos: float = 1e-4,
    tol_rot: float = 1e-3,
    max_iter: int = 300,
    max_step: float = 0.2,
) -> IKResult:
    """Joint positions (of the joints at ``qpos_adr``) putting ``site`` at ``pos``
    (and ``rot`` unless None), starting from ``q0`` or the data's current state.

    ``weights`` scale each joint's share of the motion (a small weight makes a
    joint move only when the others cannot).
    """
    scratch = mujoco.MjData(m)
    scratch.qpos[:] = d.qpos
    q = (d.qpos[qpos_adr] if q0 is None else np.asarray(q0, float)).copy()
    q = np.clip(q, lower, upper)
    w = np.ones(len(q)) if weights is None else np.asarray(weights, float)
    W = np.sqrt(w)
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    pos = np.asarray(pos, float)
    ep, er = np.inf, 0.0
    for it in range(max_iter):
        scratch.qpos[qpos_adr] = q
        mujoco.mj_kinematics(m, scratch)
        mujoco.mj_comPos(m, scratch)
        e_p = pos - scratch.site_xpos[site]
        ep = float(np.linalg.norm(e_p))
        if rot is not None:
            e_r = rot_err(rot, scratch.site_xmat[site].reshape(3, 3))
            er = float(np.linalg.norm(e_r))
            err = np.concatenate([e_p, e_r])
        else:
            err = e_p
        if ep < tol_pos and er < tol_rot:
            return IKResult(q, True, ep, er, it)
        mujoco.mj_jacSite(m, scratch, jacp, jacr, site)
        J = np.vstack([jacp, jacr])[:, dof_adr] if rot is not None else jacp[:, dof_adr]
        # free joints at a limit that the step would push further: take them out
        Jw = J * W
        lam = damping + 0.05 * min(ep + er, 0.2)
        dq = W * (Jw.T @ np.linalg.solve(Jw @ Jw.T + lam * np.eye(len(err)), err))
        n = np.linalg.norm(dq)
        if n > max_step:
            dq *= max_step / n
        q_new = np.clip(q + dq, lower, upper)
        blocked = q_new != q + dq
        if blocked.any():  # re-solve with the blocked joints fixed
            Wb = W * ~blocked
            Jw = J * Wb
            dq = Wb * (Jw.T @ np.linalg.solve(Jw @ Jw.T + lam * np.eye(len(err)), err))
            n = np.linalg.norm(dq)
            if n > max_step:
                dq *= max_step / n
            q_new = np.clip(q + dq, lower, upper)
        q = q_new
    return IKResult(q, False, ep, er, max_iter)


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
