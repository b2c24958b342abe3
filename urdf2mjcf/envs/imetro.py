"""``IMetro-v0``: the iMETRO facility with its robot on the rail.

Observations: the robot's joint positions and velocities (its roles ``joints``,
then the gripper's joints), the wrist force-torque sensor (force, then torque,
in the sensor frame), optionally the wrist camera's RGB and depth. Actions:
position targets of the robot's actuators (roles ``actuators``, then the
gripper's), within their control ranges. Reset: the home keyframe, the CTB and
the mockups at poses drawn from the recipe's seeded jitter.

The default task: reach the CTB's handle. Reward = minus the distance (m) from the
robot's grasp site to the centre of the bag's red strap; never terminated (the
time limit truncates).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..bundle_manifest import Manifest
from ..runner.load import LoadError, Robot, load, lookup, robot_roles
from ..runner.perception import red_mask
from .base import FacilityEnv, Obs
from .poses import root_bodies

RECIPE = "imetro"


def handle_point(m: mujoco.MjModel, body: int) -> np.ndarray | None:
    """In the body's frame: the centre of its red geoms (the CTB's handle strap, red as
    the perception step sees it); None when it has none."""
    geoms = np.array([g for g in range(m.ngeom) if m.geom_bodyid[g] == body], dtype=int)
    if not len(geoms):
        return None
    mat = m.geom_matid[geoms]
    rgba = np.where((mat >= 0)[:, None], m.mat_rgba[np.maximum(mat, 0)], m.geom_rgba[geoms])
    red = red_mask((rgba[None, :, :3] * 255).astype(np.uint8))[0]
    return np.asarray(m.geom_pos[geoms[red]].mean(axis=0)) if red.any() else None


class IMetroEnv(FacilityEnv):
    """The iMETRO facility (``recipes/imetro.yaml`` unless ``recipe`` names another)."""

    default_camera = "wrist"

    def __init__(self, recipe: str | Path = RECIPE, **kwargs: Any):
        super().__init__(recipe, **kwargs)

    def _open(self, folder: Path) -> tuple[mujoco.MjModel, mujoco.MjData, Manifest, Path]:
        fac = load(folder)
        self.robot: Robot = fac.robot
        m = fac.model
        path = fac.folder / "facility.json"
        ft = robot_roles(fac.manifest, path).force_torque or {}
        S = mujoco.mjtObj.mjOBJ_SENSOR
        where = "components.robot.roles.force_torque"
        self._ft = np.concatenate(
            [
                m.sensor_adr[i] + np.arange(m.sensor_dim[i])
                for i in (
                    lookup(m, S, ft.get("force", ""), file=path, element=f"{where}.force"),
                    lookup(m, S, ft.get("torque", ""), file=path, element=f"{where}.torque"),
                )
            ]
        )
        r = self.robot
        joints = np.r_[r.joints, r.gripper_joints]
        self._qpos = m.jnt_qposadr[joints]
        self._qvel = m.jnt_dofadr[joints]
        self._grasp = r.sites.get("grasp", r.sites.get("tool", -1))
        if self._grasp < 0:
            raise LoadError("needs a grasp (or tool) site", file=path, element="roles.sites")
        # the task's bag: the first free component (by name) with a red handle
        comps = fac.manifest.components
        self._target_body, self._target_local = -1, np.zeros(3)
        for name in sorted(n for n, c in comps.items() if c.free):
            for b in root_bodies(m, fac.manifest, name):
                point = handle_point(m, b)
                if point is not None and self._target_body < 0:
                    self._target_body, self._target_local = b, point
        return m, fac.data, fac.manifest, path

    def actuators(self) -> np.ndarray:
        return np.r_[self.robot.actuators, self.robot.gripper_actuator].astype(int)

    def vector_sizes(self) -> dict[str, int]:
        n = len(self._qpos)
        return {"qpos": n, "qvel": n, "force_torque": len(self._ft)}

    def vectors(self) -> Obs:
        d = self.data
        return {
            "qpos": d.qpos[self._qpos].copy(),
            "qvel": d.qvel[self._qvel].copy(),
            "force_torque": np.concatenate(
                self.noise.wrench(*d.sensordata[self._ft].reshape(2, 3))
            ),
        }

    def cameras(self) -> Mapping[str, str]:
        return {k: self.model.cam(i).name for k, i in self.robot.cameras.items()}

    def handle(self) -> np.ndarray:
        """The handle's centre in the world (m); the grasp site's when there is no bag."""
        d = self.data
        if self._target_body < 0:
            return d.site_xpos[self._grasp].copy()
        b = self._target_body
        return np.asarray(d.xpos[b] + d.xmat[b].reshape(3, 3) @ self._target_local)

    def task_step(self) -> tuple[float, bool, dict[str, Any]]:
        distance = float(np.linalg.norm(self.data.site_xpos[self._grasp] - self.handle()))
        return -distance, False, {"distance": distance}

    def free_camera(self, cam: mujoco.MjvCamera) -> None:
        # the whole facility from above, the robot and the bag in front of the mockups
        mujoco.mjv_defaultFreeCamera(self.model, cam)
        cam.lookat[:] = self.model.stat.center
        cam.distance = 1.5 * float(self.model.stat.extent)
        cam.azimuth, cam.elevation = 30.0, -45.0
