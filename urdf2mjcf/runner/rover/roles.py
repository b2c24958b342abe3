"""The rovers of a built facility: the components of ``facility.json`` whose roles name
wheels, resolved to MuJoCo ids and sensor addresses. Their roles were checked as
facility.json was read (``urdf2mjcf.bundle_manifest.RoverRoles``: a wheel radius or
track in (0, ``WHEEL_LENGTH_MAX``] m, every name a string)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from ...bundle_manifest import Manifest, RoverRoles
from ...errors import RoverError
from ..load import LoadError, lookup


def _id(m: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    try:
        return lookup(m, kind, name)
    except LoadError as exc:
        raise RoverError(str(exc)) from None


def _sensor_adr(m: mujoco.MjModel, name: str) -> int:
    return int(m.sensor_adr[_id(m, mujoco.mjtObj.mjOBJ_SENSOR, name)])


@dataclass
class Rover:
    """One rover's roles as MuJoCo ids and addresses."""

    name: str
    prefix: str
    base: int
    """Body id of the base (its pose is the rover's pose)."""
    left: np.ndarray
    """Actuator ids of the left wheels."""
    right: np.ndarray
    left_vel: np.ndarray
    """sensordata addresses of the left wheels' jointvel sensors."""
    right_vel: np.ndarray
    radius: float
    track: float
    arm: np.ndarray
    """Actuator ids of the arm joints (roles order)."""
    arm_qpos: np.ndarray
    """qpos addresses of the arm joints."""
    accel: int
    gyro: int
    orientation: int
    """sensordata addresses of the IMU's accelerometer, gyro and framequat."""
    wheel_ctrl: tuple[float, float]
    """Command range of the wheel servos, rad/s."""
    wheel_qpos: np.ndarray
    """qpos addresses of the wheel joints (left, then right)."""
    spec: RoverRoles = field(repr=False)
    """Its roles, checked as facility.json was read (the names above come from them)."""
    roles: Mapping[str, Any] = field(default_factory=dict, repr=False)
    """Every role facility.json lists for it."""


def find_rovers(m: mujoco.MjModel, manifest: Manifest) -> dict[str, Rover]:
    """The components of the manifest whose roles name wheels (their rover roles were
    checked as facility.json was read), by component name; a RoverError naming a role
    the scene lacks."""
    A = mujoco.mjtObj.mjOBJ_ACTUATOR
    J = mujoco.mjtObj.mjOBJ_JOINT
    out: dict[str, Rover] = {}
    for name, spec in manifest.rovers().items():
        left = np.array([_id(m, A, a) for a in spec.wheel_actuators.left])
        right = np.array([_id(m, A, a) for a in spec.wheel_actuators.right])
        lo = float(max(m.actuator_ctrlrange[np.r_[left, right], 0]))
        hi = float(min(m.actuator_ctrlrange[np.r_[left, right], 1]))
        comp = manifest.components[name]
        out[name] = Rover(
            name=name,
            prefix=comp.prefix or "",
            base=_id(m, mujoco.mjtObj.mjOBJ_BODY, spec.base),
            left=left,
            right=right,
            left_vel=np.array([_sensor_adr(m, s) for s in spec.wheel_sensors.left]),
            right_vel=np.array([_sensor_adr(m, s) for s in spec.wheel_sensors.right]),
            radius=float(spec.wheel_radius),
            track=float(spec.track),
            arm=np.array([_id(m, A, a) for a in spec.arm_actuators]),
            arm_qpos=np.array([m.jnt_qposadr[_id(m, J, j)] for j in spec.arm_joints]),
            accel=_sensor_adr(m, spec.imu.accelerometer),
            gyro=_sensor_adr(m, spec.imu.gyro),
            orientation=_sensor_adr(m, spec.imu.orientation),
            wheel_ctrl=(lo, hi),
            wheel_qpos=np.array(
                [m.jnt_qposadr[_id(m, J, j)] for j in [*spec.wheels.left, *spec.wheels.right]]
            ),
            spec=spec,
            roles=comp.roles or {},
        )
    return out
