"""Load a built facility: the compiled scene and its manifest, with the robot's
roles resolved to MuJoCo ids (joints, actuators, sensors, cameras, sites)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np


class LoadError(RuntimeError):
    """The facility lacks something the runner needs (a file, a role, a name)."""


def lookup(m: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    """The id of a named object; LoadError naming what is missing."""
    i = mujoco.mj_name2id(m, kind, name)
    if i < 0:
        raise LoadError(f"the facility has no {kind.name[6:].lower()} named '{name}'")
    return i


@dataclass
class Robot:
    """The robot's roles as MuJoCo ids, in the order of the manifest."""

    joint_names: list[str]
    joints: np.ndarray  # joint ids
    qpos: np.ndarray  # qpos addresses of the joints
    dofs: np.ndarray  # dof addresses of the joints
    actuators: np.ndarray  # actuator ids, one per joint
    lower: np.ndarray
    upper: np.ndarray
    gripper_actuator: int
    gripper_joints: np.ndarray  # joint ids
    gripper_open: float
    gripper_closed: float
    sites: dict[str, int]
    cameras: dict[str, int]
    bodies: set[int] = field(default_factory=set)  # every body of the robot


@dataclass
class Facility:
    folder: Path
    model: mujoco.MjModel
    data: mujoco.MjData
    manifest: dict
    robot: Robot

    def component_bodies(self, name: str) -> set[int]:
        """Ids of the bodies of a component of the manifest (by its prefix)."""
        comp = self.manifest["components"].get(name)
        if comp is None:
            return set()
        prefix = comp.get("prefix", "")
        m = self.model
        if name == "ctb":
            return {b for b in range(1, m.nbody) if m.body(b).name == prefix}
        return {b for b in range(1, m.nbody) if prefix and m.body(b).name.startswith(prefix)}

    def body(self, name: str) -> int:
        return lookup(self.model, mujoco.mjtObj.mjOBJ_BODY, name)

    def joint(self, name: str) -> int:
        return lookup(self.model, mujoco.mjtObj.mjOBJ_JOINT, name)

    def q(self) -> np.ndarray:
        """The robot's joint positions (manifest order)."""
        return self.data.qpos[self.robot.qpos].copy()


def _subtree(m: mujoco.MjModel, root: int) -> set[int]:
    out = {root}
    for b in range(root + 1, m.nbody):
        if m.body_parentid[b] in out:
            out.add(b)
    return out


def load(folder: str | Path, *, keyframe: str | None = "home") -> Facility:
    """Load ``folder/scene.xml`` and ``folder/facility.json`` (or a scene.xml path)."""
    folder = Path(folder)
    if folder.suffix == ".xml":
        folder = folder.parent
    scene, manifest_path = folder / "scene.xml", folder / "facility.json"
    for p in (scene, manifest_path):
        if not p.is_file():
            raise LoadError(f"{p} does not exist (build the facility with make-facility)")
    manifest = json.loads(manifest_path.read_text())
    m = mujoco.MjModel.from_xml_path(str(scene))
    d = mujoco.MjData(m)
    if keyframe is not None and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, keyframe) >= 0:
        mujoco.mj_resetDataKeyframe(m, d, m.key(keyframe).id)
    mujoco.mj_forward(m, d)
    roles = manifest.get("components", {}).get("robot", {}).get("roles")
    if not roles:
        raise LoadError("facility.json lists no robot roles (was it built with robot=none?)")
    J = mujoco.mjtObj
    joints = np.array([lookup(m, J.mjOBJ_JOINT, n) for n in roles["joints"]])
    acts = np.array([lookup(m, J.mjOBJ_ACTUATOR, n) for n in roles["actuators"]])
    for j, a in zip(joints, acts, strict=True):
        if m.actuator_trnid[a, 0] != j:
            raise LoadError(
                f"actuator '{m.actuator(a).name}' does not drive joint '{m.joint(j).name}'"
            )
    grip = roles["gripper"]
    sites = {k: lookup(m, J.mjOBJ_SITE, v) for k, v in roles["sites"].items()}
    cams = {k: lookup(m, J.mjOBJ_CAMERA, v) for k, v in roles["cameras"].items()}
    root = int(m.body_rootid[m.jnt_bodyid[joints[0]]])
    robot = Robot(
        joint_names=list(roles["joints"]),
        joints=joints,
        qpos=m.jnt_qposadr[joints].copy(),
        dofs=m.jnt_dofadr[joints].copy(),
        actuators=acts,
        lower=m.jnt_range[joints, 0].copy(),
        upper=m.jnt_range[joints, 1].copy(),
        gripper_actuator=lookup(m, J.mjOBJ_ACTUATOR, grip["actuator"]),
        gripper_joints=np.array([lookup(m, J.mjOBJ_JOINT, n) for n in grip["joints"]]),
        gripper_open=float(grip["open"]),
        gripper_closed=float(grip["closed"]),
        sites=sites,
        cameras=cams,
        bodies=_subtree(m, root),
    )
    return Facility(folder, m, d, manifest, robot)
