"""``Mira3D-v0``: the MIRA3D rover with its arm, on the flat institute floor.

Observations: the arm's joint positions; the wheels' and the arm's joint
velocities (left wheels, right wheels, then the arm); the IMU (accelerometer
m/s^2, gyro rad/s, orientation quaternion w x y z). Actions: wheel velocity
targets (rad/s, left then right, as the roles list them) and arm position
targets (rad), within their control ranges. Reset: the home keyframe, the rover
at a start pose drawn from the seeded jitter: by default anywhere within
+-0.5 m of its placement, facing any direction (``jitter`` replaces it).

The default task: drive forward. Reward = the base's displacement (m) along its
heading during the step; terminated when the rover tips over (its up axis more
than 60 degrees from the vertical).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..bundle_manifest import Manifest
from ..runner.load import open_facility
from ..runner.rover.roles import Rover, RoverError, find_rovers
from .base import FacilityEnv, Obs, tilt

RECIPE = "mira3d-floor"
START_JITTER = {"position": 0.5, "yaw": math.pi}
"""The driven rover's start pose ranges (m, rad) unless ``jitter`` is given."""
TIP_OVER = math.radians(60.0)


class Mira3DEnv(FacilityEnv):
    """A MIRA3D world (``recipes/mira3d-floor.yaml`` unless ``recipe`` names another);
    ``rover``: the component driven (default: the first rover by name)."""

    default_camera = "stereo_left"

    def __init__(self, recipe: str | Path = RECIPE, *, rover: str | None = None, **kwargs: Any):
        self._rover_name = rover
        super().__init__(recipe, **kwargs)

    def _open(self, folder: Path) -> tuple[mujoco.MjModel, mujoco.MjData, Manifest, Path]:
        _, path, manifest, m, d = open_facility(folder)
        rovers = find_rovers(m, manifest)
        if not rovers:
            raise RoverError("no rover in this facility", file=path, element="components")
        name = self._rover_name or next(iter(rovers))
        if name not in rovers:
            valid = ", ".join(rovers)
            raise RoverError(f"no rover '{name}'; rovers: {valid}", file=path, element="rover")
        self.rover: Rover = rovers[name]
        r = self.rover
        J = mujoco.mjtObj.mjOBJ_JOINT
        spec = r.spec
        assert spec is not None  # find_rovers gives every rover its roles
        wheels = [*spec.wheels.left, *spec.wheels.right]
        arm = [mujoco.mj_name2id(m, J, j) for j in spec.arm_joints]
        self._arm_qpos = m.jnt_qposadr[arm]
        self._qvel = m.jnt_dofadr[[*(mujoco.mj_name2id(m, J, j) for j in wheels), *arm]]
        self._imu = np.r_[
            r.accel + np.arange(3), r.gyro + np.arange(3), r.orientation + np.arange(4)
        ]
        self._last_xy = np.zeros(2)
        return m, d, manifest, path

    def default_jitter(self) -> Mapping[str, Any]:
        return {self.rover.name: START_JITTER}

    def actuators(self) -> np.ndarray:
        r = self.rover
        return np.r_[r.left, r.right, r.arm].astype(int)

    def vector_sizes(self) -> dict[str, int]:
        return {"qpos": len(self._arm_qpos), "qvel": len(self._qvel), "imu": len(self._imu)}

    def vectors(self) -> Obs:
        d = self.data
        return {
            "qpos": d.qpos[self._arm_qpos].copy(),
            "qvel": d.qvel[self._qvel].copy(),
            "imu": d.sensordata[self._imu].copy(),
        }

    def cameras(self) -> Mapping[str, str]:
        return dict(self.rover.spec.cameras)

    def _heading(self) -> np.ndarray:
        x = self.data.xmat[self.rover.base].reshape(3, 3)[:2, 0]
        n = float(np.linalg.norm(x))
        return x / n if n > 1e-9 else np.zeros(2)

    def task_reset(self) -> None:
        self._last_xy = self.data.xpos[self.rover.base][:2].copy()
        self._last_heading = self._heading()

    def task_step(self) -> tuple[float, bool, dict[str, Any]]:
        d, b = self.data, self.rover.base
        xy = d.xpos[b][:2].copy()
        progress = float((xy - self._last_xy) @ self._last_heading)
        self._last_xy, self._last_heading = xy, self._heading()
        angle = tilt(d.xmat[b])
        return progress, angle > TIP_OVER, {"progress": progress, "tilt": angle}

    def free_camera(self, cam: mujoco.MjvCamera) -> None:
        # follow the rover from behind and above its start heading
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = self.rover.base
        cam.distance, cam.azimuth, cam.elevation = 4.0, 135.0, -25.0
