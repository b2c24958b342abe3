"""``facility.json``: what a built facility contains, with stable names.

Read back from the compiled model itself (MuJoCo's names are the truth a
runner will use), plus the recipe, the seed and the poses it produced. No
timestamps or absolute paths: two builds with the same seed are identical.
``"generator": "make-facility"`` and ``"files"`` (every file the build wrote)
mark the folder as ours: a rebuild replaces exactly those files.
``"schema_version"`` (``urdf2mjcf.bundle``) is the bundle format the runtime reads.
The manifest is made as the runtime reads it, a :class:`~urdf2mjcf.bundle_manifest.Manifest`,
and written from it (:meth:`~urdf2mjcf.bundle_manifest.Manifest.dumps`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

from .. import output
from ..bundle import MANIFEST, SCHEMA_VERSION
from ..bundle_manifest import (
    BundleFiles,
    Camera,
    Component,
    Counts,
    Manifest,
    Pose,
    Roles,
    Simulation,
    freeze,
)
from ..errors import BadManifest, InputError
from .recipe import Pose2D, Recipe
from .values import number

if TYPE_CHECKING:
    import mujoco

GENERATOR = "make-facility"

_JOINT_TYPES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}


def _pose(p: Pose2D) -> Pose:
    return Pose((p.xyz[0], p.xyz[1], p.xyz[2]), p.yaw)


def _name(m: mujoco.MjModel, objtype: int, i: int) -> str:
    import mujoco

    return mujoco.mj_id2name(m, objtype, i) or ""


def _prefixed(value: Any, prefix: str) -> Any:
    """Role values with the component's prefix: names in lists and mappings, numbers as they are."""
    if isinstance(value, str):
        return prefix + value
    if isinstance(value, list):
        return [_prefixed(v, prefix) for v in value]
    if isinstance(value, dict):
        return {k: _prefixed(v, prefix) for k, v in value.items()}
    return value


def _check_names(m: mujoco.MjModel, value: Any, where: str) -> None:
    """Every name a role gives must exist in the compiled model (as some kind of object)."""
    import mujoco

    if isinstance(value, str):
        kinds = (
            mujoco.mjtObj.mjOBJ_JOINT,
            mujoco.mjtObj.mjOBJ_ACTUATOR,
            mujoco.mjtObj.mjOBJ_SENSOR,
            mujoco.mjtObj.mjOBJ_CAMERA,
            mujoco.mjtObj.mjOBJ_SITE,
            mujoco.mjtObj.mjOBJ_BODY,
        )
        if not any(mujoco.mj_name2id(m, k, value) >= 0 for k in kinds):
            raise InputError(
                f"role names '{value}', which the facility does not contain", file=where
            )
    elif isinstance(value, list):
        for v in value:
            _check_names(m, v, where)
    elif isinstance(value, dict):
        for v in value.values():
            _check_names(m, v, where)


def _components(
    m: mujoco.MjModel, placements: dict[str, Pose2D], roles: dict[str, dict]
) -> dict[str, Component]:
    out = {}
    joint_names = [_name(m, 3, j) for j in range(m.njnt)]  # mjOBJ_JOINT
    for name in sorted(set(placements) | set(roles)):
        pose = _pose(placements[name]) if name in placements else None
        spec = roles.get(name)
        if spec is None:
            out[name] = Component(name, pose)
            continue
        prefix = spec["prefix"]
        named = None
        if spec.get("roles"):
            named = _prefixed(spec["roles"], prefix)
            _check_names(m, named, f"roles of '{name}'")
        try:
            out[name] = Component(
                name,
                pose,
                prefix=prefix,
                free=bool(spec.get("free")),
                joints=tuple(j for j in joint_names if j.startswith(prefix)) if prefix else None,
                roles=Roles.of(named) if named is not None else None,
                # URDF 1.2's, for planners: MuJoCo ignores them
                motion_limits=freeze(spec["motion_limits"]) if spec.get("motion_limits") else None,
            )
        except BadManifest as exc:  # roles a runner could not read: refused here already
            raise InputError(exc.message, file=f"roles of '{name}'", element=exc.key) from None
    return out


MECHANISM_KEYS = ("holds", "lock", "locked", "released")
JOINT_MAX = 10_000.0
"""Magnitude of a mechanism's locked and released joint values (rad or m)."""
_OPTIONS = {  # recipe simulation key -> (MjOption field, MuJoCo enum or None)
    "timestep": ("timestep", None),
    "impratio": ("impratio", None),
    "iterations": ("iterations", None),
    "integrator": ("integrator", "mjtIntegrator"),
    "solver": ("solver", "mjtSolver"),
    "cone": ("cone", "mjtCone"),
}


def check_simulation(m: mujoco.MjModel, recipe: Recipe) -> None:
    """Every ``simulation:`` option of the recipe is the compiled model's: a world
    xacro that does not pass one to ``<option>`` would otherwise ignore it silently.
    An InputError naming the recipe and the option when it differs."""
    import mujoco

    for key, value in recipe.simulation.items():
        field, enum = _OPTIONS[key]
        actual = getattr(m.opt, field)
        if enum is None:
            same = float(actual) == float(value)
            shown = f"{float(actual):g}"
        else:
            name = getattr(mujoco, enum)(int(actual)).name.split("_", 1)[1]
            same = name.lower() == str(value).lower()
            shown = name.lower()
        if not same:
            raise InputError(
                f"the world's xacro ({recipe.xacro}) does not set option '{key}' from the "
                f"recipe: the built model has {shown}, the recipe asks for {value}",
                file=recipe.path or "recipe",
                element=f"simulation.{key}",
            )


def _mechanisms(
    m: mujoco.MjModel, recipe: Recipe, root: Path, present: list[str]
) -> list[dict]:
    """The mechanisms of every component present, from the file its table entry names
    (``mechanisms``: ``NAME: {holds, lock, locked, released}``, joint names without the
    prefix): names prefixed, each joint checked against the compiled model. Errors name
    the file, the key and its line."""
    import mujoco

    from ..schema import load
    from .root import data_path

    out = []
    for name in present:
        comp = recipe.components.get(name)
        if comp is None or not comp.mechanisms:
            continue
        data, src = load(data_path(root, recipe.path, comp.mechanisms), "mechanisms file")
        for mech, spec in src.mapping(data, "mechanisms", "a mapping of mechanism names").items():
            spec = src.mapping(spec, mech, "{holds, lock, locked, released}")
            src.known(spec, MECHANISM_KEYS, mech)
            entry: dict[str, Any] = {"name": comp.prefix + mech, "component": name}
            for key in MECHANISM_KEYS:
                if key not in spec:
                    raise src.fail(f"{mech}.{key}", "is required")
                if key in ("holds", "lock"):
                    joint = comp.prefix + str(src.text(spec[key], f"{mech}.{key}", required=True))
                    if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, joint) < 0:
                        message = f"no joint '{joint}' in the facility (component '{name}')"
                        raise src.fail(f"{mech}.{key}", message)
                    entry[key] = joint
                else:  # a joint value, rad or m
                    entry[key] = number(
                        spec[key], src, f"{mech}.{key}", low=-JOINT_MAX, high=JOINT_MAX
                    )
            out.append(entry)
    return out


def manifest(
    scene: Path,
    recipe: Recipe,
    root: Path,
    seed: int | None,
    placements: dict[str, Pose2D],
    offsets: dict[str, dict[str, float]],
    components: dict[str, Path],
    roles: dict[str, dict] | None = None,
    compiled: Any = None,
    fiducials: list[dict] | None = None,
    bundled: dict[str, str | None] | None = None,
) -> Manifest:
    """``compiled``: the model of ``scene`` the conversion validated, so it is not
    compiled again (None: compiled here); ``fiducials``: the tags the build added
    (``urdf2mjcf.facility.fiducials.manifest_entries``); ``bundled``: the copies the
    bundle holds, ``{"recipe": name, "demo": name or None}`` (names in the bundle)."""
    import mujoco

    m = compiled if compiled is not None else mujoco.MjModel.from_xml_path(str(scene))
    check_simulation(m, recipe)
    obj = mujoco.mjtObj
    joints = [
        {
            "name": _name(m, obj.mjOBJ_JOINT, j),
            "type": _JOINT_TYPES[int(m.jnt_type[j])],
            "body": _name(m, obj.mjOBJ_BODY, int(m.jnt_bodyid[j])),
            "range": [float(v) for v in m.jnt_range[j]] if m.jnt_limited[j] else None,
        }
        for j in range(m.njnt)
    ]
    actuators = []
    for a in range(m.nu):
        kind = (
            "position"
            if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
            and m.actuator_biasprm[a, 1] != 0
            else ("velocity" if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE else "motor")
        )
        actuators.append(
            {
                "name": _name(m, obj.mjOBJ_ACTUATOR, a),
                "joint": _name(m, obj.mjOBJ_JOINT, int(m.actuator_trnid[a, 0])),
                "type": kind,
                "ctrlrange": [float(v) for v in m.actuator_ctrlrange[a]]
                if m.actuator_ctrllimited[a]
                else None,
            }
        )
    sensors = [
        {
            "name": _name(m, obj.mjOBJ_SENSOR, s),
            "type": mujoco.mjtSensor(int(m.sensor_type[s])).name[len("mjSENS_") :].lower(),
            "dim": int(m.sensor_dim[s]),
        }
        for s in range(m.nsensor)
    ]
    cameras = tuple(
        Camera(
            name=_name(m, obj.mjOBJ_CAMERA, c),
            body=_name(m, obj.mjOBJ_BODY, int(m.cam_bodyid[c])),
            resolution=(int(m.cam_resolution[c][0]), int(m.cam_resolution[c][1])),
            fovy=float(m.cam_fovy[c]),
        )
        for c in range(m.ncam)
    )
    recipe_file = None
    if recipe.path is not None:
        try:
            recipe_file = str(Path(recipe.path).resolve().relative_to(root))
        except ValueError:
            recipe_file = Path(recipe.path).name
    return Manifest(
        schema_version=SCHEMA_VERSION,
        generator=GENERATOR,
        recipe=recipe.name,
        recipe_file=recipe_file,
        bundle=BundleFiles(present=tuple(bundled or {}), **(bundled or {})),
        xacro=recipe.xacro,
        seed=seed,
        flags=freeze(dict(recipe.flags)),
        jitter=freeze(
            {k: dict(v) if v is not None else False for k, v in recipe.jitter.items()}
            if seed is not None
            else {}
        ),
        offsets=freeze(offsets),
        components=MappingProxyType(_components(m, placements, roles or {})),
        component_mjcf=MappingProxyType({k: str(v) for k, v in sorted(components.items())}),
        simulation=Simulation(
            timestep=float(m.opt.timestep),
            integrator=mujoco.mjtIntegrator(int(m.opt.integrator)).name[len("mjINT_") :].lower(),
        ),
        counts=Counts(
            bodies=int(m.nbody),
            joints=int(m.njnt),
            dofs=int(m.nv),
            actuators=int(m.nu),
            sensors=int(m.nsensor),
            cameras=int(m.ncam),
        ),
        joints=freeze(joints),
        actuators=freeze(actuators),
        sensors=freeze(sensors),
        cameras=cameras,
        fiducials=freeze(fiducials or []),
        noise=freeze(dict(recipe.noise)),
        mechanisms=freeze(_mechanisms(m, recipe, root, list(placements))),
    )


def write_manifest(folder: Path, data: Manifest) -> Manifest:
    """``folder/facility.json``, listing every file in ``folder`` (the build's output),
    written from ``data`` (:meth:`Manifest.dumps`); the manifest as written."""
    data = replace(data, generator=GENERATOR, files=tuple(output.list_files(folder)))
    (folder / MANIFEST).write_text(data.dumps())
    return data
