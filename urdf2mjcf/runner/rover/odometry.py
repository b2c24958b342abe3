"""Dead reckoning of a rover (wheels; wheels + IMU) and its true pose."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from .roles import Rover


def yaw_of(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def wrap_angle(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def rotation_matrix(quat: np.ndarray) -> np.ndarray:
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, np.asarray(quat, float))
    return r.reshape(3, 3)


@dataclass
class Odometry:
    """Dead reckoning of one rover; starts at the true pose (the rover's map origin)."""

    x: float
    y: float
    yaw: float
    fused: np.ndarray
    """Wheel + IMU position (3D)."""
    distance: float = 0.0
    """Path length from the wheels (m, signed: backwards counts negative)."""
    turned: float = 0.0
    """Yaw turned according to the wheels (rad, unwrapped)."""
    turned_imu: float = 0.0
    """Yaw turned according to the IMU's orientation (rad, unwrapped)."""
    imu_yaw: float = 0.0

    def update(self, rover: Rover, d: mujoco.MjData, dt: float) -> None:
        wl = float(np.mean(d.sensordata[rover.left_vel]))
        wr = float(np.mean(d.sensordata[rover.right_vel]))
        v = rover.radius * (wl + wr) / 2
        w = rover.radius * (wr - wl) / rover.track
        mid = self.yaw + w * dt / 2
        self.x += v * math.cos(mid) * dt
        self.y += v * math.sin(mid) * dt
        self.yaw = wrap_angle(self.yaw + w * dt)
        self.turned += w * dt
        self.distance += v * dt
        q = d.sensordata[rover.orientation : rover.orientation + 4]
        self.fused = self.fused + rotation_matrix(q)[:, 0] * v * dt
        yaw = yaw_of(q)
        self.turned_imu += wrap_angle(yaw - self.imu_yaw)
        self.imu_yaw = yaw


@dataclass
class Pose:
    x: float
    y: float
    z: float
    yaw: float
    roll: float
    pitch: float
    tilt: float
    """Angle between the rover's z axis and the world's (rad)."""


def true_pose(m: mujoco.MjModel, d: mujoco.MjData, rover: Rover) -> Pose:
    p = d.xpos[rover.base]
    r = d.xmat[rover.base].reshape(3, 3)
    yaw = math.atan2(r[1, 0], r[0, 0])
    pitch = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    roll = math.atan2(r[2, 1], r[2, 2])
    tilt = math.acos(max(-1.0, min(1.0, r[2, 2])))
    return Pose(float(p[0]), float(p[1]), float(p[2]), yaw, roll, pitch, tilt)
