"""Load a built facility: the compiled scene and its manifest, with the robot's
roles resolved to MuJoCo ids (joints, actuators, sensors, cameras, sites).

Only the bundle is read (``urdf2mjcf.bundle.open_bundle``: its files and its
manifest, read and checked once into the typed ``urdf2mjcf.bundle_manifest.Manifest``),
never a facility root or a recipe of a checkout."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .. import bundle, mjcf_input
from ..bundle import MANIFEST
from ..bundle_manifest import ArmRoles, Manifest
from ..demos import DEMO_ROBOT
from ..errors import BadManifest, LoadError
from ..limits import TIMESTEP_RANGE


def lookup(
    m: mujoco.MjModel,
    kind: mujoco.mjtObj,
    name: str,
    *,
    file: Path | str | None = None,
    element: str | None = None,
) -> int:
    """The id of a named object; LoadError naming what is missing (and where it was named)."""
    i = mujoco.mj_name2id(m, kind, name) if isinstance(name, str) else -1
    if i < 0:
        what = kind.name[6:].lower()
        raise LoadError(f"the facility has no {what} named '{name}'", file=file, element=element)
    return i


def facility_files(path: str | Path) -> tuple[Path, Path]:
    """``(scene.xml, facility.json)`` of a built facility given as its folder or a scene
    file; a LoadError naming the path when it is not one."""
    return bundle.facility_files(path, error=LoadError)


def read_manifest(path: Path) -> Manifest:
    """A facility.json of this schema version, read and checked once
    (``urdf2mjcf.bundle.read_manifest``); LoadError naming the key otherwise."""
    return bundle.read_manifest(path, error=LoadError)


def bundled_file(folder: Path, manifest: Manifest, key: str) -> Path | None:
    """The bundle's copy ``key`` (``"demo"``, ``"recipe"``) that facility.json names, or
    None when the bundle has none; a LoadError naming facility.json otherwise."""
    return bundle.bundled_file(folder, manifest, key, folder / MANIFEST, error=LoadError)


def compile_scene(scene: Path) -> mujoco.MjModel:
    """The compiled scene, loaded as a stranger's MJCF (:mod:`urdf2mjcf.mjcf_input`);
    a LoadError naming the file and element when it is refused or MuJoCo cannot load
    it, or when its timestep is outside the range a recipe may set (the runtime steps
    by it: a tiny one would run without end)."""
    m = mjcf_input.load_model(scene, error=LoadError, what="scene")
    low, high = TIMESTEP_RANGE
    if not low <= m.opt.timestep <= high:
        raise LoadError(
            f"timestep {m.opt.timestep:g} s is outside [{low:g}, {high:g}] s, the range "
            "a facility may simulate at",
            file=scene,
            element="<option timestep>",
        )
    return m


def open_facility(
    path: str | Path, *, keyframe: str | None = "home"
) -> tuple[Path, Path, Manifest, mujoco.MjModel, mujoco.MjData]:
    """``(folder, manifest path, manifest, model, data)`` of a built facility (its
    manifest read and checked once, ``urdf2mjcf.bundle.open_bundle``), at its
    ``keyframe`` (when the model has it) after ``mj_forward``."""
    opened = bundle.open_bundle(path, error=LoadError)
    scene, manifest_path, manifest = opened.scene, opened.manifest_path, opened.manifest
    m = compile_scene(scene)
    d = mujoco.MjData(m)
    if keyframe is not None and mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, keyframe) >= 0:
        mujoco.mj_resetDataKeyframe(m, d, m.key(keyframe).id)
    mujoco.mj_forward(m, d)
    return scene.parent, manifest_path, manifest, m, d


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
    arm: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    """Indices into ``joints`` of the arm's joints (roles ``arm_joints``), in their order."""
    vmax: np.ndarray | None = None
    """Speed limit of each joint (rad/s or m/s; roles ``vmax``), None where not given."""
    amax: list[float | None] = field(default_factory=list)
    """Acceleration limit of each joint that its description states (URDF 1.2: the lower
    of ``acceleration`` and ``deceleration``, rad/s^2 or m/s^2; facility.json's
    ``components.robot.motion_limits``), None where it states none; empty: none at all.
    MuJoCo does not enforce it: the planners do."""


@dataclass
class Facility:
    folder: Path
    model: mujoco.MjModel
    data: mujoco.MjData
    manifest: Manifest
    robot: Robot

    def component_bodies(self, name: str) -> set[int]:
        """Ids of the bodies of a component of the manifest (by its prefix; a free body's
        prefix is its body's name)."""
        comp = self.manifest.components.get(name)
        if comp is None:
            return set()
        prefix = comp.prefix or ""
        m = self.model
        return {b for b in range(1, m.nbody) if prefix and m.body(b).name.startswith(prefix)}

    def body(self, name: str) -> int:
        return lookup(self.model, mujoco.mjtObj.mjOBJ_BODY, name)

    def link_of_geom(self, geom: int) -> str:
        """The link (body name) a geom was described on: its body's, or for a static
        fixture the build folded into its weld body, the one ``facility.json`` lists
        under ``folded_geoms`` ("world" for the world body)."""
        return self._geom_links[geom]

    @cached_property
    def _geom_links(self) -> list[str]:
        m = self.model
        folded = self.manifest.folded_geoms or {}
        return [
            str(folded.get(m.geom(g).name) or m.body(int(m.geom_bodyid[g])).name or "world")
            for g in range(m.ngeom)
        ]

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


ROBOT_ROLES = f"components.{DEMO_ROBOT}.roles"
"""Where facility.json lists the roles of the robot the demo drives."""


def _motion_limits(manifest: Manifest, names: list[str]) -> list[float | None]:
    """Per role joint, the lower of its acceleration and deceleration limits in
    facility.json (None where none is stated; empty when the robot lists none; the
    values were checked as the manifest was read)."""
    section = manifest.components[DEMO_ROBOT].motion_limits
    if section is None:
        return []
    out: list[float | None] = []
    for name in names:
        limits = section.get(name) or {}
        given = [float(limits[k]) for k in ("acceleration", "deceleration") if k in limits]
        out.append(min(given) if given else None)
    return out


def robot_roles(manifest: Manifest, path: Path) -> ArmRoles:
    """The demo's robot's arm roles (checked as the manifest was read); a LoadError
    naming facility.json and the key when the facility has no robot or its roles are
    not an arm's."""
    comp = manifest.components.get(DEMO_ROBOT)
    if comp is None or not comp.roles:
        raise LoadError(
            "the facility has no robot (built with robot=none?); the demo needs one",
            file=path,
            element=ROBOT_ROLES,
        )
    if comp.arm is not None:
        return comp.arm
    try:
        return ArmRoles.parse(comp.roles, ROBOT_ROLES)
    except BadManifest as exc:
        raise LoadError(exc.message, file=path, element=exc.key) from None


def load(folder: str | Path, *, keyframe: str | None = "home") -> Facility:
    """Load a built facility (its folder or scene.xml) and resolve the robot's roles."""
    folder, manifest_path, manifest, m, d = open_facility(folder, keyframe=keyframe)
    roles = robot_roles(manifest, manifest_path)
    J = mujoco.mjtObj

    def ids(kind: mujoco.mjtObj, names: Any, at: str) -> np.ndarray:
        return np.array([one(kind, n, at) for n in names], dtype=int)

    def one(kind: mujoco.mjtObj, name: Any, at: str) -> int:
        return lookup(m, kind, name, file=manifest_path, element=f"{ROBOT_ROLES}.{at}")

    names = list(roles.joints)
    joints = ids(J.mjOBJ_JOINT, names, "joints")
    acts = ids(J.mjOBJ_ACTUATOR, roles.actuators, "actuators")
    for j, a in zip(joints, acts, strict=True):
        if m.actuator_trnid[a, 0] != j:
            raise LoadError(
                f"actuator '{m.actuator(a).name}' does not drive joint '{m.joint(j).name}'",
                file=manifest_path,
                element=f"{ROBOT_ROLES}.actuators",
            )
    sites = {k: one(J.mjOBJ_SITE, v, "sites") for k, v in roles.sites.items()}
    cams = {k: one(J.mjOBJ_CAMERA, v, "cameras") for k, v in roles.cameras.items()}
    root = int(m.body_rootid[m.jnt_bodyid[joints[0]]])
    grip = roles.gripper
    robot = Robot(
        joint_names=names,
        joints=joints,
        qpos=m.jnt_qposadr[joints].copy(),
        dofs=m.jnt_dofadr[joints].copy(),
        actuators=acts,
        lower=m.jnt_range[joints, 0].copy(),
        upper=m.jnt_range[joints, 1].copy(),
        gripper_actuator=one(J.mjOBJ_ACTUATOR, grip.actuator, "gripper.actuator"),
        gripper_joints=ids(J.mjOBJ_JOINT, grip.joints, "gripper.joints"),
        gripper_open=float(grip.open),
        gripper_closed=float(grip.closed),
        sites=sites,
        cameras=cams,
        bodies=_subtree(m, root),
        arm=np.array([names.index(a) for a in roles.arm_joints], int),
        vmax=np.array(roles.vmax, float) if roles.vmax is not None else None,
        amax=_motion_limits(manifest, names),
    )
    return Facility(folder, m, d, manifest, robot)
