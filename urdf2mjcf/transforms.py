"""Rigid-body math in the conventions of URDF and MuJoCo.

Quaternions are (w, x, y, z). Rotations from URDF ``rpy`` are fixed-axis:
R = Rz(yaw) @ Ry(pitch) @ Rx(roll).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .ir import Pose, Quat, Vec3

IDENTITY_QUAT: Quat = (1.0, 0.0, 0.0, 0.0)


def quat_from_rpy(rpy: Vec3) -> Quat:
    """Exact composition qz(yaw) * qy(pitch) * qx(roll), canonical sign (w >= 0)."""
    r, p, y = (0.5 * a for a in rpy)
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    q = (
        cy * cp * cr + sy * sp * sr,
        cy * cp * sr - sy * sp * cr,
        cy * sp * cr + sy * cp * sr,
        sy * cp * cr - cy * sp * sr,
    )
    return canonical_quat(q)


def canonical_quat(q: Quat | np.ndarray) -> Quat:
    """Unit quaternion with w >= 0 (first non-zero component positive)."""
    a = np.asarray(q, dtype=float)
    a = a / np.linalg.norm(a)
    for c in a:
        if c != 0.0:
            if c < 0:
                a = -a
            break
    return (float(a[0]) + 0.0, float(a[1]) + 0.0, float(a[2]) + 0.0, float(a[3]) + 0.0)


def quat_to_matrix(q: Quat) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(m: np.ndarray) -> Quat:
    """Shepperd's method: numerically stable for every rotation."""
    m = np.asarray(m, dtype=float)
    t = np.trace(m)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    return canonical_quat(q)


def quat_mul(a: Quat, b: Quat) -> Quat:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def rpy_to_matrix(rpy: Vec3) -> np.ndarray:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def quat_to_rpy(q: Quat) -> Vec3:
    """Fixed-axis (roll, pitch, yaw) of the unit quaternion ``q``; pitch from atan2, so it
    keeps its digits near +-pi/2, and at +-pi/2 exactly roll is 0 (yaw takes the turn)."""
    m = quat_to_matrix(q)
    cos_pitch = math.hypot(m[2, 1], m[2, 2])
    pitch = math.atan2(-m[2, 0], cos_pitch)
    if cos_pitch < 1e-12:  # gimbal lock: only yaw - roll (or yaw + roll) is defined
        return 0.0, pitch + 0.0, math.atan2(-m[0, 1], m[1, 1]) + 0.0
    return math.atan2(m[2, 1], m[2, 2]) + 0.0, pitch + 0.0, math.atan2(m[1, 0], m[0, 0]) + 0.0


def pose_quat(pose: Pose) -> Quat:
    """The rotation of a URDF origin: its quaternion (URDF 1.1) or that of its rpy."""
    return pose.quat if pose.quat is not None else quat_from_rpy(pose.rpy)


def pose_matrix(pose: Pose) -> np.ndarray:
    """(4, 4) homogeneous transform of a URDF origin."""
    t = np.eye(4)
    t[:3, :3] = rpy_to_matrix(pose.rpy) if pose.quat is None else quat_to_matrix(pose.quat)
    t[:3, 3] = pose.xyz
    return t


def transform(pos: Vec3, quat: Quat) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = quat_to_matrix(quat)
    t[:3, 3] = pos
    return t


def split_transform(t: np.ndarray) -> tuple[Vec3, Quat]:
    p = t[:3, 3]
    return (float(p[0]) + 0.0, float(p[1]) + 0.0, float(p[2]) + 0.0), matrix_to_quat(t[:3, :3])


def vec3(v: Sequence[float] | np.ndarray) -> Vec3:
    return (float(v[0]) + 0.0, float(v[1]) + 0.0, float(v[2]) + 0.0)


def inertia_matrix(i6_urdf: tuple[float, ...]) -> np.ndarray:
    """URDF (ixx, ixy, ixz, iyy, iyz, izz) -> symmetric (3, 3)."""
    ixx, ixy, ixz, iyy, iyz, izz = i6_urdf
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


def mujoco_fullinertia(m: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """Symmetric (3, 3) -> MuJoCo fullinertia order (ixx, iyy, izz, ixy, ixz, iyz)."""
    return (
        float(m[0, 0]) + 0.0,
        float(m[1, 1]) + 0.0,
        float(m[2, 2]) + 0.0,
        float(m[0, 1]) + 0.0,
        float(m[0, 2]) + 0.0,
        float(m[1, 2]) + 0.0,
    )
