"""Sensor descriptions read from URDF extensions, before any placement.

Two sources, both kept verbatim by ``passes.parse`` as
:class:`~urdf2mjcf.ir.Extension` text:

* ``<gazebo reference="LINK_OR_JOINT">`` blocks holding ``<sensor type=... name=...>``,
  in Gazebo classic (ROS 1 and 2) and Gazebo Sim (gz) spellings, plus the two
  ROS 1 *model* plugins that act as sensors (``libgazebo_ros_ft_sensor.so`` with
  ``<jointName>``; ``libgazebo_ros_imu.so`` / ``libhector_gazebo_ros_imu.so`` with
  ``<bodyName>``);
* ``<ros2_control>`` ``<sensor>`` elements, classified by their state interfaces.

This module only parses (SDF defaults filled in, numbers checked); it knows
nothing of the robot's links. :mod:`urdf2mjcf.passes.sensors` places the
results in MuJoCo frames.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Literal

from lxml import etree

from ...ir import Note, Quat, Vec3
from ...transforms import IDENTITY_QUAT, canonical_quat, quat_from_rpy

SensorKind = Literal["camera", "imu", "force_torque", "lidar", "contact"]

GAZEBO_TYPES: dict[str, SensorKind] = {
    "camera": "camera",
    "depth": "camera",
    "depth_camera": "camera",
    "rgbd_camera": "camera",
    "rgbd": "camera",
    "imu": "imu",
    "force_torque": "force_torque",
    "ray": "lidar",
    "gpu_ray": "lidar",
    "lidar": "lidar",
    "gpu_lidar": "lidar",
    "contact": "contact",
}
"""Gazebo ``<sensor type>`` values we map, classic and gz spellings."""
DEPTH_TYPES = frozenset({"depth", "depth_camera", "rgbd_camera", "rgbd"})

OPTICAL_FRAME_TAGS = ("frame_name", "frameName", "optical_frame_id")
"""Tags (in ``<plugin>`` or ``<camera>``) that name the ROS optical frame of a camera."""
HEADER_FRAME_TAGS = ("gz_frame_id", "ignition_frame_id")
"""gz sensor tags naming the frame of the published messages: optical only by name."""

FT_INTERFACES = ("force.", "torque.")
IMU_INTERFACES = ("orientation.", "angular_velocity.", "linear_acceleration.")


@dataclass(frozen=True)
class CameraSpec:
    width: int
    """Pixels (SDF default 320)."""
    height: int
    """Pixels (SDF default 240)."""
    hfov: float
    """Horizontal field of view, radians (SDF default 1.047)."""
    depth: bool
    near: float | None = None
    """``<clip><near>``, metres; None when not given."""
    far: float | None = None
    optical_frame: str | None = None
    """Frame named by ``frame_name`` / ``frameName`` / ``optical_frame_id``."""
    header_frame: str | None = None
    """Frame named by ``gz_frame_id`` / ``ignition_frame_id`` (message header)."""
    pos: Vec3 = (0.0, 0.0, 0.0)
    """``<camera><pose>`` translation in the sensor frame, metres."""
    quat: Quat = IDENTITY_QUAT


@dataclass(frozen=True)
class ImuSpec:
    accel_noise: float | None = None
    """Largest stddev of the linear-acceleration noise, m/s^2."""
    gyro_noise: float | None = None
    """Largest stddev of the angular-velocity noise, rad/s."""


@dataclass(frozen=True)
class ScanAxis:
    samples: int
    min_angle: float
    """Radians."""
    max_angle: float
    resolution: float = 1.0

    def angles(self) -> tuple[float, ...]:
        """Gazebo's ray angles: evenly spaced, both ends included; 0 for one sample."""
        if self.samples <= 1:
            return (0.0,)
        step = (self.max_angle - self.min_angle) / (self.samples - 1)
        return tuple(self.min_angle + k * step for k in range(self.samples))


@dataclass(frozen=True)
class LidarSpec:
    horizontal: ScanAxis
    vertical: ScanAxis | None
    range_min: float | None
    """Metres."""
    range_max: float | None
    noise: float | None = None
    """Range noise stddev, metres."""


@dataclass(frozen=True)
class ForceTorqueSpec:
    frame: Literal["child", "parent", "sensor"] = "child"
    """Orientation the wrench is expressed in (SDF ``<frame>``, default child)."""
    measure_direction: Literal["child_to_parent", "parent_to_child"] = "child_to_parent"
    """SDF default: the wrench the child applies on the parent."""
    force_noise: float | None = None
    torque_noise: float | None = None


@dataclass(frozen=True)
class ContactSpec:
    collisions: tuple[str, ...] = ()
    """``<contact><collision>`` names (SDF collision names; informative only)."""


@dataclass(frozen=True)
class SensorSpec:
    """One described sensor, in the frame of ``reference`` offset by ``pos``/``quat``."""

    kind: SensorKind
    name: str
    """Sensor name in the description (Gazebo ``name`` / ros2_control ``name``)."""
    source: Literal["gazebo", "gazebo_plugin", "ros2_control"]
    type: str
    """The spelling in the description: Gazebo type, plugin file or ``ros2_control``."""
    reference: str | None
    """Link or joint name; None when the description gives none."""
    pos: Vec3 = (0.0, 0.0, 0.0)
    """SDF ``<pose>`` translation in the reference frame, metres."""
    quat: Quat = IDENTITY_QUAT
    """SDF ``<pose>`` rotation, (w, x, y, z)."""
    camera: CameraSpec | None = None
    imu: ImuSpec | None = None
    lidar: LidarSpec | None = None
    force_torque: ForceTorqueSpec | None = None
    contact: ContactSpec | None = None
    topic: str | None = None
    """The ROS topic its tags name, fully qualified (:func:`ros_topic`); None: none."""
    frame_id: str | None = None
    """The messages' frame its tags name (``frame_name``, ``frameName``, ``gz_frame_id``)."""

    @property
    def element(self) -> str:
        return f"{self.source.replace('_plugin', '')} sensor '{self.name}'"


class _Reader:
    """Number parsing that records problems as notes instead of failing."""

    def __init__(self, element: str) -> None:
        self.element = element
        self.notes: list[Note] = []

    def warn(self, message: str) -> None:
        self.notes.append(Note("warning", self.element, message))

    def text(self, el: etree._Element | None, path: str) -> str | None:
        if el is None:
            return None
        found = el.find(path)
        if found is None or found.text is None or not found.text.strip():
            return None
        return found.text.strip()

    def number(self, el: etree._Element | None, path: str, default: float | None) -> float | None:
        text = self.text(el, path)
        if text is None:
            return default
        try:
            value = float(text)
        except ValueError:
            self.warn(f"<{path}> is {text!r}, not a number; using {default!r}")
            return default
        if not math.isfinite(value):
            self.warn(f"<{path}> is {text!r}; using {default!r}")
            return default
        return value

    def count(self, el: etree._Element | None, path: str, default: int) -> int:
        value = self.number(el, path, float(default))
        assert value is not None
        if value < 1 or not float(value).is_integer():
            self.warn(f"<{path}> must be a positive integer, got {value!r}; using {default}")
            return default
        return int(value)

    def pose(self, el: etree._Element | None) -> tuple[Vec3, Quat]:
        """An SDF ``<pose>``: ``x y z roll pitch yaw`` (or ``x y z qx qy qz qw``)."""
        pose = el.find("pose") if el is not None else None
        if pose is None or not (pose.text or "").strip():
            return (0.0, 0.0, 0.0), IDENTITY_QUAT
        if pose.get("relative_to"):
            self.notes.append(
                Note(
                    "info",
                    self.element,
                    f"<pose relative_to='{pose.get('relative_to')}'> read as relative to the "
                    "sensor's reference frame",
                )
            )
        try:
            v = [float(t) for t in (pose.text or "").split()]
        except ValueError:
            self.warn(f"<pose> {pose.text!r} is not numbers; identity used")
            return (0.0, 0.0, 0.0), IDENTITY_QUAT
        quat_form = pose.get("rotation_format", "euler_rpy") == "quat_xyzw"
        if len(v) != (7 if quat_form else 6) or not all(math.isfinite(x) for x in v):
            self.warn(f"<pose> {pose.text!r} needs {7 if quat_form else 6} numbers; identity used")
            return (0.0, 0.0, 0.0), IDENTITY_QUAT
        pos: Vec3 = (v[0], v[1], v[2])
        if quat_form:
            return pos, canonical_quat((v[6], v[3], v[4], v[5]))
        rpy = v[3:6]
        if pose.get("degrees", "false").lower() in ("true", "1"):
            rpy = [math.radians(a) for a in rpy]
        return pos, quat_from_rpy((rpy[0], rpy[1], rpy[2]))

    def noise(self, el: etree._Element | None) -> float | None:
        """Largest positive ``stddev`` of the ``<noise>`` elements under ``el``."""
        if el is None:
            return None
        values = []
        for noise in el.iter("noise"):
            for std in noise.iter("stddev"):
                try:
                    value = float((std.text or "").strip())
                except ValueError:
                    self.warn(f"<noise><stddev> {std.text!r} is not a number; ignored")
                    continue
                if math.isfinite(value) and value > 0:
                    values.append(value)
        return max(values) if values else None


def _find_any(el: etree._Element, tags: tuple[str, ...]) -> str | None:
    for tag in tags:
        for sub in el.iter(tag):
            if sub.text and sub.text.strip():
                return sub.text.strip()
    return None


def _plugins(sensor: etree._Element) -> list[etree._Element]:
    return list(sensor.iter("plugin"))


def _plugin_noise(r: _Reader, sensor: etree._Element) -> float | None:
    """ROS 1 plugins' ``<gaussianNoise>`` (ROS 2: ``<gaussian_noise>``)."""
    for plugin in _plugins(sensor):
        for tag in ("gaussianNoise", "gaussian_noise"):
            value = r.number(plugin, tag, None)
            if value is not None and value > 0:
                return value
    return None


def _camera(r: _Reader, sensor: etree._Element, gz_type: str) -> CameraSpec:
    cam = sensor.find("camera")
    width = r.count(cam, "image/width", 320)
    height = r.count(cam, "image/height", 240)
    hfov = r.number(cam, "horizontal_fov", 1.047) or 1.047
    if not 0 < hfov < math.pi:
        r.warn(f"<horizontal_fov> {hfov!r} rad is outside (0, pi); using 1.047")
        hfov = 1.047
    clip = cam.find("clip") if cam is not None else None
    if clip is None and cam is not None:
        clip = cam.find("depth_camera/clip")
    optical = None
    for plugin in _plugins(sensor):
        optical = optical or _find_any(plugin, OPTICAL_FRAME_TAGS)
    if optical is None and cam is not None:
        optical = _find_any(cam, OPTICAL_FRAME_TAGS)
    pos, quat = r.pose(cam)
    return CameraSpec(
        width=width,
        height=height,
        hfov=hfov,
        depth=gz_type in DEPTH_TYPES,
        near=r.number(clip, "near", None),
        far=r.number(clip, "far", None),
        optical_frame=optical,
        header_frame=_find_any(sensor, HEADER_FRAME_TAGS),
        pos=pos,
        quat=quat,
    )


def _imu(r: _Reader, sensor: etree._Element) -> ImuSpec:
    imu = sensor.find("imu")
    accel = r.noise(imu.find("linear_acceleration")) if imu is not None else None
    gyro = r.noise(imu.find("angular_velocity")) if imu is not None else None
    old = imu.find("noise") if imu is not None else None  # SDF 1.4: <noise><rate>, <accel>
    if old is not None:
        gyro = gyro or r.number(old, "rate/stddev", None) or None
        accel = accel or r.number(old, "accel/stddev", None) or None
    plugin = _plugin_noise(r, sensor)
    return ImuSpec(accel_noise=accel or plugin, gyro_noise=gyro or plugin)


def _scan_axis(r: _Reader, el: etree._Element | None) -> ScanAxis | None:
    if el is None:
        return None
    return ScanAxis(
        samples=r.count(el, "samples", 640),
        min_angle=r.number(el, "min_angle", 0.0) or 0.0,
        max_angle=r.number(el, "max_angle", 0.0) or 0.0,
        resolution=r.number(el, "resolution", 1.0) or 1.0,
    )


def _lidar(r: _Reader, sensor: etree._Element) -> LidarSpec:
    ray = sensor.find("ray")
    if ray is None:
        ray = sensor.find("lidar")  # gz spelling
    scan = ray.find("scan") if ray is not None else None
    horizontal = _scan_axis(r, scan.find("horizontal") if scan is not None else None)
    if horizontal is None:
        r.warn("has no <scan><horizontal>; one ray along the sensor's x axis")
        horizontal = ScanAxis(1, 0.0, 0.0)
    vertical = _scan_axis(r, scan.find("vertical") if scan is not None else None)
    rng = ray.find("range") if ray is not None else None
    noise = r.noise(ray.find("noise") if ray is not None else None)
    if ray is not None and noise is None:
        noise = r.number(ray, "noise/stddev", None)
    return LidarSpec(
        horizontal=horizontal,
        vertical=vertical if vertical is not None and vertical.samples > 1 else None,
        range_min=r.number(rng, "min", None),
        range_max=r.number(rng, "max", None),
        noise=noise or _plugin_noise(r, sensor),
    )


def _force_torque(r: _Reader, sensor: etree._Element) -> ForceTorqueSpec:
    ft = sensor.find("force_torque")
    frame = (r.text(ft, "frame") or "child").lower()
    if frame not in ("child", "parent", "sensor"):
        r.warn(f"<frame> {frame!r} is not child, parent or sensor; using child")
        frame = "child"
    direction = (r.text(ft, "measure_direction") or "child_to_parent").lower()
    if direction not in ("child_to_parent", "parent_to_child"):
        r.warn(
            f"<measure_direction> {direction!r} is not child_to_parent or parent_to_child; "
            "using child_to_parent"
        )
        direction = "child_to_parent"
    plugin = _plugin_noise(r, sensor)
    return ForceTorqueSpec(
        frame=frame,  # type: ignore[arg-type]
        measure_direction=direction,  # type: ignore[arg-type]
        force_noise=r.noise(ft.find("force") if ft is not None else None) or plugin,
        torque_noise=r.noise(ft.find("torque") if ft is not None else None) or plugin,
    )


_ROS_NAME = re.compile(r"[A-Za-z_~/][A-Za-z0-9_/~]*")
FRAME_TAGS = ("frame_name", "frameName", *HEADER_FRAME_TAGS)
"""Tags naming the frame of a sensor's messages (ROS 2 plugins, ROS 1 plugins, gz)."""


def _qualified(namespace: str, name: str) -> str | None:
    """``/ns/name`` (``name`` absolute: itself); None for what is not a ROS name."""
    namespace, name = namespace.strip(), name.strip()
    if (
        not name
        or not _ROS_NAME.fullmatch(name)
        or (namespace and not _ROS_NAME.fullmatch(namespace))
    ):
        return None
    full = name if name.startswith("/") else f"/{namespace.strip('/')}/{name}"
    return re.sub(r"/+", "/", full).rstrip("/") or None


def _named_topic(
    sensor: etree._Element, ros2: Callable[[etree._Element], str], output: str, ros1: Callable
) -> str | None:
    """The first topic a sensor's tags name: a ROS 2 gazebo_ros plugin's ``<ros>``
    namespace with its ``~/<output>`` (remapped, else ``ros2(plugin)``), a ROS 1 plugin's
    ``<robotNamespace>`` with ``ros1(plugin)``, or gz's ``<topic>``."""
    for plugin in _plugins(sensor):
        ros = plugin.find("ros")
        if ros is not None:
            name = ros2(plugin)
            for remap in ros.findall("remapping"):
                left, sep, right = (remap.text or "").partition(":=")
                if sep and left.strip() in (f"~/{output}", output):
                    name = right.strip()
            found = _qualified((ros.findtext("namespace") or ""), name.removeprefix("~/"))
            if found:
                return found
        relative = ros1(plugin)
        if relative:
            found = _qualified(_find_any(plugin, ("robotNamespace",)) or "", relative)
            if found:
                return found
    topic = (sensor.findtext("topic") or "").strip()
    return _qualified("", topic) if topic else None


def ros_topic(sensor: etree._Element) -> str | None:
    """The topic a Gazebo sensor publishes on, as its tags name it: a ROS 2 gazebo_ros
    plugin's ``<ros><namespace>`` with its ``~/out`` remapped (else ``<plugin
    name>/out``), a ROS 1 plugin's ``<robotNamespace>``/``<topicName>``, or gz's
    ``<topic>``; None where none is named."""
    return _named_topic(
        sensor,
        lambda plugin: f"{(plugin.get('name') or 'sensor').strip()}/out",
        "out",
        lambda plugin: _find_any(plugin, ("topicName", "topic_name")),
    )


def ros_camera_topic(sensor: etree._Element) -> str | None:
    """A Gazebo camera's image topic as its tags name it: a ROS 2 gazebo_ros_camera's
    ``<ros><namespace>`` with ``<camera_name>`` (default the sensor's name) and its
    ``~/image_raw`` (remapped or not), a ROS 1 plugin's ``<robotNamespace>``,
    ``<cameraName>`` and ``<imageTopicName>``, or gz's ``<topic>``; None where none is
    named (the camera_info topic is its sibling, ``.../camera_info``)."""
    default = (sensor.get("name") or "camera").strip()

    def ros1(plugin: etree._Element) -> str | None:
        topic = _find_any(plugin, ("imageTopicName",))
        camera = _find_any(plugin, ("cameraName",))
        if topic and camera and not topic.startswith("/"):
            return f"{camera}/{topic}"
        return topic

    return _named_topic(
        sensor,
        lambda plugin: f"{(plugin.findtext('camera_name') or default).strip()}/image_raw",
        "image_raw",
        ros1,
    )


def ros_frame(sensor: etree._Element) -> str | None:
    for el in (*_plugins(sensor), sensor):
        for tag in FRAME_TAGS:
            text = (el.findtext(tag) or "").strip()
            if text and _ROS_NAME.fullmatch(text.lstrip("/")):
                return text.lstrip("/")
    return None


def _sensor(sensor: etree._Element, reference: str | None, notes: list[Note]) -> SensorSpec | None:
    gz_type = (sensor.get("type") or "").strip()
    name = sensor.get("name") or f"{reference or 'robot'}_{gz_type or 'sensor'}"
    r = _Reader(f"gazebo sensor '{name}'")
    kind = GAZEBO_TYPES.get(gz_type)
    if kind is None:
        supported = ", ".join(GAZEBO_TYPES)
        notes.append(
            Note("info", r.element, f"type '{gz_type}' is not mapped (supported: {supported})")
        )
        return None
    pos, quat = r.pose(sensor)
    spec = SensorSpec(kind, name, "gazebo", gz_type, reference, pos, quat)
    topic = ros_camera_topic(sensor) if kind == "camera" else ros_topic(sensor)
    spec = replace(spec, topic=topic, frame_id=ros_frame(sensor))
    if kind == "camera":
        spec = replace(spec, camera=_camera(r, sensor, gz_type))
    elif kind == "imu":
        spec = replace(spec, imu=_imu(r, sensor))
    elif kind == "lidar":
        spec = replace(spec, lidar=_lidar(r, sensor))
    elif kind == "force_torque":
        spec = replace(spec, force_torque=_force_torque(r, sensor))
    else:
        names = tuple(c.text.strip() for c in sensor.iterfind("contact/collision") if c.text)
        spec = replace(spec, contact=ContactSpec(names))
    notes.extend(r.notes)
    return spec


def _model_plugin(plugin: etree._Element, notes: list[Note]) -> SensorSpec | None:
    """ROS 1 model plugins that are sensors: force-torque on a joint, IMU on a body."""
    filename = plugin.get("filename") or ""
    name = plugin.get("name") or filename
    r = _Reader(f"gazebo sensor '{name}'")
    if filename.endswith("gazebo_ros_ft_sensor.so"):
        joint = r.text(plugin, "jointName")
        noise = _plugin_noise(r, plugin)
        # The plugin publishes the joint's wrench on the child link (parent on child).
        ft = ForceTorqueSpec("child", "parent_to_child", noise, noise)
        spec = SensorSpec("force_torque", name, "gazebo_plugin", filename, joint, force_torque=ft)
    elif filename.endswith(("gazebo_ros_imu.so", "hector_gazebo_ros_imu.so")):
        body = r.text(plugin, "bodyName")
        noise = _plugin_noise(r, plugin)
        imu = ImuSpec(noise, noise)
        spec = SensorSpec("imu", name, "gazebo_plugin", filename, body, imu=imu)
    else:
        return None
    topic = _find_any(plugin, ("topicName",))
    if topic:
        spec = replace(spec, topic=_qualified(_find_any(plugin, ("robotNamespace",)) or "", topic))
    notes.extend(r.notes)
    return spec


def parse_gazebo(xml: str) -> tuple[list[SensorSpec], list[Note]]:
    """Sensors of one ``<gazebo>`` extension, in document order."""
    root = etree.fromstring(xml)
    reference = (root.get("reference") or "").strip() or None
    specs: list[SensorSpec] = []
    notes: list[Note] = []
    for sensor in root.iter("sensor"):
        spec = _sensor(sensor, reference, notes)
        if spec is not None:
            specs.append(spec)
    for plugin in root.findall("plugin"):
        spec = _model_plugin(plugin, notes)
        if spec is not None:
            specs.append(spec)
    return specs, notes


def parse_ros2_control(xml: str) -> tuple[list[SensorSpec], list[Note]]:
    """``<sensor>`` elements of one ``<ros2_control>`` extension.

    Force-torque when a state interface starts with ``force.``/``torque.``; IMU
    when one starts with ``orientation.``/``angular_velocity.``/``linear_acceleration.``.
    ``reference`` is the ``frame_id`` parameter, or None (the pass then tries
    the sensor name as a link).
    """
    root = etree.fromstring(xml)
    specs: list[SensorSpec] = []
    notes: list[Note] = []
    for sensor in root.findall("sensor"):
        name = sensor.get("name") or "sensor"
        interfaces = [s.get("name") or "" for s in sensor.findall("state_interface")]
        params = {
            p.get("name"): (p.text or "").strip() for p in sensor.findall("param") if p.get("name")
        }
        frame = params.get("frame_id") or None
        found = False
        if any(i.startswith(FT_INTERFACES) for i in interfaces):
            specs.append(
                SensorSpec(
                    "force_torque",
                    name,
                    "ros2_control",
                    "ros2_control",
                    frame,
                    force_torque=ForceTorqueSpec(measure_direction="parent_to_child"),
                )
            )
            found = True
        if any(i.startswith(IMU_INTERFACES) for i in interfaces):
            specs.append(
                SensorSpec("imu", name, "ros2_control", "ros2_control", frame, imu=ImuSpec())
            )
            found = True
        if not found:
            notes.append(
                Note(
                    "info",
                    f"ros2_control sensor '{name}'",
                    f"state interfaces {interfaces} are not mapped (supported: force.*, torque.*, "
                    "orientation.*, angular_velocity.*, linear_acceleration.*)",
                )
            )
    return specs, notes
