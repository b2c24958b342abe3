"""An arc of tool poses around a hinge joint, about the axis where the robot believes it is.

The axis is the joint's anchor and direction in its body (the description:
``jnt_pos``, ``jnt_axis``) carried into the world by the body's pose as the caller
knows it: for a mockup, the pose estimated from its tags (runner/demo.py), never
its pose in the simulated model. Both are unchanged by the joint's own angle, so
the lid's pose in the description (shut) serves at any opening. The tool position is
rotated about the axis by each step's angle; its orientation is either held
(as the real demo does) or rotated with the lid.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation


def hinge_axis(
    m: mujoco.MjModel, joint: int, body_pose: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A point on the hinge's axis and its unit direction, in the world, for the joint's
    body at ``body_pose`` ((4, 4) in the world)."""
    if m.jnt_type[joint] != mujoco.mjtJoint.mjJNT_HINGE:
        raise ValueError(f"joint '{m.joint(joint).name}' is not a hinge")
    t = np.asarray(body_pose, float)
    axis = t[:3, :3] @ m.jnt_axis[joint]
    return t[:3, :3] @ m.jnt_pos[joint] + t[:3, 3], axis / np.linalg.norm(axis)


def arc(
    anchor: np.ndarray,
    axis: np.ndarray,
    start_pos: np.ndarray,
    start_rot: np.ndarray,
    *,
    steps: int = 8,
    step_deg: float = 11.5,
    hold_orientation: bool = True,
) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``steps`` poses after the start: (angle in rad, position, rotation) each, the
    position turned about the axis through ``anchor`` by k x ``step_deg``."""
    out = []
    for k in range(1, steps + 1):
        ang = math.radians(step_deg * k)
        out.append((ang, *turned(anchor, axis, start_pos, start_rot, ang, hold_orientation)))
    return out


def turned(
    anchor: np.ndarray,
    axis: np.ndarray,
    pos: np.ndarray,
    rot: np.ndarray,
    angle: float,
    hold_orientation: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """The pose (pos, rot) turned by ``angle`` (rad) about the hinge axis."""
    a = np.asarray(axis, float)
    R = Rotation.from_rotvec(angle * a / np.linalg.norm(a)).as_matrix()
    return anchor + R @ (np.asarray(pos, float) - anchor), (
        rot.copy() if hold_orientation else R @ rot
    )
