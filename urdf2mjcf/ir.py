"""Typed, frozen data that flows between the compiler passes.

Two layers:

* the URDF layer (:class:`Robot` and its parts), produced by ``passes.parse``;
* the MJCF layer (:class:`Model`: geoms, assets, inertials per link), built up
  by ``passes.meshes``, ``passes.collision`` and ``passes.inertia`` and read
  by ``passes.emit``.

Conventions: lengths in metres, angles in radians, masses in kilograms,
quaternions ``(w, x, y, z)`` as MuJoCo writes them, inertia tensors about the
centre of mass. Nothing here touches the file system.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

if TYPE_CHECKING:
    from .packages import PackageResolver

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
RGBA = tuple[float, float, float, float]

# ---------------------------------------------------------------------------
# URDF layer
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class UrdfDocument:
    """Output of the xacro pass: plain URDF text and how to resolve its URIs."""

    source: Path
    """The file the user gave (``.urdf``, ``.xacro`` or ``.urdf.xacro``)."""
    xml: bytes
    """The expanded URDF document."""
    resolver: PackageResolver
    """Resolves the document's ``package://``, ``file://`` and relative URIs to files."""
    expanded: bool = False
    """True when xacro ran on the source."""
    warnings: tuple[str, ...] = ()
    """Warnings xacro printed while expanding."""
    notes: tuple[Note, ...] = ()
    """Liberties taken reading the source (repaired XML, substituted ``$(...)``)."""


@dataclass(frozen=True)
class Pose:
    """A URDF ``<origin>``: translation then fixed-axis roll, pitch, yaw (or, from
    URDF 1.1 on, a quaternion ``quat_xyzw``)."""

    xyz: Vec3 = (0.0, 0.0, 0.0)
    """(3,) float, metres."""
    rpy: Vec3 = (0.0, 0.0, 0.0)
    """(3,) float, radians; R = Rz(yaw) @ Ry(pitch) @ Rx(roll). With ``quat`` set, the
    same rotation as angles (exact but near pitch +-pi/2, where angles lose digits)."""
    quat: Quat | None = None
    """Unit (w, x, y, z), w >= 0, when the origin gave ``quat_xyzw`` (URDF 1.1): the
    rotation itself, which :func:`urdf2mjcf.transforms.pose_quat` returns."""

    @property
    def is_identity(self) -> bool:
        return (
            self.xyz == (0.0, 0.0, 0.0)
            and self.rpy == (0.0, 0.0, 0.0)
            and self.quat in (None, (1.0, 0.0, 0.0, 0.0))
        )


@dataclass(frozen=True)
class Box:
    size: Vec3
    """(3,) full edge lengths, metres."""


@dataclass(frozen=True)
class Cylinder:
    radius: float
    """Metres."""
    length: float
    """Full length along the local z axis, metres."""


@dataclass(frozen=True)
class Sphere:
    radius: float
    """Metres."""


@dataclass(frozen=True)
class Capsule:
    """Non-standard but common URDF extension: cylinder with hemispherical caps."""

    radius: float
    """Radius of the cylinder and of its caps, metres."""
    length: float
    """Length of the cylindrical part along z, metres."""


@dataclass(frozen=True)
class MeshRef:
    filename: str
    """The file name exactly as written in the URDF (for messages)."""
    path: Path | None
    """Resolved absolute path, or None when it could not be resolved."""
    scale: Vec3 = (1.0, 1.0, 1.0)
    """(3,) per-axis factors applied to the file's vertices, dimensionless."""


@dataclass(frozen=True)
class Plane:
    """Gazebo's ``<plane>``: infinite for collision; only legal in static links."""

    normal: Vec3 = (0.0, 0.0, 1.0)
    """(3,) unit normal in the element frame."""
    size: tuple[float, float] = (0.0, 0.0)
    """Full extents drawn (x, y), metres; 0 draws it infinite."""


Geometry = Box | Cylinder | Sphere | Capsule | MeshRef | Plane


@dataclass(frozen=True)
class Material:
    name: str
    """The ``name`` attribute; "" when unnamed."""
    rgba: RGBA | None = None
    """(4,) ``<color rgba>``, each 0..1; None when there is no ``<color>``."""
    texture: Path | None = None
    """Resolved absolute path of an image texture, if any."""


@dataclass(frozen=True)
class Visual:
    origin: Pose
    """Pose of the geometry frame in the link frame."""
    geometry: Geometry
    """The shape, sizes in metres (zero-size shapes are dropped by parse)."""
    material: Material | None = None
    """Inline ``<material>``, or the top-level one it names; None when absent."""
    name: str | None = None
    """The ``name`` attribute, or None."""


@dataclass(frozen=True)
class Collision:
    origin: Pose
    """Pose of the geometry frame in the link frame."""
    geometry: Geometry
    """The shape, sizes in metres (zero-size shapes are dropped by parse)."""
    name: str | None = None
    """The ``name`` attribute, or None; names the collision geoms when unique."""


@dataclass(frozen=True)
class Inertial:
    origin: Pose
    """Centre of mass and orientation of the frame ``inertia`` is written in."""
    mass: float
    """kg."""
    inertia: tuple[float, float, float, float, float, float]
    """(ixx, ixy, ixz, iyy, iyz, izz), kg m^2, about the COM in the ``origin`` frame."""


@dataclass(frozen=True)
class Link:
    name: str
    """Link name, unique in the robot."""
    inertial: Inertial | None = None
    """The ``<inertial>``, or None when absent."""
    visuals: tuple[Visual, ...] = ()
    """``<visual>`` elements in document order (unusable ones dropped)."""
    collisions: tuple[Collision, ...] = ()
    """``<collision>`` elements in document order (unusable ones dropped)."""


JointType = Literal[
    "revolute", "continuous", "prismatic", "fixed", "floating", "planar", "spherical"
]
JOINT_TYPES: tuple[str, ...] = (
    "revolute",
    "continuous",
    "prismatic",
    "fixed",
    "floating",
    "planar",
    "spherical",
)
"""``spherical`` (not in urdfdom; Gazebo and others read it) is a MuJoCo ball joint."""


@dataclass(frozen=True)
class Limit:
    lower: float | None = None
    """rad or m; None when absent."""
    upper: float | None = None
    """rad (revolute) or m (prismatic); None when absent."""
    effort: float | None = None
    """N m or N; None when absent."""
    velocity: float | None = None
    """rad/s or m/s."""
    acceleration: float | None = None
    """rad/s^2 or m/s^2 (URDF 1.2); None when absent. MuJoCo does not enforce it: kept
    for the report and planners."""
    deceleration: float | None = None
    """rad/s^2 or m/s^2 (URDF 1.2); urdfdom's default is ``acceleration``."""
    jerk: float | None = None
    """rad/s^3 or m/s^3 (URDF 1.2); None when absent."""


@dataclass(frozen=True)
class Dynamics:
    damping: float = 0.0
    """N m s/rad or N s/m."""
    friction: float = 0.0
    """Coulomb (dry) friction, N m or N."""


@dataclass(frozen=True)
class Mimic:
    joint: str
    """Name of the leader joint."""
    multiplier: float = 1.0
    """Follower per leader unit: rad/rad or m/m (rad/m or m/rad across joint types)."""
    offset: float = 0.0
    """follower = multiplier * leader + offset."""


@dataclass(frozen=True)
class Joint:
    name: str
    """Joint name, unique in the robot."""
    type: JointType
    """URDF joint type; non-URDF aliases already mapped by parse."""
    parent: str
    """Name of the parent link."""
    child: str
    """Name of the child link."""
    origin: Pose = Pose()
    """Pose of the joint (= child link) frame in the parent link frame."""
    axis: Vec3 = (1.0, 0.0, 0.0)
    """(3,) unit vector in the joint (= child link) frame."""
    limit: Limit | None = None
    """The ``<limit>``; units follow the type (rad or m). None when absent."""
    dynamics: Dynamics | None = None
    """The ``<dynamics>`` damping and friction; None when absent."""
    mimic: Mimic | None = None
    """The ``<mimic>`` (one naming a missing joint is dropped); None when absent."""

    @property
    def range(self) -> tuple[float, float] | None:
        """(lower, upper) MuJoCo limits the joint to: a revolute or prismatic joint's
        ``<limit>``, a missing end read as 0 as urdfdom reads it. None: unlimited (no
        limit, another type, or no range: lower == upper, or lower > upper, which
        urdfdom reads as unlimited too)."""
        if self.type not in ("revolute", "prismatic") or self.limit is None:
            return None
        lo, hi = self.limit.lower or 0.0, self.limit.upper or 0.0
        return (lo, hi) if lo < hi else None


@dataclass(frozen=True)
class Extension:
    """A URDF extension element kept verbatim for later passes to map."""

    tag: str
    """``ros2_control``, ``transmission``, ``gazebo`` or ``mujoco``."""
    xml: str
    """The element serialised as XML text (kept as text so the IR stays immutable)."""


@dataclass(frozen=True)
class Robot:
    name: str
    """``<robot name>``, or the source file's stem when it has none."""
    source: Path
    """The file the description was read from (for error messages)."""
    links: tuple[Link, ...]
    """All links in document order; they form one tree."""
    joints: tuple[Joint, ...]
    """All joints in document order."""
    materials: tuple[Material, ...] = ()
    """Top-level named materials."""
    extensions: tuple[Extension, ...] = ()
    """Top-level extension elements in document order."""
    version: tuple[int, int] = (1, 0)
    """``<robot version>`` (URDF 1.0, 1.1 or 1.2; 1.0 when absent)."""

    @cached_property
    def link_map(self) -> dict[str, Link]:
        return {link.name: link for link in self.links}

    @cached_property
    def joint_map(self) -> dict[str, Joint]:
        return {joint.name: joint for joint in self.joints}

    @cached_property
    def parent_joint(self) -> dict[str, Joint]:
        """Child link name -> the joint that attaches it."""
        return {joint.child: joint for joint in self.joints}

    @cached_property
    def child_joints(self) -> dict[str, tuple[Joint, ...]]:
        """Link name -> joints whose parent it is, in document order."""
        out: dict[str, list[Joint]] = {link.name: [] for link in self.links}
        for joint in self.joints:
            out.setdefault(joint.parent, []).append(joint)
        return {k: tuple(v) for k, v in out.items()}

    @cached_property
    def root(self) -> str | None:
        """The single root link (None for an empty robot); parse guarantees uniqueness."""
        roots = [link.name for link in self.links if link.name not in self.parent_joint]
        return roots[0] if roots else None

    def is_moving(self, link: str) -> bool:
        """True when some non-fixed joint lies between the root and ``link``."""
        while link in self.parent_joint:
            joint = self.parent_joint[link]
            if joint.type != "fixed":
                return True
            link = joint.parent
        return False

    def topological_links(self) -> tuple[str, ...]:
        """Link names, parents before children, siblings in document order."""
        if self.root is None:
            return ()
        order: list[str] = []
        stack = [self.root]
        while stack:
            name = stack.pop()
            order.append(name)
            stack.extend(j.child for j in reversed(self.child_joints.get(name, ())))
        return tuple(order)


# ---------------------------------------------------------------------------
# MJCF layer
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class MeshData:
    """A triangle mesh in metres (URDF scale applied) in its mesh-file frame."""

    vertices: np.ndarray
    """(n, 3) float64, metres."""
    faces: np.ndarray
    """(m, 3) int64 vertex indices, counter-clockwise seen from outside."""
    uv: np.ndarray | None = None
    """(n, 2) float64 texture coordinates per vertex, or None."""


@dataclass(frozen=True, eq=False)
class MeshPart:
    """One material's share of a loaded mesh file."""

    mesh: MeshData
    """This part's triangles, metres, in the mesh-file frame."""
    material: str | None
    """Name of a :class:`MaterialAsset`, or None for the element's own colour."""


@dataclass(frozen=True, eq=False)
class LoadedMesh:
    """A mesh file loaded once for a given scale."""

    path: Path
    """Resolved absolute path of the mesh file."""
    scale: Vec3
    """(3,) per-axis factors applied to its vertices (``MeshRef.scale``), dimensionless."""
    parts: tuple[MeshPart, ...]
    """Per-material pieces (visual use)."""
    merged: MeshData
    """All parts in one mesh (collision and inertia use)."""
    sha256: str
    """Hash of the file content and scale: the identity of this mesh."""


@dataclass(frozen=True)
class MeshAsset:
    """A mesh file written to ``assets/``."""

    name: str
    """MJCF asset name; unique, derived from the source stem and the content hash."""
    file: str
    """File name inside ``assets/``."""
    data: bytes = field(repr=False)
    """Exact file content (binary STL or OBJ)."""
    vertices: np.ndarray | None = field(default=None, repr=False, compare=False)
    """(n, 3) float64 vertices exactly as ``data`` stores them (STL: rounded to float32),
    kept so that later passes (inertia, sensors) need not decode ``data`` again."""
    digest: bytes = field(default=b"", repr=False, compare=False)
    """sha256 of ``data`` (empty: not computed), so merging assets hashes each once."""


@dataclass(frozen=True)
class TextureAsset:
    name: str
    """MJCF texture asset name; unique, from the image stem and the content hash."""
    file: str
    """File name inside ``assets/`` (``<name>.png``)."""
    data: bytes = field(repr=False)
    """Exact file content (8-bit RGB or RGBA PNG)."""


@dataclass(frozen=True)
class MaterialAsset:
    name: str
    """MJCF material asset name; unique, from a stem and the content hash."""
    rgba: RGBA = (1.0, 1.0, 1.0, 1.0)
    """(4,) red, green, blue, alpha, each 0..1."""
    texture: str | None = None
    """Name of a :class:`TextureAsset`."""


GeomType = Literal["box", "sphere", "cylinder", "capsule", "mesh", "plane"]


@dataclass(frozen=True)
class Geom:
    role: Literal["visual", "collision"]
    """Emit's default class: ``visual`` (group 2, no contacts) or ``collision`` (group 3)."""
    type: GeomType
    """MuJoCo geom type; decides what ``size`` means."""
    pos: Vec3
    """Position in the link frame, metres."""
    quat: Quat
    """Orientation in the link frame, (w, x, y, z)."""
    size: tuple[float, ...] = ()
    """MuJoCo size semantics: box half-extents; sphere radius; cylinder/capsule
    (radius, half-length); plane (half x, half y, grid spacing). Empty for meshes."""
    mesh: str | None = None
    """MeshAsset name for mesh geoms."""
    material: str | None = None
    """MaterialAsset name."""
    rgba: RGBA | None = None
    """(4,) colour, each 0..1, overriding ``material``; None: material or class colour."""
    name: str | None = None
    """MJCF geom name (collision geoms get one from the collision pass), or None."""


@dataclass(frozen=True)
class BodyInertial:
    mass: float
    """kg."""
    pos: Vec3
    """Centre of mass in the link frame, metres."""
    fullinertia: tuple[float, float, float, float, float, float]
    """MuJoCo order (ixx, iyy, izz, ixy, ixz, iyz), kg m^2, about the COM, link axes."""
    source: Literal["urdf", "repaired", "estimated"] = "urdf"
    """Where it came from: the URDF as given, repaired for MuJoCo, or estimated from geometry."""


ActuatorKind = Literal["position", "velocity", "motor"]


@dataclass(frozen=True)
class Actuator:
    """One MuJoCo actuator driving one joint (mimic followers get none)."""

    name: str
    """Actuator name; by convention the joint name."""
    joint: str
    """Name of the (one-degree-of-freedom) joint it drives."""
    kind: ActuatorKind
    """``position`` (servo with kp, kv), ``velocity`` (gain kv) or ``motor`` (torque)."""
    kp: float | None = None
    """Position gain, N m/rad or N/m (position actuators)."""
    kv: float | None = None
    """Velocity gain: damping of a position servo, or the gain of a velocity actuator."""
    ctrlrange: tuple[float, float] | None = None
    """Command range: rad or m (position), rad/s or m/s (velocity), N m or N (motor)."""
    forcerange: tuple[float, float] | None = None
    """Force/torque limit, N m or N."""
    actuator_class: str | None = None
    """Default class name, for grouping actuators of one size."""


@dataclass(frozen=True)
class JointTuning:
    """Joint properties that controllers care about, set from actuator parameters."""

    armature: float | None = None
    """Reflected rotor inertia, kg m^2 (or kg)."""
    damping: float | None = None
    """N m s/rad; replaces the URDF <dynamics> damping when given."""
    frictionloss: float | None = None
    """N m; replaces the URDF <dynamics> friction when given."""


@dataclass(frozen=True)
class Site:
    name: str
    """MJCF site name, unique in the model (sensors refer to it)."""
    body: str
    """Link the site is attached to."""
    pos: Vec3 = (0.0, 0.0, 0.0)
    """(3,) position in the ``body`` link frame, metres."""
    quat: Quat = (1.0, 0.0, 0.0, 0.0)
    """Orientation in the ``body`` link frame, (w, x, y, z); the sensor axes."""
    type: Literal["sphere", "box"] = "sphere"
    """MuJoCo site shape; with ``size``, the zone a touch sensor counts contacts in."""
    size: tuple[float, ...] = (0.005,)
    """MuJoCo site size (sphere radius; box half-extents), metres."""


@dataclass(frozen=True)
class Camera:
    name: str
    """MJCF camera name, unique in the model."""
    body: str
    """Link the camera is attached to."""
    pos: Vec3
    """(3,) position of the camera in the link frame, metres."""
    quat: Quat
    """MuJoCo camera frame in the link frame: looks along -z, +y up."""
    fovy: float
    """Vertical field of view, degrees."""
    resolution: tuple[int, int]
    """(width, height), pixels."""
    depth: bool = False
    """True when the description asks for depth images too (RGBD)."""
    near: float | None = None
    """Near clip distance from the description, metres, or None (see ``far``)."""
    far: float | None = None
    """Clip distances from the description, metres (reported; MuJoCo clips globally)."""


@dataclass(frozen=True)
class RosTopic:
    """Where a described sensor publishes on ROS (its Gazebo tags), for a server to keep."""

    kind: Literal["imu", "wrench", "scan", "camera"]
    """The message: sensor_msgs/Imu, geometry_msgs/WrenchStamped, sensor_msgs/LaserScan,
    sensor_msgs/Image (its CameraInfo beside it, ``.../camera_info``)."""
    key: str
    """What the sensor is read from: its site (imu, wrench), its link (scan), the
    camera's name (camera)."""
    topic: str
    """The fully qualified topic name (``/ns/name``; a camera's: its image topic)."""
    frame_id: str | None = None
    """The messages' header frame the description names; None: the site's or link's."""


BODY_SENSORS = frozenset({"force", "torque", "rangefinder", "touch"})
"""Sensors whose reading depends on the body their site is on: force and torque
measure the body's subtree, rangefinders skip the body's geoms, touch sensors
count the body's contacts."""


@dataclass(frozen=True)
class Sensor:
    """One MuJoCo sensor element."""

    name: str
    """MJCF sensor name, unique in the model."""
    type: str
    """MuJoCo sensor element: accelerometer, gyro, framequat, force, torque,
    rangefinder, touch, jointpos, jointvel, ..."""
    site: str | None = None
    """Site it reads at (IMU, force/torque, rangefinder, touch); None otherwise."""
    joint: str | None = None
    """Joint it reads (``jointpos``, ``jointvel``); None otherwise."""
    objtype: str | None = None
    """Frame sensors: MuJoCo type of the object read, e.g. ``site``; else None."""
    objname: str | None = None
    """Frame sensors: name of the object read; else None."""
    noise: float | None = None
    """Noise stddev in the reading's unit (m/s^2, rad/s, N, N m, m); None: none."""
    cutoff: float | None = None
    """Clamp on the reading, its unit (rangefinder: max range, m); None: none."""


NoteKind = Literal[
    "warning",
    "repaired",
    "estimated",
    "decomposed",
    "cached",
    "hull",
    "primitive",
    "decimated",
    "excluded",
    "info",
]
"""``decomposed``: CoACD ran; ``cached``: a decomposition came from the disk cache;
``primitive``: a collision mesh became fitted primitives; ``excluded``: a pair of bodies
the conversion does not collide (a contact ``<exclude>``)."""

CollisionShape = Literal["decompose", "hull", "primitive", "auto"]
"""What a collision mesh becomes (see :mod:`urdf2mjcf.passes.collision`)."""

COLLISION_SHAPES: tuple[CollisionShape, ...] = ("decompose", "hull", "primitive", "auto")
CONTACTS = ("keep", "resolve")
"""What a description may say of the contacts the conversion creates at home: ``keep``
them as converted, or ``resolve`` them (the contacts pass's exclusions, the default)."""


@dataclass(frozen=True)
class Note:
    """One line of the conversion report."""

    kind: NoteKind
    """Category; ``warning``, ``repaired`` and ``decimated`` are shown without ``-v``."""
    element: str
    """What it concerns, e.g. ``link 'base'`` or ``mesh 'meshes/arm.stl'``."""
    message: str
    """One sentence for the user, with units where it gives numbers."""


@dataclass(frozen=True, eq=False)
class Model:
    """Everything emit needs: the robot plus per-link geoms, inertials and assets.

    Mappings are keyed by link name and must not be mutated: passes build new
    ones and return ``dataclasses.replace(model, ...)``.
    """

    robot: Robot
    """The parsed URDF (URDF layer); passes after parse do not change it."""
    meshes: Mapping[tuple[Path, Vec3], LoadedMesh] = field(default_factory=dict)
    """Loaded mesh files keyed by (path, scale)."""
    mesh_assets: tuple[MeshAsset, ...] = ()
    """Mesh files for ``assets/`` (visual and collision), each content stored once."""
    textures: tuple[TextureAsset, ...] = ()
    """Texture images for ``assets/``, in order of first use."""
    materials: tuple[MaterialAsset, ...] = ()
    """MJCF materials the visual geoms use, in order of first use."""
    visual_geoms: Mapping[str, tuple[Geom, ...]] = field(default_factory=dict)
    """Link name -> its visual geoms, placed in the link frame."""
    collision_geoms: Mapping[str, tuple[Geom, ...]] = field(default_factory=dict)
    """Link name -> its collision geoms, placed in the link frame."""
    inertials: Mapping[str, BodyInertial | None] = field(default_factory=dict)
    """Link name -> mass, COM and inertia; None for a massless body."""
    actuators: tuple[Actuator, ...] = ()
    """In the document order of the joints they drive."""
    joint_tuning: Mapping[str, JointTuning] = field(default_factory=dict)
    """Joint name -> armature, damping, friction from actuator parameters."""
    home: Mapping[str, float] = field(default_factory=dict)
    """Joint name -> position in the ``home`` keyframe (ros2_control ``initial_value``);
    other joints start at 0 clamped into their range."""
    gravcomp: Mapping[str, float] = field(default_factory=dict)
    """Link name -> gravity compensation (0..1, MuJoCo body ``gravcomp``)."""
    sites: tuple[Site, ...] = ()
    """Sites the sensors pass adds (emit adds frame sites for frame-only links)."""
    cameras: tuple[Camera, ...] = ()
    """Cameras from the description's camera sensors."""
    sensors: tuple[Sensor, ...] = ()
    """MJCF sensors, in the order emit writes them."""
    ros_topics: tuple[RosTopic, ...] = ()
    """Topics the description names for its sensors (emit writes them as ``<custom>``
    texts ``ros2:<kind>:<key>``)."""
    notes: tuple[Note, ...] = ()
    """The conversion report so far, in the order the passes added them."""

    def sensor_bodies(self) -> frozenset[str]:
        """Links carrying the site of a :data:`BODY_SENSORS` sensor: merging one
        into its parent (``fuse_fixed``) would change what the sensor measures."""
        site_body = {site.name: site.body for site in self.sites}
        return frozenset(
            site_body[s.site]
            for s in self.sensors
            if s.type in BODY_SENSORS and s.site in site_body
        )
