"""``facility.json`` as typed, frozen values: the one reading of a bundle's manifest.

:func:`parse_manifest` checks everything the runtime uses (the schema version, every
component's pose and roles, the cameras, the seed, the offsets, the rocks; types, finite
numbers, names) and raises one error naming ``facility.json`` and the key
(``components.rover.roles.wheel_radius``) on the first thing wrong; the runtime then
reads only the :class:`Manifest` it returns, never the JSON. The builder
(``urdf2mjcf.facility.manifest``) makes the same :class:`Manifest` and writes it with
:meth:`Manifest.to_json`: what it writes and what the runtime reads are one type.

Roles are a component's open-ended names by role (a roles file's, prefixed):
:class:`Roles` keeps all of them, in their order, and two typed views check the ones
the runners use: :class:`ArmRoles` (a manipulator: joints, actuators, gripper, sites,
cameras) for a component whose roles name ``joints`` or a ``gripper``, and
:class:`RoverRoles` (wheels, IMU, arm) for one whose roles name ``wheel_actuators``.
Which component a runner drives is the runner's choice, not the format's.

Sections no runtime reads (the recipe's flags and jitter, the joint, actuator and
sensor tables, the mechanisms, the file list) are kept as frozen JSON values
(:data:`Json`: tuples for arrays, read-only mappings for objects).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from types import MappingProxyType
from typing import Any

from . import untrusted
from .errors import BadManifest as ManifestError  # noqa: N814
from .errors import BundleError, ForgeError
from .limits import NOISE_CHANNELS, NOISE_RANGES, TAG_COUNT

Json = Any
"""A frozen JSON value: str, int, float, bool, None, a tuple or a read-only mapping."""

SCHEMA_VERSION = 1
"""The bundle format (``urdf2mjcf.bundle.SCHEMA_VERSION``)."""
BUNDLE_KEY = "bundle"
"""The manifest's section naming the recipe and demo copies (relative to the bundle)."""
WHEEL_LENGTH_MAX = 100.0
"""m: the largest wheel radius, track or wheelbase a rover's roles may give."""
MOTION_KEYS = ("acceleration", "deceleration", "jerk")
"""The keys of a joint's ``motion_limits`` (URDF 1.2's)."""


def freeze(value: Any) -> Json:
    """A JSON value with its arrays as tuples and its objects as read-only mappings."""
    if isinstance(value, (list, tuple)):
        return tuple(freeze(v) for v in value)
    if isinstance(value, Mapping):
        return MappingProxyType({str(k): freeze(v) for k, v in value.items()})
    return value


def thaw(value: Json) -> Any:
    """The plain JSON value (lists, dicts) of a frozen one, in the same order."""
    if isinstance(value, tuple):
        return [thaw(v) for v in value]
    if isinstance(value, Mapping):
        return {k: thaw(v) for k, v in value.items()}
    return value


# -- checks (each raises ManifestError naming the key) ------------------------------------


def _shown(value: Any, n: int = 40) -> str:
    try:
        text = json.dumps(thaw(value))
    except (TypeError, ValueError):
        text = repr(value)
    return untrusted.excerpt(text, n)


def is_number(value: Any) -> bool:
    """A finite int or float, not a bool."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _number(value: Any, key: str, *, positive: bool = False) -> float:
    if not is_number(value) or (positive and not value > 0):
        kind = "a positive number" if positive else "a finite number"
        raise ManifestError(key, f"{_shown(value)} is not {kind}")
    return value  # type: ignore[no-any-return]  # as written: an int stays an int


def _name(value: Any, key: str, missing: str = "missing or not a name") -> str:
    if not isinstance(value, str) or not value:
        raise ManifestError(key, missing)
    return value


def _names(value: Any, key: str, *, empty: bool = False) -> tuple[str, ...]:
    if not isinstance(value, (list, tuple)) or (not value and not empty):
        raise ManifestError(key, "missing or not a non-empty list")
    for i, v in enumerate(value):
        _name(v, f"{key}[{i}]", f"{_shown(v)} is not a name")
    return tuple(value)


def _mapping(value: Any, key: str, what: str = "missing or not a mapping") -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ManifestError(key, what)
    return value


def _named(value: Any, key: str) -> Mapping[str, str]:
    """A mapping of role -> name."""
    section = _mapping(value, key)
    for k, v in section.items():
        _name(v, f"{key}.{k}", f"{_shown(v)} is not a name")
    return MappingProxyType(dict(section))


def _empty() -> Mapping[str, Any]:
    return MappingProxyType({})


# -- components and roles -----------------------------------------------------------------


@dataclass(frozen=True)
class Pose:
    """A placed component's pose: ``xyz`` (m) and ``yaw`` (rad) about +z."""

    xyz: tuple[float, float, float]
    yaw: float

    def to_json(self) -> dict[str, Any]:
        return {"xyz": list(self.xyz), "yaw": self.yaw}

    @classmethod
    def parse(cls, value: Any, key: str) -> Pose:
        section = _mapping(value, key, "not a mapping of xyz and yaw")
        xyz = section.get("xyz")
        if not isinstance(xyz, (list, tuple)) or len(xyz) != 3:
            raise ManifestError(f"{key}.xyz", "missing or not three numbers")
        nums = tuple(_number(v, f"{key}.xyz[{i}]") for i, v in enumerate(xyz))
        return cls((nums[0], nums[1], nums[2]), _number(section.get("yaw"), f"{key}.yaw"))


@dataclass(frozen=True)
class Roles(Mapping[str, Json]):
    """A component's roles, every one of them in the roles file's order (frozen JSON
    values); ``roles["joints"]`` and ``roles.get("base")`` read one."""

    entries: Mapping[str, Json]

    @classmethod
    def of(cls, value: Mapping[str, Any]) -> Roles:
        return cls(freeze(value))

    def __getitem__(self, key: str) -> Json:
        return self.entries[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.entries)

    def __len__(self) -> int:
        return len(self.entries)

    def to_json(self) -> dict[str, Any]:
        return thaw(self.entries)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class Gripper:
    actuator: str
    joints: tuple[str, ...]
    open: float
    closed: float


@dataclass(frozen=True)
class ArmRoles:
    """A manipulator's roles, checked: what the demo, its planners and the arm
    environment drive. Names as facility.json gives them (prefixed)."""

    joints: tuple[str, ...]
    actuators: tuple[str, ...]
    gripper: Gripper
    sites: Mapping[str, str]
    cameras: Mapping[str, str]
    arm_joints: tuple[str, ...] = ()
    """The arm's joints among ``joints`` (empty: none named)."""
    vmax: tuple[float, ...] | None = None
    """Speed of each joint (rad/s or m/s), None where the roles give none."""
    force_torque: Mapping[str, str] | None = None
    """The wrist's ``{site, force, torque}`` names, None where it has none."""

    @classmethod
    def parse(cls, roles: Mapping[str, Any], key: str) -> ArmRoles:
        """``key``: where the roles are (``components.robot.roles``), for errors."""
        joints = _names(roles.get("joints"), f"{key}.joints")
        actuators = _names(roles.get("actuators"), f"{key}.actuators")
        if len(actuators) != len(joints):
            raise ManifestError(f"{key}.actuators", "needs one actuator per joint")
        sites = _named(roles.get("sites"), f"{key}.sites")
        cameras = _named(roles.get("cameras"), f"{key}.cameras")
        g = _mapping(roles.get("gripper"), f"{key}.gripper")
        grip = f"{key}.gripper"
        gripper = Gripper(
            actuator=_name(g.get("actuator"), f"{grip}.actuator"),
            joints=_names(g.get("joints"), f"{grip}.joints"),
            open=_number_role(g.get("open"), f"{grip}.open"),
            closed=_number_role(g.get("closed"), f"{grip}.closed"),
        )
        arm: tuple[str, ...] = ()
        if "arm_joints" in roles:
            arm = _names(roles.get("arm_joints"), f"{key}.arm_joints")
            unknown = [a for a in arm if a not in joints]
            if unknown:
                raise ManifestError(
                    f"{key}.arm_joints",
                    f"'{untrusted.excerpt(unknown[0], 60)}' is not one of the robot's joints",
                )
        vmax = None
        if "vmax" in roles:
            values = roles.get("vmax")
            ok = isinstance(values, (list, tuple)) and len(values) == len(joints)
            if not ok or not all(is_number(v) and v > 0 for v in values):  # type: ignore[union-attr]
                raise ManifestError(
                    f"{key}.vmax", f"needs {len(joints)} positive speeds, one per joint"
                )
            vmax = tuple(values)  # type: ignore[arg-type]
        ft = None
        if roles.get("force_torque") is not None:
            ft = _named(roles.get("force_torque"), f"{key}.force_torque")
        return cls(joints, actuators, gripper, sites, cameras, arm, vmax, ft)


def _number_role(value: Any, key: str) -> float:
    if not is_number(value):
        raise ManifestError(key, "missing or not a number")
    return value  # type: ignore[no-any-return]


@dataclass(frozen=True)
class Sides:
    """Names of the left and the right side (wheels, their servos, their sensors)."""

    left: tuple[str, ...]
    right: tuple[str, ...]

    @classmethod
    def parse(cls, value: Any, key: str) -> Sides:
        section = _mapping(value, key, "missing or not a mapping of left and right")
        return cls(
            _names(section.get("left"), f"{key}.left"), _names(section.get("right"), f"{key}.right")
        )


@dataclass(frozen=True)
class Imu:
    accelerometer: str
    gyro: str
    orientation: str
    site: str | None = None


@dataclass(frozen=True)
class RoverRoles:
    """A rover's roles, checked: what the rover runners, the console and the rover
    environment drive."""

    base: str
    wheels: Sides
    wheel_actuators: Sides
    wheel_sensors: Sides
    wheel_radius: float
    track: float
    arm_joints: tuple[str, ...]
    arm_actuators: tuple[str, ...]
    imu: Imu
    base_joint: str | None = None
    cameras: Mapping[str, str] = field(default_factory=_empty)
    sites: Mapping[str, str] = field(default_factory=_empty)

    @classmethod
    def parse(cls, roles: Mapping[str, Any], key: str) -> RoverRoles:
        imu = _mapping(roles.get("imu"), f"{key}.imu")
        lengths: dict[str, float] = {}
        for k in ("wheel_radius", "track"):
            x: Any = roles.get(k)
            if not is_number(x) or not 0.0 < x <= WHEEL_LENGTH_MAX:
                raise ManifestError(
                    f"{key}.{k}", f"{_shown(x)} m is not above 0 and at most {WHEEL_LENGTH_MAX:g}"
                )
            lengths[k] = x
        base_joint = roles.get("base_joint")
        return cls(
            base=_name(roles.get("base"), f"{key}.base"),
            wheels=Sides.parse(roles.get("wheels"), f"{key}.wheels"),
            wheel_actuators=Sides.parse(roles.get("wheel_actuators"), f"{key}.wheel_actuators"),
            wheel_sensors=Sides.parse(roles.get("wheel_sensors"), f"{key}.wheel_sensors"),
            wheel_radius=lengths["wheel_radius"],
            track=lengths["track"],
            arm_joints=_names(roles.get("arm_joints"), f"{key}.arm_joints"),
            arm_actuators=_names(roles.get("arm_actuators"), f"{key}.arm_actuators"),
            imu=Imu(
                accelerometer=_name(imu.get("accelerometer"), f"{key}.imu.accelerometer"),
                gyro=_name(imu.get("gyro"), f"{key}.imu.gyro"),
                orientation=_name(imu.get("orientation"), f"{key}.imu.orientation"),
                site=imu.get("site") if isinstance(imu.get("site"), str) else None,
            ),
            base_joint=_name(base_joint, f"{key}.base_joint") if base_joint is not None else None,
            cameras=_named(roles.get("cameras") or {}, f"{key}.cameras"),
            sites=_named(roles.get("sites") or {}, f"{key}.sites"),
        )


def _motion_limits(value: Any, key: str) -> Mapping[str, Mapping[str, float]]:
    section = _mapping(value, key, "not a mapping of joints")
    for joint, limits in section.items():
        where = f"{key}.{untrusted.excerpt(str(joint), 60)}"
        if not isinstance(limits, Mapping) or set(limits) - set(MOTION_KEYS) or not limits:
            raise ManifestError(where, f"a mapping of {', '.join(MOTION_KEYS)}")
        for k, v in limits.items():
            if not is_number(v) or not v > 0:
                raise ManifestError(
                    f"{where}.{k}", f"'{untrusted.excerpt(str(v), 40)}' is not a positive number"
                )
    return freeze(section)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class Component:
    """One component of the facility: its pose where the recipe placed it, the prefix of
    its names, whether it is a free body, its joints, its roles (with the typed view the
    runners use) and the motion limits its description states."""

    name: str
    pose: Pose | None = None
    prefix: str | None = None
    """None where facility.json gives none (a component without a table entry)."""
    free: bool = False
    joints: tuple[str, ...] | None = None
    roles: Roles | None = None
    motion_limits: Mapping[str, Mapping[str, float]] | None = None
    arm: ArmRoles | None = field(default=None, compare=False)
    """The roles as a manipulator's (roles naming ``joints`` or a ``gripper``)."""
    rover: RoverRoles | None = field(default=None, compare=False)
    """The roles as a rover's (roles naming ``wheel_actuators``)."""

    def __post_init__(self) -> None:
        if self.roles is not None and self.arm is None and self.rover is None:
            where = f"components.{self.name}.roles"
            if "wheel_actuators" in self.roles:
                object.__setattr__(self, "rover", RoverRoles.parse(self.roles, where))
            elif "joints" in self.roles or "gripper" in self.roles:
                object.__setattr__(self, "arm", ArmRoles.parse(self.roles, where))

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.pose is not None:
            out["pose"] = self.pose.to_json()
        if self.prefix is not None:
            out["prefix"] = self.prefix
        if self.free:
            out["free"] = True
        if self.joints is not None:
            out["joints"] = list(self.joints)
        if self.roles is not None:
            out["roles"] = self.roles.to_json()
        if self.motion_limits is not None:
            out["motion_limits"] = thaw(self.motion_limits)
        return out

    @classmethod
    def parse(cls, name: str, value: Any) -> Component:
        key = f"components.{name}"
        section = _mapping(value, key, "not a mapping")
        pose = Pose.parse(section["pose"], f"{key}.pose") if "pose" in section else None
        prefix = section.get("prefix")
        if prefix is not None and not isinstance(prefix, str):
            raise ManifestError(f"{key}.prefix", f"{_shown(prefix)} is not a name")
        free = section.get("free", False)
        if not isinstance(free, bool):
            raise ManifestError(f"{key}.free", f"{_shown(free)} is not true or false")
        joints = None
        if "joints" in section:
            joints = _names(section["joints"], f"{key}.joints", empty=True)
        roles = None
        if section.get("roles") is not None:
            roles = Roles.of(_mapping(section["roles"], f"{key}.roles", "not a mapping"))
        limits = None
        if section.get("motion_limits") is not None:
            limits = _motion_limits(section["motion_limits"], f"{key}.motion_limits")
        return cls(name, pose, prefix, free, joints, roles, limits)


# -- the other sections the runtime reads -------------------------------------------------


@dataclass(frozen=True)
class BundleFiles:
    """The copies the bundle holds (names inside it; None: it holds none)."""

    recipe: str | None = None
    demo: str | None = None
    present: tuple[str, ...] = ("recipe", "demo")
    """The keys facility.json gives (a copy missing from it is an error where it is read)."""

    def to_json(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.present}

    @classmethod
    def parse(cls, value: Any) -> BundleFiles:
        if not isinstance(value, Mapping):
            return cls(present=())
        out: dict[str, str | None] = {}
        for k in ("recipe", "demo"):
            if k not in value:
                continue
            rel = value[k]
            if rel is not None:
                pure = PurePosixPath(rel) if isinstance(rel, str) and rel else None
                if pure is None or pure.is_absolute() or ".." in pure.parts or "\\" in rel:
                    raise ManifestError(
                        f"{BUNDLE_KEY}.{k}",
                        f"{_shown(rel, 60)} is not a file name inside the bundle",
                    )
            out[k] = rel
        return cls(present=tuple(out), **out)


@dataclass(frozen=True)
class Simulation:
    timestep: float
    integrator: str

    def to_json(self) -> dict[str, Any]:
        return {"timestep": self.timestep, "integrator": self.integrator}


@dataclass(frozen=True)
class Counts:
    bodies: int
    joints: int
    dofs: int
    actuators: int
    sensors: int
    cameras: int

    def to_json(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in COUNT_KEYS}


COUNT_KEYS = ("bodies", "joints", "dofs", "actuators", "sensors", "cameras")


@dataclass(frozen=True)
class Camera:
    """A model camera: its body, its sensor's resolution (width, height; 0s: none) and
    its vertical field of view (degrees)."""

    name: str
    body: str
    resolution: tuple[int, int]
    fovy: float

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "body": self.body,
            "resolution": list(self.resolution),
            "fovy": self.fovy,
        }

    @classmethod
    def parse(cls, value: Any, key: str) -> Camera:
        section = _mapping(value, key, "not a mapping")
        res = section.get("resolution")
        if (
            not isinstance(res, (list, tuple))
            or len(res) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in res)
        ):
            raise ManifestError(f"{key}.resolution", f"{_shown(res)} is not two pixel counts")
        fovy = _number(section.get("fovy"), f"{key}.fovy", positive=True)
        if not fovy < 180:
            raise ManifestError(f"{key}.fovy", f"{_shown(fovy)} is not below 180 degrees")
        body = section.get("body", "")
        if not isinstance(body, str):
            raise ManifestError(f"{key}.body", f"{_shown(body)} is not a name")
        return cls(_name(section.get("name"), f"{key}.name"), body, (res[0], res[1]), fovy)


@dataclass(frozen=True)
class Rock:
    x: float
    y: float
    size: float
    entry: Mapping[str, Json]
    """Every field as facility.json gives it (``urdf2mjcf.facility.scatter.Rock``)."""


@dataclass(frozen=True)
class Rocks:
    """The recipe's scatter of rocks: its seed and each rock (x, y, size in m)."""

    seed: int | None
    rocks: tuple[Rock, ...]

    def to_json(self) -> dict[str, Any]:
        return {"seed": self.seed, "rocks": [thaw(r.entry) for r in self.rocks]}

    @classmethod
    def parse(cls, value: Any) -> Rocks:
        section = _mapping(value, "rocks", "not a mapping of seed and rocks")
        out = []
        items = section.get("rocks") or []
        if not isinstance(items, (list, tuple)):
            raise ManifestError("rocks.rocks", "not a list")
        for i, r in enumerate(items):
            key = f"rocks.rocks[{i}]"
            r = _mapping(r, key, "not a mapping")
            nums = [_number(r.get(k), f"{key}.{k}") for k in ("x", "y", "size")]
            out.append(Rock(nums[0], nums[1], nums[2], freeze(r)))
        seed = section.get("seed")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
            raise ManifestError("rocks.seed", f"{_shown(seed)} is not an integer")
        return cls(seed, tuple(out))


# -- the manifest -------------------------------------------------------------------------


@dataclass(frozen=True)
class Manifest:
    """A bundle's ``facility.json`` (docs/facility.md lists every field)."""

    components: Mapping[str, Component]
    schema_version: int = SCHEMA_VERSION
    generator: str = "make-facility"
    recipe: str = ""
    recipe_file: str | None = None
    bundle: BundleFiles = field(default_factory=BundleFiles)
    xacro: str = ""
    seed: int | None = None
    """The build's seed (None: nominal poses)."""
    flags: Mapping[str, Json] = field(default_factory=_empty)
    jitter: Mapping[str, Json] = field(default_factory=_empty)
    offsets: Mapping[str, Mapping[str, float]] = field(default_factory=_empty)
    """Component -> its drawn ``{dx, dy, dyaw}`` (m, rad)."""
    component_mjcf: Mapping[str, str] = field(default_factory=_empty)
    simulation: Simulation | None = None
    counts: Counts | None = None
    joints: tuple[Json, ...] = ()
    actuators: tuple[Json, ...] = ()
    sensors: tuple[Json, ...] = ()
    cameras: tuple[Camera, ...] = ()
    fiducials: tuple[Json, ...] = ()
    """The tags the build placed (``urdf2mjcf.facility.fiducials.manifest_entries``)."""
    noise: Mapping[str, Json] = field(default_factory=_empty)
    """The recipe's sensor noise (``urdf2mjcf.runner.noise.SensorNoise``'s config)."""
    mechanisms: tuple[Json, ...] = ()
    folded_geoms: Mapping[str, str] | None = None
    """Geom -> the link it was described on, for the fixtures the build folded."""
    rocks: Rocks | None = None
    files: tuple[str, ...] | None = None
    """Every file the build wrote (the folder is ours: a rebuild replaces exactly those)."""

    def to_json(self) -> dict[str, Any]:
        """The JSON object facility.json holds, in its order."""
        out: dict[str, Any] = {
            "schema_version": self.schema_version,
            "generator": self.generator,
            "recipe": self.recipe,
            "recipe_file": self.recipe_file,
            BUNDLE_KEY: self.bundle.to_json(),
            "xacro": self.xacro,
            "seed": self.seed,
            "flags": thaw(self.flags),
            "jitter": thaw(self.jitter),
            "offsets": thaw(self.offsets),
            "components": {n: c.to_json() for n, c in self.components.items()},
            "component_mjcf": dict(self.component_mjcf),
            "simulation": self.simulation.to_json() if self.simulation else None,
            "counts": self.counts.to_json() if self.counts else None,
            "joints": thaw(self.joints),
            "actuators": thaw(self.actuators),
            "sensors": thaw(self.sensors),
            "cameras": [c.to_json() for c in self.cameras],
            "fiducials": thaw(self.fiducials),
            "noise": thaw(self.noise),
            "mechanisms": thaw(self.mechanisms),
        }
        if self.folded_geoms is not None:
            out["folded_geoms"] = dict(self.folded_geoms)
        if self.rocks is not None:
            out["rocks"] = self.rocks.to_json()
        if self.files is not None:
            out["files"] = list(self.files)
        return out

    def dumps(self) -> str:
        """facility.json's text, as the builder writes it."""
        return json.dumps(self.to_json(), indent=2, sort_keys=False) + "\n"

    def component(self, name: str) -> Component | None:
        return self.components.get(name)

    def placed(self) -> list[str]:
        """The components the recipe placed (those with a pose), by name."""
        return [n for n, c in self.components.items() if c.pose is not None]

    def poses(self) -> dict[str, Pose]:
        """Component -> its pose, for the components the recipe placed."""
        return {n: c.pose for n, c in self.components.items() if c.pose is not None}

    def arms(self) -> dict[str, ArmRoles]:
        """Component -> its manipulator roles, for every component that has them."""
        return {n: c.arm for n, c in self.components.items() if c.arm is not None}

    def rovers(self) -> dict[str, RoverRoles]:
        """Component -> its rover roles, by component name."""
        return {n: c.rover for n, c in sorted(self.components.items()) if c.rover is not None}


def check_schema_version(data: Mapping[str, Any]) -> None:
    """The manifest's ``schema_version`` is the one this version reads."""
    version = data.get("schema_version")
    if type(version) is int and version == SCHEMA_VERSION:
        return
    if "schema_version" not in data:
        said = "missing: the bundle was built by an older make-facility"
    else:
        said = f"{_shown(version)} is not {SCHEMA_VERSION}, the version this runtime reads"
    raise ManifestError("schema_version", f"{said}; rebuild it with make-facility")


def _noise(value: Mapping[str, Any]) -> Mapping[str, Any]:
    """facility.json's ``noise``: channel -> false, or its settings, each a number in the
    range make-facility checks a recipe's against (:data:`urdf2mjcf.limits.NOISE_RANGES`)."""
    for channel, settings in value.items():
        key = f"noise.{channel}"
        if channel not in NOISE_CHANNELS:
            raise ManifestError(key, f"not a sensor channel ({', '.join(NOISE_CHANNELS)})")
        if settings is None or settings is False:
            continue
        for field_name, v in _mapping(settings, key, "not a mapping of settings, or false").items():
            where = f"{key}.{field_name}"
            if field_name not in NOISE_RANGES:
                raise ManifestError(where, "not a noise setting")
            if v is None and field_name == "focal_px":  # the rendering camera's
                continue
            low, high, low_open = NOISE_RANGES[field_name]
            if not is_number(v) or v > high or v < low or (low_open and v == low):
                bound = f"above {low:g}, up to {high:g}" if low_open else f"{low:g} .. {high:g}"
                raise ManifestError(where, f"{_shown(v)} is not a number in {bound}")
    return value


def _fiducials(value: list) -> list:
    """facility.json's ``fiducials``: each tag's id, size, component and, where the
    runtime localizes by it, its pose on the component (xyz, a 3 x 3 matrix)."""
    for i, tag in enumerate(value):
        key = f"fiducials[{i}]"
        tag = _mapping(tag, key)
        ident = tag.get("id")
        if isinstance(ident, bool) or not isinstance(ident, int) or not 0 <= ident < TAG_COUNT:
            raise ManifestError(
                f"{key}.id", f"{_shown(ident)} is not a tag id (0 .. {TAG_COUNT - 1})"
            )
        _number(tag.get("size"), f"{key}.size", positive=True)
        _name(tag.get("component"), f"{key}.component")
        if "pose_in_component" in tag:
            pose = _mapping(tag["pose_in_component"], f"{key}.pose_in_component")
            for name, n in (("xyz", 3), ("matrix", 9)):
                v = pose.get(name)
                where = f"{key}.pose_in_component.{name}"
                if not isinstance(v, (list, tuple)) or len(v) != n:
                    raise ManifestError(where, f"not a list of {n} numbers")
                for j, x in enumerate(v):
                    _number(x, f"{where}[{j}]")
    return value


def _section(data: Mapping[str, Any], key: str, kind: type, default: Any) -> Any:
    value = data.get(key, default)
    if value is None:
        return default
    if not isinstance(value, kind):
        raise ManifestError(key, f"not a {'list' if kind is list else 'mapping'}")
    return value


def from_json(data: Any) -> Manifest:
    """The :class:`Manifest` of a facility.json's JSON value; ManifestError naming the
    key of the first value refused."""
    if not isinstance(data, Mapping):
        raise ManifestError("components", "not a manifest of make-facility (no components)")
    check_schema_version(data)
    comps = data.get("components")
    if not isinstance(comps, Mapping):
        raise ManifestError("components", "not a manifest of make-facility (no components)")
    components = {}
    for name, comp in comps.items():
        components[str(name)] = Component.parse(str(name), comp)
    seed = data.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        raise ManifestError("seed", f"{_shown(seed)} is not a seed (a non-negative integer)")
    offsets = _section(data, "offsets", Mapping, {})
    for name, off in offsets.items():
        off = _mapping(off, f"offsets.{name}", "not a mapping of dx, dy, dyaw")
        for k, v in off.items():
            _number(v, f"offsets.{name}.{k}")
    cameras = tuple(
        Camera.parse(c, f"cameras[{i}]") for i, c in enumerate(_section(data, "cameras", list, []))
    )
    sim = data.get("simulation")
    simulation = None
    if isinstance(sim, Mapping) and "timestep" in sim:
        simulation = Simulation(
            _number(sim.get("timestep"), "simulation.timestep", positive=True),
            str(sim.get("integrator", "")),
        )
    counts = None
    raw_counts = data.get("counts")
    if isinstance(raw_counts, Mapping) and all(k in raw_counts for k in COUNT_KEYS):
        for k in COUNT_KEYS:
            v = raw_counts[k]
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ManifestError(f"counts.{k}", f"{_shown(v)} is not a count")
        counts = Counts(**{k: raw_counts[k] for k in COUNT_KEYS})
    folded = data.get("folded_geoms")
    if folded is not None:
        folded = _named(folded, "folded_geoms")
    rocks = Rocks.parse(data["rocks"]) if data.get("rocks") is not None else None
    files = data.get("files")
    if files is not None:
        files = _names(files, "files", empty=True)
    text = {}
    for k in ("generator", "recipe", "xacro"):
        v = data.get(k, "")
        if not isinstance(v, str):
            raise ManifestError(k, f"{_shown(v)} is not a name")
        text[k] = v
    recipe_file = data.get("recipe_file")
    if recipe_file is not None and not isinstance(recipe_file, str):
        raise ManifestError("recipe_file", f"{_shown(recipe_file)} is not a file name")
    mjcf = _section(data, "component_mjcf", Mapping, {})
    return Manifest(
        components=MappingProxyType(components),
        schema_version=SCHEMA_VERSION,
        generator=text["generator"],
        recipe=text["recipe"],
        recipe_file=recipe_file,
        bundle=BundleFiles.parse(data.get(BUNDLE_KEY)),
        xacro=text["xacro"],
        seed=seed,
        flags=freeze(_section(data, "flags", Mapping, {})),
        jitter=freeze(_section(data, "jitter", Mapping, {})),
        offsets=freeze(offsets),
        component_mjcf=_named(mjcf, "component_mjcf"),
        simulation=simulation,
        counts=counts,
        joints=freeze(_section(data, "joints", list, [])),
        actuators=freeze(_section(data, "actuators", list, [])),
        sensors=freeze(_section(data, "sensors", list, [])),
        cameras=cameras,
        fiducials=freeze(_fiducials(_section(data, "fiducials", list, []))),
        noise=freeze(_noise(_section(data, "noise", Mapping, {}))),
        mechanisms=freeze(_section(data, "mechanisms", list, [])),
        folded_geoms=folded,
        rocks=rocks,
        files=files,
    )


def parse_manifest(
    data: Any, path: Path | str, *, error: type[ForgeError] = BundleError
) -> Manifest:
    """:func:`from_json`, its refusal one ``error`` naming ``path`` (facility.json) and
    the key."""
    try:
        return from_json(data)
    except ManifestError as exc:
        raise error(exc.message, file=path, element=exc.key) from None


def read_manifest(path: Path, *, error: type[ForgeError] = BundleError) -> Manifest:
    """facility.json read once (as an untrusted file, within its size limit) and
    checked: the typed :class:`Manifest`, or one ``error`` naming the file and the key."""
    raw = untrusted.read_file(path, "report", error=error, what="manifest")
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else "not JSON"
        raise error(f"not a manifest of make-facility: {reason}", file=path) from None
    return parse_manifest(data, path, error=error)
