"""The sensors pass: described sensors and cameras -> MuJoCo sites, cameras and sensors.

Runs after the actuators pass and before emit. Reads the ``<gazebo>`` and
``<ros2_control>`` extensions (parsed by :mod:`.gazebo`) and
the actuators, and fills ``Model.sites``, ``Model.cameras``, ``Model.sensors``.
A robot without any of these returns unchanged.

Names (``<frame>`` is the link the sensor sits on; a joint reference means its
child link; a name already taken gets ``_2``, ``_3``, ... and a note):

=================  ==========================================================
camera, depth,     camera ``<frame>``: the optical frame when one is named, else
rgbd(_camera),     the reference link
depth_camera
imu                site ``<frame>``; ``<frame>_accelerometer``, ``<frame>_gyro``,
                   ``<frame>_orientation`` (framequat of the site)
force_torque       site ``<frame>``; ``<frame>_force``, ``<frame>_torque``
ray, gpu_ray,      site and rangefinder ``<frame>_ray_<k>``, k zero-padded to the
lidar, gpu_lidar   width of the ray count, vertical rows outer, horizontal inner
contact            box site and touch sensor ``<frame>_touch``
actuated joints    ``<joint>_pos`` (jointpos), ``<joint>_vel`` (jointvel)
=================  ==========================================================

A sensor site placed away from its link frame (an SDF ``<pose>``, a rotated
force-torque frame) is named ``<frame>_imu`` / ``<frame>_ft`` instead, so the
site ``<frame>`` always marks the link frame itself.

Frame conventions (rotations are quaternions (w, x, y, z) of the MuJoCo frame
in the frame it is placed on):

* MuJoCo cameras look along -z with +x right and +y up.
* ROS optical frames look along +z with +x right and +y down:
  MuJoCo camera = optical frame rotated 180 deg about x, ``(0, 1, 0, 0)``.
* Gazebo sensor frames (reference link + ``<pose>``) look along +x with +y left
  and +z up: MuJoCo camera = sensor frame rotated by ``(0.5, 0.5, -0.5, -0.5)``
  (camera x = -y, camera y = +z, camera z = -x of the sensor frame).
* Gazebo rays point along +x of the sensor frame turned by yaw = horizontal
  angle about z, then pitched up by the vertical angle; MuJoCo rangefinders
  measure along the site's +z: ray site = sensor frame * Rz(yaw) *
  Ry(pi/2 - pitch).
* MuJoCo's force and torque sensors report the wrench the parent body applies
  on the subtree of the site's body, at the site, in site axes: Gazebo's
  ``parent_to_child``. Gazebo's default ``child_to_parent`` is its negation,
  which no site rotation can produce (it has determinant -1); a note says so.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ...ir import Camera, Geom, Joint, Model, Note, Quat, RosTopic, Sensor, Site, Vec3
from ...transforms import (
    IDENTITY_QUAT,
    canonical_quat,
    pose_matrix,
    pose_quat,
    quat_mul,
    split_transform,
    transform,
    vec3,
)
from . import gazebo as gz

Q_OPTICAL_TO_CAMERA: Quat = (0.0, 1.0, 0.0, 0.0)
"""MuJoCo camera in a ROS optical frame: 180 deg about x."""
Q_GAZEBO_TO_CAMERA: Quat = (0.5, 0.5, -0.5, -0.5)
"""MuJoCo camera in a Gazebo sensor frame (x forward, y left, z up)."""
Q_GAZEBO_TO_OPTICAL: Quat = (0.5, -0.5, 0.5, -0.5)
"""ROS optical frame in a Gazebo sensor frame: URDF rpy (-pi/2, 0, -pi/2)."""

WORLD = "world"


@dataclass(frozen=True)
class SensorConfig:
    joint_sensors: bool = True
    """Add ``jointpos``/``jointvel`` sensors for every actuated joint."""
    gazebo: bool = True
    """Read ``<gazebo>`` sensor blocks (and the ROS 1 F/T and IMU model plugins)."""
    ros2_control: bool = True
    """Read ``<ros2_control>`` ``<sensor>`` elements."""
    contact_margin: float = 0.005
    """Metres added on every side of the box enclosing a link's collision geoms
    (the touch sensor's zone), so contact points on the surface fall inside."""
    many_rays: int = 360
    """A lidar with more rays than this gets a note (each ray is a sensor)."""
    optical_tolerance: tuple[float, float] = (1e-3, 1.0)
    """(metres, degrees): an optical frame further than this from the Gazebo
    sensor pose (turned to the optical convention) gets a warning."""


class _Builder:
    """New sites, cameras and sensors with unique names, and the notes about them."""

    def __init__(self, model: Model, cfg: SensorConfig) -> None:
        self.model, self.robot, self.cfg = model, model.robot, cfg
        self.sites: list[Site] = []
        self.cameras: list[Camera] = []
        self.sensors: list[Sensor] = []
        self.topics: list[RosTopic] = []
        self.notes: list[Note] = []
        self._sites = {s.name: s for s in model.sites}
        self._sensor_names = {s.name for s in model.sensors}
        self._camera_names = {c.name for c in model.cameras}
        self._mesh_vertices: dict[str, np.ndarray | None] = {}

    # -- names -------------------------------------------------------------

    def _unique(self, name: str, taken: Callable[[str], bool], element: str, what: str) -> str:
        final, k = name, 2
        while taken(final):
            final, k = f"{name}_{k}", k + 1
        if final != name:
            self.notes.append(Note("info", element, f"{what} name '{name}' taken; named '{final}'"))
        return final

    def site(
        self,
        name: str,
        body: str,
        pos: Vec3,
        quat: Quat,
        element: str,
        type: str = "sphere",
        size: tuple[float, ...] = Site.size,
    ) -> str:
        """Add a site (or reuse an identical one, e.g. an IMU and an F/T on one frame)."""
        site = Site(name, body, vec3(pos), canonical_quat(quat), type, size)  # type: ignore[arg-type]
        if self._sites.get(name) == site:
            return name
        links = self.robot.link_map
        # A link's name is its own frame site's name (emit adds one to frame-only links).
        final = self._unique(
            name, lambda n: n in self._sites or (n in links and n != body), element, "site"
        )
        site = replace(site, name=final)
        self.sites.append(site)
        self._sites[final] = site
        return final

    def sensor(self, sensor: Sensor, element: str) -> str:
        name = self._unique(sensor.name, self._sensor_names.__contains__, element, "sensor")
        self._sensor_names.add(name)
        self.sensors.append(replace(sensor, name=name))
        return name

    def camera(self, camera: Camera, element: str) -> str:
        name = self._unique(camera.name, self._camera_names.__contains__, element, "camera")
        self._camera_names.add(name)
        self.cameras.append(replace(camera, name=name))
        return name

    # -- frames ------------------------------------------------------------

    def frame(self, spec: gz.SensorSpec) -> str | None:
        """The link ``spec`` sits on, or None (with a warning)."""
        robot, ref = self.robot, spec.reference
        if ref is None:
            if spec.source == "ros2_control" and spec.name in robot.link_map:
                return spec.name
            why = (
                "has no frame_id parameter and its name is not a link"
                if spec.source == "ros2_control"
                else "has no reference link (a <gazebo> block without reference means the "
                "whole robot)"
            )
            self.notes.append(Note("warning", spec.element, f"{why}; skipped"))
            return None
        if ref in robot.link_map:
            return ref
        if ref in robot.joint_map:
            return robot.joint_map[ref].child
        self.notes.append(
            Note("warning", spec.element, f"frame '{ref}' is neither a link nor a joint; skipped")
        )
        return None

    def _chain(self, link: str) -> list[Joint]:
        chain: list[Joint] = []
        while link in self.robot.parent_joint:
            joint = self.robot.parent_joint[link]
            chain.append(joint)
            link = joint.parent
        return chain[::-1]

    def relative(self, a: str, b: str) -> np.ndarray | None:
        """Pose of link ``b`` in link ``a`` when only fixed joints separate them."""
        ca, cb = self._chain(a), self._chain(b)
        n = 0
        while n < min(len(ca), len(cb)) and ca[n] is cb[n]:
            n += 1
        if any(j.type != "fixed" for j in ca[n:] + cb[n:]):
            return None
        ta, tb = np.eye(4), np.eye(4)
        for j in ca[n:]:
            ta = ta @ pose_matrix(j.origin)
        for j in cb[n:]:
            tb = tb @ pose_matrix(j.origin)
        return np.linalg.inv(ta) @ tb

    # -- sensor kinds ------------------------------------------------------

    def add(self, spec: gz.SensorSpec, frame: str) -> bool:
        return {
            "camera": self._camera,
            "imu": self._imu,
            "force_torque": self._force_torque,
            "lidar": self._lidar,
            "contact": self._contact,
        }[spec.kind](spec, frame)

    def _optical_frame(self, spec: gz.SensorSpec, frame: str) -> str | None:
        cam = spec.camera
        assert cam is not None
        links = self.robot.link_map
        if cam.optical_frame is not None:
            if cam.optical_frame in links:
                return cam.optical_frame
            message = (
                f"optical frame '{cam.optical_frame}' is not a link; camera placed on "
                f"'{frame}' in the Gazebo convention (looking along +x)"
            )
            self.notes.append(Note("warning", spec.element, message))
        if cam.header_frame and cam.header_frame.endswith("optical_frame"):
            if cam.header_frame in links:
                return cam.header_frame
        if frame.endswith("optical_frame"):
            return frame
        return None

    def _camera(self, spec: gz.SensorSpec, frame: str) -> bool:
        cam = spec.camera
        assert cam is not None
        sensor_t = transform(spec.pos, spec.quat) @ transform(cam.pos, cam.quat)
        optical = self._optical_frame(spec, frame)
        if optical is None:
            body, convention = frame, "Gazebo sensor frame, looking along +x"
            cam_t = sensor_t @ transform((0, 0, 0), Q_GAZEBO_TO_CAMERA)
        else:
            body, convention = optical, "ROS optical frame, looking along +z"
            optical_t = sensor_t if optical == frame else np.eye(4)
            if optical != frame:
                self._check_optical(spec, frame, optical, sensor_t)
            cam_t = optical_t @ transform((0, 0, 0), Q_OPTICAL_TO_CAMERA)
        pos, quat = split_transform(cam_t)
        fovy = math.degrees(2 * math.atan(math.tan(cam.hfov / 2) * cam.height / cam.width))
        camera = Camera(
            name=body,
            body=body,
            pos=pos,
            quat=quat,
            fovy=fovy,
            resolution=(cam.width, cam.height),
            depth=cam.depth,
            near=cam.near,
            far=cam.far,
        )
        name = self.camera(camera, spec.element)
        self.topic("camera", name, spec)
        clip = ""
        if cam.near is not None or cam.far is not None:
            clip = (
                f"; clip {cam.near}..{cam.far} m not per camera in MuJoCo "
                "(global <visual><map znear/zfar>)"
            )
        message = (
            f"{spec.type} -> camera '{name}' on '{body}' ({convention}), "
            f"{cam.width}x{cam.height}, fovy {fovy:.6g} deg{', depth' if cam.depth else ''}{clip}"
        )
        self.notes.append(Note("info", spec.element, message))
        return True

    def _check_optical(
        self, spec: gz.SensorSpec, frame: str, optical: str, sensor_t: np.ndarray
    ) -> None:
        """Warn when the named optical frame is not where Gazebo renders from."""
        actual = self.relative(frame, optical)
        if actual is None:
            return
        expected = sensor_t @ transform((0, 0, 0), Q_GAZEBO_TO_OPTICAL)
        dist = float(np.linalg.norm(actual[:3, 3] - expected[:3, 3]))
        cos = (np.trace(expected[:3, :3].T @ actual[:3, :3]) - 1) / 2
        angle = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
        tol_pos, tol_deg = self.cfg.optical_tolerance
        if dist > tol_pos or angle > tol_deg:
            message = (
                f"optical frame '{optical}' is {dist:.3g} m and {angle:.3g} deg away from the "
                f"Gazebo sensor pose on '{frame}' (turned to the optical convention); the camera "
                "follows the optical frame"
            )
            self.notes.append(Note("warning", spec.element, message))

    def _imu(self, spec: gz.SensorSpec, frame: str) -> bool:
        imu = spec.imu or gz.ImuSpec()
        at_frame = _is_identity(spec.pos, spec.quat)
        site = self.site(
            frame if at_frame else f"{frame}_imu", frame, spec.pos, spec.quat, spec.element
        )
        for suffix, kind, noise in (
            ("accelerometer", "accelerometer", imu.accel_noise),
            ("gyro", "gyro", imu.gyro_noise),
        ):
            self.sensor(Sensor(f"{frame}_{suffix}", kind, site=site, noise=noise), spec.element)
        quat = Sensor(f"{frame}_orientation", "framequat", objtype="site", objname=site)
        self.sensor(quat, spec.element)
        self.topic("imu", site, spec)
        return True

    def topic(
        self, kind: Literal["imu", "wrench", "scan", "camera"], key: str, spec: gz.SensorSpec
    ) -> None:
        """The ROS topic the description names for this sensor, kept for a server (the
        first sensor on a key keeps it)."""
        if spec.topic is None or any(t.kind == kind and t.key == key for t in self.topics):
            return
        self.topics.append(RosTopic(kind, key, spec.topic, spec.frame_id))

    def _force_torque(self, spec: gz.SensorSpec, frame: str) -> bool:
        ft = spec.force_torque or gz.ForceTorqueSpec()
        if frame == WORLD and self.robot.root == WORLD:
            message = "on the world body, which has no parent to measure against; skipped"
            self.notes.append(Note("warning", spec.element, message))
            return False
        joint = self.robot.parent_joint.get(frame)
        quat = IDENTITY_QUAT
        if ft.frame == "parent" and joint is not None:
            w, x, y, z = pose_quat(joint.origin)
            quat = (w, -x, -y, -z)  # parent axes seen from the child at zero configuration
            if joint.type != "fixed":
                message = f"parent '{joint.parent}' axes are exact only at '{joint.name}' = 0"
                self.notes.append(Note("info", spec.element, message))
        elif ft.frame == "sensor":
            quat = spec.quat
        name = frame if _is_identity((0, 0, 0), quat) else f"{frame}_ft"
        # The site is at the link origin: the joint frame, where Gazebo takes the torque.
        site = self.site(name, frame, (0.0, 0.0, 0.0), quat, spec.element)
        self.sensor(
            Sensor(f"{frame}_force", "force", site=site, noise=ft.force_noise), spec.element
        )
        self.sensor(
            Sensor(f"{frame}_torque", "torque", site=site, noise=ft.torque_noise), spec.element
        )
        self.topic("wrench", site, spec)
        message = (
            f"force/torque at '{site}': MuJoCo reports the wrench the parent applies on "
            f"'{frame}' and everything below it, in the site's axes"
        )
        if ft.measure_direction == "child_to_parent":
            message += (
                " (Gazebo's parent_to_child); this sensor is child_to_parent, the negation: "
                "negate both readings (no site rotation can flip all three axes)"
            )
        self.notes.append(Note("info", spec.element, message))
        return True

    def _lidar(self, spec: gz.SensorSpec, frame: str) -> bool:
        lidar = spec.lidar
        assert lidar is not None
        yaws = lidar.horizontal.angles()
        pitches = lidar.vertical.angles() if lidar.vertical is not None else (0.0,)
        count = len(yaws) * len(pitches)
        width = len(str(count))
        k = 0
        for pitch in pitches:
            for yaw in yaws:
                turn = quat_mul(_qz(yaw), _qy(math.pi / 2 - pitch))
                name = f"{frame}_ray_{k:0{width}d}"
                site = self.site(name, frame, spec.pos, quat_mul(spec.quat, turn), spec.element)
                ray = Sensor(
                    site, "rangefinder", site=site, cutoff=lidar.range_max, noise=lidar.noise
                )
                self.sensor(ray, spec.element)
                k += 1
        self.topic("scan", frame, spec)
        last = f"{frame}_ray_{count - 1:0{width}d}"
        message = (
            f"{spec.type} -> {count} rangefinders {frame}_ray_{0:0{width}d}..{last} "
            f"({len(yaws)} x {len(pitches)} rays), measured from the sensor origin"
        )
        if lidar.range_min:
            message += f" (Gazebo's <range><min> {lidar.range_min} m is not applied)"
        if lidar.range_max is not None:
            message += f"; readings clamp at {lidar.range_max} m, -1 where nothing is hit"
        self.notes.append(Note("info", spec.element, message))
        if count > self.cfg.many_rays:
            message = f"{count} rays: one rangefinder sensor (ray cast per step) each"
            self.notes.append(Note("info", spec.element, message))
        for axis in (lidar.horizontal, lidar.vertical):
            if axis is not None and axis.resolution != 1.0:
                message = f"<resolution> {axis.resolution} ignored: one ray per sample"
                self.notes.append(Note("info", spec.element, message))
        return True

    def _contact(self, spec: gz.SensorSpec, frame: str) -> bool:
        points = []
        for geom in self.model.collision_geoms.get(frame, ()):
            local = self._geom_points(geom, spec.element)
            if local is not None:
                t = transform(geom.pos, geom.quat)
                points.append(local @ t[:3, :3].T + t[:3, 3])
        if not points:
            message = f"link '{frame}' has no collision geometry to sense contacts on; skipped"
            self.notes.append(Note("warning", spec.element, message))
            return False
        allp = np.concatenate(points)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        half = vec3((hi - lo) / 2 + self.cfg.contact_margin)
        name = f"{frame}_touch"
        site = self.site(name, frame, vec3((hi + lo) / 2), IDENTITY_QUAT, spec.element, "box", half)
        self.sensor(Sensor(name, "touch", site=site), spec.element)
        message = (
            f"touch sensor '{name}': box around all collision geoms of '{frame}' "
            f"+ {self.cfg.contact_margin} m"
        )
        self.notes.append(Note("info", spec.element, message))
        return True

    def _geom_points(self, geom: Geom, element: str) -> np.ndarray | None:
        """Points whose bounding box bounds the geom, in the geom frame."""
        if geom.type == "mesh":
            vertices = self._vertices(geom.mesh, element)
            return vertices
        if geom.type == "plane":
            return None  # unbounded: no box holds it
        size = geom.size
        half = {
            "box": lambda: size[:3],
            "sphere": lambda: (size[0],) * 3,
            "cylinder": lambda: (size[0], size[0], size[1]),
            "capsule": lambda: (size[0], size[0], size[1] + size[0]),
        }[geom.type]()
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        return signs * np.asarray(half, float)

    def _vertices(self, mesh: str | None, element: str) -> np.ndarray | None:
        if mesh not in self._mesh_vertices:
            asset = next((a for a in self.model.mesh_assets if a.name == mesh), None)
            vertices = asset.vertices if asset is not None else None
            if vertices is None or not len(vertices):
                message = f"mesh '{mesh}' has no readable vertices; left out of the touch zone"
                self.notes.append(Note("warning", element, message))
                vertices = None
            self._mesh_vertices[str(mesh)] = vertices
        return self._mesh_vertices[str(mesh)]

    # -- joints ------------------------------------------------------------

    def joint_sensors(self) -> None:
        seen: set[str] = set()
        for actuator in self.model.actuators:
            if actuator.joint in seen:
                continue
            seen.add(actuator.joint)
            joint = self.robot.joint_map.get(actuator.joint)
            element = f"joint '{actuator.joint}'"
            if joint is None or joint.type not in ("revolute", "continuous", "prismatic"):
                kind = "unknown" if joint is None else joint.type
                message = f"actuated joint is {kind}; no jointpos/jointvel sensors"
                self.notes.append(Note("warning", element, message))
                continue
            self.sensor(Sensor(f"{joint.name}_pos", "jointpos", joint=joint.name), element)
            self.sensor(Sensor(f"{joint.name}_vel", "jointvel", joint=joint.name), element)


def _is_identity(pos: Vec3, quat: Quat) -> bool:
    q = canonical_quat(quat)
    return max(abs(p) for p in pos) < 1e-12 and abs(q[0] - 1.0) < 1e-12


def _qz(angle: float) -> Quat:
    return (math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2))


def _qy(angle: float) -> Quat:
    return (math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0)


def run(model: Model, cfg: SensorConfig) -> Model:
    """Sites, cameras and sensors for the described sensors and the actuated joints."""
    builder = _Builder(model, cfg)
    sdf_specs: list[gz.SensorSpec] = []
    plugin_specs: list[gz.SensorSpec] = []
    ros_specs: list[gz.SensorSpec] = []
    for ext in model.robot.extensions:
        if ext.tag == "gazebo" and cfg.gazebo:
            specs, notes = gz.parse_gazebo(ext.xml)
            sdf_specs += [s for s in specs if s.source == "gazebo"]
            plugin_specs += [s for s in specs if s.source == "gazebo_plugin"]
        elif ext.tag == "ros2_control" and cfg.ros2_control:
            specs, notes = gz.parse_ros2_control(ext.xml)
            ros_specs += specs
        else:
            continue
        builder.notes += notes

    # A ROS 1 plugin or ros2_control sensor that repeats a Gazebo <sensor> (same frame and
    # kind, or same name: gz_ros2_control binds sensors by name) is the same sensor.
    by_frame: dict[tuple[str, str], str] = {}
    by_name: dict[tuple[str, str], str] = {}
    for spec in sdf_specs + plugin_specs + ros_specs:
        frame = builder.frame(spec)
        if frame is None:
            continue
        first = by_frame.get((frame, spec.kind)) or by_name.get((spec.name, spec.kind))
        if spec.source != "gazebo" and first is not None:
            message = f"same {spec.kind} as {first} on '{frame}'; not duplicated"
            builder.notes.append(Note("info", spec.element, message))
            continue
        if builder.add(spec, frame):
            by_frame.setdefault((frame, spec.kind), spec.element)
            by_name.setdefault((spec.name, spec.kind), spec.element)

    if cfg.joint_sensors:
        builder.joint_sensors()

    if not (builder.sites or builder.cameras or builder.sensors or builder.notes):
        return model
    return replace(
        model,
        sites=model.sites + tuple(builder.sites),
        cameras=model.cameras + tuple(builder.cameras),
        sensors=model.sensors + tuple(builder.sensors),
        ros_topics=model.ros_topics + tuple(builder.topics),
        notes=model.notes + tuple(builder.notes),
    )
