"""Load a built facility: the compiled scene and its manifest, with the robot's
roles resolved to MuJoCo ids (joints, actuators, sensors, cameras, sites).

Only the bundle is read (``urdf2mjcf.bundle``: its files and the manifest's schema
version), never a facility root or a recipe of a checkout."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .. import bundle, bundle_manifest, mjcf_input
from ..bundle import MANIFEST
from ..errors import LoadError
from ..limits import TIMESTEP_RANGE
from ..untrusted import excerpt


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


def read_manifest(path: Path) -> dict:
    """A facility.json of this schema version, checked (``urdf2mjcf.bundle.read_manifest``),
    as its JSON; LoadError otherwise."""
    return bundle.read_manifest(path, error=LoadError).to_json()


def bundled_file(folder: Path, manifest: dict, key: str) -> Path | None:
    """The bundle's copy ``key`` (``"demo"``, ``"recipe"``) that facility.json names, or
    None when the bundle has none; a LoadError naming facility.json otherwise."""
    typed = bundle_manifest.parse_manifest(manifest, folder / MANIFEST, error=LoadError)
    return bundle.bundled_file(folder, typed, key, folder / MANIFEST, error=LoadError)


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
) -> tuple[Path, Path, dict, mujoco.MjModel, mujoco.MjData]:
    """``(folder, manifest path, manifest, model, data)`` of a built facility, at its
    ``keyframe`` (when the model has it) after ``mj_forward``."""
    scene, manifest_path = facility_files(path)
    manifest = read_manifest(manifest_path)
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
    manifest: dict
    robot: Robot

    def component_bodies(self, name: str) -> set[int]:
        """Ids of the bodies of a component of the manifest (by its prefix; a free body's
        prefix is its body's name)."""
        comp = self.manifest["components"].get(name)
        if comp is None:
            return set()
        prefix = comp.get("prefix", "")
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
        folded = self.manifest.get("folded_geoms") or {}
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


ROBOT_ROLES = "components.robot.roles"
MOTION_LIMITS = "components.robot.motion_limits"
MOTION_KEYS = ("acceleration", "deceleration", "jerk")


def _motion_limits(manifest: dict, path: Path, names: list[str]) -> list[float | None]:
    """Per role joint, the lower of its acceleration and deceleration limits in
    facility.json (None where none is stated; empty when the robot lists none); a
    LoadError naming the key of a value that is not a positive number."""
    section = manifest["components"]["robot"].get("motion_limits")
    if section is None:
        return []
    if not isinstance(section, dict):
        raise LoadError("not a mapping of joints", file=path, element=MOTION_LIMITS)
    for joint, limits in section.items():
        where = f"{MOTION_LIMITS}.{excerpt(str(joint), 60)}"
        if not isinstance(limits, dict) or set(limits) - set(MOTION_KEYS) or not limits:
            raise LoadError(f"a mapping of {', '.join(MOTION_KEYS)}", file=path, element=where)
        for key, value in limits.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                ok = False
            else:
                ok = 0 < value < float("inf")
            if not ok:
                message = f"'{excerpt(str(value), 40)}' is not a positive number"
                raise LoadError(message, file=path, element=f"{where}.{key}")
    out: list[float | None] = []
    for name in names:
        limits = section.get(name) or {}
        given = [float(limits[k]) for k in ("acceleration", "deceleration") if k in limits]
        out.append(min(given) if given else None)
    return out


_KINDS: dict[Any, str] = {list: "non-empty list", dict: "mapping", str: "name"}


class _Roles:
    """The robot's roles from facility.json, each field checked as it is read."""

    def __init__(self, m: mujoco.MjModel, manifest: dict, path: Path):
        robot = manifest["components"].get("robot")
        roles = robot.get("roles") if isinstance(robot, dict) else None
        if not isinstance(roles, dict) or not roles:
            raise LoadError(
                "the facility has no robot (built with robot=none?); the demo needs one",
                file=path,
                element=ROBOT_ROLES,
            )
        self.m, self.roles, self.path = m, roles, path

    def value(self, key: str, kind: type | tuple[type, ...], where: str | None = None) -> Any:
        section: Any = self.roles
        if where is not None:
            section = self.roles.get(where)
            if not isinstance(section, dict):
                raise LoadError("missing or not a mapping", file=self.path, element=self._at(where))
        value = section.get(key)
        if not isinstance(value, kind) or (kind is list and not value):
            name = f"{where}.{key}" if where else key
            raise LoadError(
                f"missing or not a {_KINDS.get(kind, 'number')}",
                file=self.path,
                element=self._at(name),
            )
        return value

    def ids(self, kind: mujoco.mjtObj, names: Any, at: str) -> np.ndarray:
        return np.array([self.id(kind, n, at) for n in names], dtype=int)

    def id(self, kind: mujoco.mjtObj, name: Any, at: str) -> int:
        return lookup(self.m, kind, name, file=self.path, element=self._at(at))

    def _at(self, name: str) -> str:
        return f"{ROBOT_ROLES}.{name}"


def load(folder: str | Path, *, keyframe: str | None = "home") -> Facility:
    """Load a built facility (its folder or scene.xml) and resolve the robot's roles."""
    folder, manifest_path, manifest, m, d = open_facility(folder, keyframe=keyframe)
    r = _Roles(m, manifest, manifest_path)
    J = mujoco.mjtObj
    names = r.value("joints", list)
    joints = r.ids(J.mjOBJ_JOINT, names, "joints")
    acts = r.ids(J.mjOBJ_ACTUATOR, r.value("actuators", list), "actuators")
    if len(acts) != len(joints):
        raise LoadError(
            "needs one actuator per joint", file=manifest_path, element=r._at("actuators")
        )
    for j, a in zip(joints, acts, strict=True):
        if m.actuator_trnid[a, 0] != j:
            raise LoadError(
                f"actuator '{m.actuator(a).name}' does not drive joint '{m.joint(j).name}'",
                file=manifest_path,
                element=r._at("actuators"),
            )
    sites = {k: r.id(J.mjOBJ_SITE, v, "sites") for k, v in r.value("sites", dict).items()}
    cams = {k: r.id(J.mjOBJ_CAMERA, v, "cameras") for k, v in r.value("cameras", dict).items()}
    grip_open = r.value("open", (int, float), "gripper")
    grip_closed = r.value("closed", (int, float), "gripper")
    root = int(m.body_rootid[m.jnt_bodyid[joints[0]]])
    arm_names = r.value("arm_joints", list) if "arm_joints" in r.roles else []
    unknown = [a for a in arm_names if a not in names]
    if unknown:
        raise LoadError(
            f"'{unknown[0]}' is not one of the robot's joints",
            file=manifest_path,
            element=r._at("arm_joints"),
        )
    vmax = None
    if "vmax" in r.roles:
        values = r.value("vmax", list)
        ok = all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < float("inf")
            for v in values
        )
        if len(values) != len(names) or not ok:
            raise LoadError(
                f"needs {len(names)} positive speeds, one per joint",
                file=manifest_path,
                element=r._at("vmax"),
            )
        vmax = np.array(values, float)
    amax = _motion_limits(manifest, manifest_path, list(names))
    robot = Robot(
        joint_names=list(names),
        joints=joints,
        qpos=m.jnt_qposadr[joints].copy(),
        dofs=m.jnt_dofadr[joints].copy(),
        actuators=acts,
        lower=m.jnt_range[joints, 0].copy(),
        upper=m.jnt_range[joints, 1].copy(),
        gripper_actuator=r.id(
            J.mjOBJ_ACTUATOR, r.value("actuator", str, "gripper"), "gripper.actuator"
        ),
        gripper_joints=r.ids(J.mjOBJ_JOINT, r.value("joints", list, "gripper"), "gripper.joints"),
        gripper_open=float(grip_open),
        gripper_closed=float(grip_closed),
        sites=sites,
        cameras=cams,
        bodies=_subtree(m, root),
        arm=np.array([list(names).index(a) for a in arm_names], int),
        vmax=vmax,
        amax=amax,
    )
    return Facility(folder, m, d, manifest, robot)
