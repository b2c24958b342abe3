"""The rovers of a built facility: the components of ``facility.json`` whose roles name
wheels, resolved to MuJoCo ids and sensor addresses."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import mujoco
import numpy as np

from ...errors import RoverError
from ..load import LoadError, lookup


def _id(m: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    try:
        return lookup(m, kind, name)
    except LoadError as exc:
        raise RoverError(str(exc)) from None


LENGTH_MAX = 100.0
"""m: the largest wheel radius or track a roles file may give."""


def _length(value: object, rover: str, key: str) -> float:
    """A wheel radius or track from facility.json: a finite length in (0, LENGTH_MAX];
    every wheel command divides by it."""
    x = float(value)  # type: ignore[arg-type]  # TypeError/ValueError: malformed roles
    if not 0.0 < x <= LENGTH_MAX:  # also NaN
        raise RoverError(f"{rover}: {key} {x:g} m is not above 0 and at most {LENGTH_MAX:g}")
    return x


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
    roles: dict = field(default_factory=dict, repr=False)


def find_rovers(m: mujoco.MjModel, manifest: Mapping) -> dict[str, Rover]:
    """The components of the manifest whose roles name wheels, by component name."""
    A = mujoco.mjtObj.mjOBJ_ACTUATOR
    out: dict[str, Rover] = {}
    for name, comp in sorted(manifest.get("components", {}).items()):
        roles = comp.get("roles") or {}
        if "wheel_actuators" not in roles:
            continue
        acts = roles["wheel_actuators"]
        left = np.array([_id(m, A, a) for a in acts["left"]])
        right = np.array([_id(m, A, a) for a in acts["right"]])
        lo = float(max(m.actuator_ctrlrange[np.r_[left, right], 0]))
        hi = float(min(m.actuator_ctrlrange[np.r_[left, right], 1]))
        imu = roles["imu"]
        radius = _length(roles["wheel_radius"], name, "wheel_radius")
        track = _length(roles["track"], name, "track")
        out[name] = Rover(
            name=name,
            prefix=comp.get("prefix", ""),
            base=_id(m, mujoco.mjtObj.mjOBJ_BODY, roles["base"]),
            left=left,
            right=right,
            left_vel=np.array([_sensor_adr(m, s) for s in roles["wheel_sensors"]["left"]]),
            right_vel=np.array([_sensor_adr(m, s) for s in roles["wheel_sensors"]["right"]]),
            radius=radius,
            track=track,
            arm=np.array([_id(m, A, a) for a in roles["arm_actuators"]]),
            arm_qpos=np.array(
                [m.jnt_qposadr[_id(m, mujoco.mjtObj.mjOBJ_JOINT, j)] for j in roles["arm_joints"]]
            ),
            accel=_sensor_adr(m, imu["accelerometer"]),
            gyro=_sensor_adr(m, imu["gyro"]),
            orientation=_sensor_adr(m, imu["orientation"]),
            wheel_ctrl=(lo, hi),
            wheel_qpos=np.array(
                [
                    m.jnt_qposadr[_id(m, mujoco.mjtObj.mjOBJ_JOINT, j)]
                    for j in [*roles["wheels"]["left"], *roles["wheels"]["right"]]
                ]
            ),
            roles=roles,
        )
    return out
