"""ROS 2 recordings of a simulated run: an MCAP file that ``ros2 bag play`` and Foxglove open.

A :class:`Recorder` is called after every physics step and writes, at rates of
simulated time (:class:`Rates`), stamped with ``data.time``:

================================================  ==========================================
topic                                             type
================================================  ==========================================
``/joint_states``                                 ``sensor_msgs/msg/JointState``
``/tf``                                           ``tf2_msgs/msg/TFMessage``
``/<role>_camera/color/image_raw``                ``sensor_msgs/msg/Image`` (rgb8)
``/<role>_camera/color/camera_info``              ``sensor_msgs/msg/CameraInfo``
``/<role>_camera/aligned_depth_to_color/...``     the same two, depth as 16UC1 (millimetres)
``/<ft>/wrench``                                  ``geometry_msgs/msg/WrenchStamped``
``/<rover>/imu/data``                             ``sensor_msgs/msg/Imu``
================================================  ==========================================

Frames are MuJoCo's names: ``world``, every body of a robot's kinematic tree
(each transform relative to its parent body), a free component's body
(``world -> ctb``), and the cameras' and sensors' sites as children of their
bodies. A camera's frame is the ROS optical frame (z forward, x right, y down):
MuJoCo's camera frame turned 180 deg about x. Depth follows the RealSense ROS
driver (``realsense2_camera``): ``aligned_depth_to_color`` as 16UC1 in mm, 0
where nothing is seen. Everything goes on ``/tf`` (none on ``/tf_static``): a
bag played from any point, or a subscriber that joins late, has the whole tree.
Given a ``SensorNoise`` (``facility-demo --record`` passes the facility's), images,
depth and wrenches carry the sensor noise the run's cameras see; joint states, TF
and IMU are exact.

The writer libraries are the optional extra ``ros`` (``mcap``,
``mcap-ros2-support``), imported only when a recording is asked for.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

import mujoco
import numpy as np

from ..bundle_manifest import Manifest
from ..errors import OutputError
from ..output import Reserved, check_output_file, read_own, reserve
from .camera import CameraModel
from .load import ROBOT_ROLES, Facility, LoadError, lookup, robot_roles

if TYPE_CHECKING:
    from .noise import SensorNoise
    from .perception import Camera
    from .rover.roles import Rover

SUFFIX = ".mcap"
METADATA = "urdf2mjcf"
"""Name of the MCAP metadata record that marks a recording as ours (``generator``)."""
INSTALL = "pip install 'mjcf-forge[ros]'"


@dataclass(frozen=True)
class Rates:
    """Messages per second of simulated time (0: the topic is not recorded)."""

    joint_states: float = 100.0
    tf: float = 100.0
    wrench: float = 100.0
    imu: float = 100.0
    images: float = 10.0
    """Both images and both camera infos of every camera; each costs a render."""


@dataclass(frozen=True)
class WrenchSource:
    topic: str
    site: int
    force: int
    torque: int
    """sensordata addresses of the force and torque sensors (3 each, in the site frame)."""


@dataclass(frozen=True)
class ImuSource:
    topic: str
    site: int
    accel: int
    gyro: int
    orientation: int
    """sensordata addresses of accelerometer, gyro and framequat (w, x, y, z)."""


@dataclass
class Sources:
    """What a recording holds, as MuJoCo ids."""

    joints: list[int] = field(default_factory=list)
    """Joint ids on /joint_states (hinge or slide)."""
    trees: list[int] = field(default_factory=list)
    """Root bodies whose kinematic trees go on /tf."""
    free: list[int] = field(default_factory=list)
    """Bodies published as world -> body."""
    cameras: dict[str, int] = field(default_factory=dict)
    """Role -> camera id."""
    wrenches: list[WrenchSource] = field(default_factory=list)
    imus: list[ImuSource] = field(default_factory=list)


# -- what to record, read from the roles as the runners read them ---------------------------


def _free_components(m: mujoco.MjModel, manifest: Manifest) -> list[int]:
    """Bodies of the manifest's free components (a free body's prefix is its name)."""
    out = []
    for comp in manifest.components.values():
        if comp.free and comp.prefix:
            b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, comp.prefix)
            if b >= 0:
                out.append(b)
    return sorted(out)


def _sensor(m: mujoco.MjModel, name: Any, where: str, file: Path | None) -> int:
    s = lookup(m, mujoco.mjtObj.mjOBJ_SENSOR, name, file=file, element=where)
    return int(m.sensor_adr[s])


def facility_sources(fac: Facility) -> Sources:
    """The facility robot's joints (gripper included), its tree, its cameras and its wrist
    force-torque sensor (``roles.force_torque``), and the free components (the CTB)."""
    m, r = fac.model, fac.robot
    where = fac.folder / "facility.json"
    ft = robot_roles(fac.manifest, where).force_torque
    wrenches = []
    if ft is not None:
        at = f"{ROBOT_ROLES}.force_torque"
        name: Any = ft.get("site")
        site = lookup(m, mujoco.mjtObj.mjOBJ_SITE, name, file=where, element=at)
        wrenches.append(
            WrenchSource(
                f"/{m.site(site).name}/wrench",
                site,
                _sensor(m, ft.get("force"), f"{at}.force", where),
                _sensor(m, ft.get("torque"), f"{at}.torque", where),
            )
        )
    root = int(m.body_rootid[m.jnt_bodyid[r.joints[0]]])
    return Sources(
        joints=[int(j) for j in (*r.joints, *r.gripper_joints)],
        trees=[root],
        free=_free_components(m, fac.manifest),
        cameras=dict(r.cameras),
        wrenches=wrenches,
    )


def rover_sources(
    m: mujoco.MjModel,
    manifest: Manifest,
    rovers: Mapping[str, Rover],
    cameras: Mapping[str, str] | None = None,
) -> Sources:
    """Every rover's wheel and arm joints, its tree and its IMU (``/<rover>/imu/data``),
    and the free components; ``cameras``: rover -> camera role to record (none by
    default: six cameras at 10 Hz would dominate the run)."""
    J = mujoco.mjtObj.mjOBJ_JOINT
    src = Sources(free=_free_components(m, manifest))
    for name, rv in rovers.items():
        spec = rv.spec
        names = [*spec.wheels.left, *spec.wheels.right, *spec.arm_joints]
        src.joints += [lookup(m, J, j) for j in names]
        src.trees.append(int(m.body_rootid[rv.base]))
        site = lookup(m, mujoco.mjtObj.mjOBJ_SITE, spec.imu.site or "")
        src.imus.append(ImuSource(f"/{name}/imu/data", site, rv.accel, rv.gyro, rv.orientation))
    for name, role in (cameras or {}).items():
        cams = rovers[name].spec.cameras
        if role not in cams:
            raise LoadError(
                f"rover '{name}' has no camera '{role}'; cameras: {', '.join(cams) or 'none'}",
                element="--record-camera",
            )
        key = role if len(rovers) == 1 else f"{name}_{role}"
        src.cameras[key] = lookup(m, mujoco.mjtObj.mjOBJ_CAMERA, cams[role])
    return src


# -- ROS 2 message definitions (Humble = Jazzy for these), as ros2 bag writes them ---------

_MSGS = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Transform": (
        "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation"
    ),
    "geometry_msgs/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform"
    ),
    "geometry_msgs/Wrench": "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque",
    "geometry_msgs/WrenchStamped": "std_msgs/Header header\ngeometry_msgs/Wrench wrench",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "sensor_msgs/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
        "float64[] effort"
    ),
    "sensor_msgs/Image": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
        "uint8 is_bigendian\nuint32 step\nuint8[] data"
    ),
    "sensor_msgs/RegionOfInterest": (
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify"
    ),
    "sensor_msgs/CameraInfo": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
        "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n"
        "uint32 binning_y\nsensor_msgs/RegionOfInterest roi"
    ),
    "sensor_msgs/Imu": (
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n"
        "float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n"
        "float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n"
        "float64[9] linear_acceleration_covariance"
    ),
}
_SEPARATOR = "=" * 80


def msgdef(datatype: str) -> str:
    """The definition of ``pkg/msg/Name`` with every type it uses, depth first, each after
    a line of 80 '=' and ``MSG: pkg/Name``: what ``ros2 bag record`` stores in MCAP."""
    pkg, _, name = datatype.split("/")
    order: list[str] = []

    def visit(short: str) -> None:
        for line in _MSGS[short].splitlines():
            kind = re.sub(r"\[\d*\]$", "", line.split()[0])
            if "/" in kind and kind not in order:
                order.append(kind)
                visit(kind)

    main = f"{pkg}/{name}"
    visit(main)
    parts = [_MSGS[main]] + [f"{_SEPARATOR}\nMSG: {t}\n{_MSGS[t]}" for t in order]
    return "\n".join(parts) + "\n"


# -- one file we write: ours to replace, anything else only with --overwrite --------------


def _writer_module() -> Any:
    try:
        import mcap_ros2.writer
    except ImportError:
        return None
    return mcap_ros2.writer


def check_recording(path: Path, overwrite: bool, generator: str) -> None:
    """Before the run: the MCAP libraries are there, ``path`` ends in .mcap, and an
    existing file there is a recording of ``generator`` (or ``overwrite``)."""
    if _writer_module() is None:
        raise OutputError(
            f"recording needs the MCAP libraries: {INSTALL}", file=path, element="--record"
        )
    if path.suffix.lower() != SUFFIX:
        raise OutputError(f"a recording must end in {SUFFIX}", file=path, element="--record")
    if path.is_dir():
        raise OutputError("is a folder; give the .mcap file to write", file=path)
    check_output_file(
        path,
        overwrite,
        lambda f: _generator_of(f) == generator,
        f"is not a recording of {generator}",
    )


def _generator_of(f: BinaryIO) -> str | None:
    from mcap.reader import make_reader

    for meta in make_reader(f).iter_metadata():
        if meta.name == METADATA:
            return meta.metadata.get("generator")
    return None


def recorded_by(path: Path) -> str | None:
    """The ``generator`` in our metadata record of an MCAP file; None for any other file
    (never opened unless it is a regular file: :func:`urdf2mjcf.output.read_own`)."""
    return read_own(path, _generator_of)


# -- the recorder ----------------------------------------------------------------------------

OPTICAL = np.array([0.0, 1.0, 0.0, 0.0])
"""A MuJoCo camera frame (looks along -z, y up) -> the ROS optical frame: 180 deg about x."""


def _stamp(t: float) -> dict:
    ns = int(round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def _xyzw(q: np.ndarray) -> dict:
    return {"x": float(q[1]), "y": float(q[2]), "z": float(q[3]), "w": float(q[0])}


def _vec(v: np.ndarray) -> dict:
    return {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])}


def _body_name(m: mujoco.MjModel, b: int) -> str:
    return m.body(b).name or f"body_{b}"


def relative(
    p_parent: np.ndarray, q_parent: np.ndarray, p_child: np.ndarray, q_child: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The child's pose in the parent's frame (quaternions w, x, y, z)."""
    inv = np.zeros(4)
    mujoco.mju_negQuat(inv, q_parent)
    p = np.zeros(3)
    mujoco.mju_rotVecQuat(p, p_child - p_parent, inv)
    q = np.zeros(4)
    mujoco.mju_mulQuat(q, inv, q_child)
    return p, q


def camera_info(m: mujoco.MjModel, cam: int, height: int, width: int) -> dict:
    """Pinhole intrinsics of a MuJoCo camera from its fovy, square pixels, the principal
    point at the image centre in ROS pixel coordinates (pixel centres on integers: (w-1)/2);
    no distortion (plumb_bob zeros)."""
    model = CameraModel.of(m, cam, width, height)
    f = model.focal
    cx, cy = model.principal_point
    return {
        "height": height,
        "width": width,
        "distortion_model": "plumb_bob",
        "d": [0.0] * 5,
        "k": [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0],
        "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "p": [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
    }


class _Clock:
    """Due at start and then every 1/rate s of simulated time (at the step nearest)."""

    def __init__(self, rate: float, t0: float, dt: float):
        self.period = 1.0 / rate if rate > 0 else None
        self.t0, self.half = t0, dt / 2
        self.k = 0

    def due(self, t: float) -> bool:
        if self.period is None or t - self.t0 < self.k * self.period - self.half:
            return False
        self.k = int(math.floor((t - self.t0 + self.half) / self.period)) + 1
        return True


@dataclass(frozen=True)
class _Attached:
    """A frame fixed to a body (a camera's optical frame, a sensor site)."""

    name: str
    body: int
    pos: np.ndarray
    quat: np.ndarray


class Recorder:
    """Writes the ``sources`` of ``(m, d)`` to ``path`` (an .mcap) at ``rates``.

    Call :meth:`step` after every physics step (the first call records the start): a
    hook of the run's :class:`~urdf2mjcf.runner.sim.Sim`, ``sim.on_step.append(rec.step)``;
    :meth:`close` finishes the file and moves it into place, :meth:`abort` leaves
    nothing. Also a context manager (an exception aborts). Each message, built once,
    also goes to every one of ``sinks`` as ``(topic, datatype, message, stamp_ns)``
    (the live Foxglove stream); with ``path`` None it goes only there."""

    def __init__(
        self,
        m: mujoco.MjModel,
        d: mujoco.MjData,
        sources: Sources,
        path: str | Path | Reserved | None,
        *,
        rates: Rates | None = None,
        generator: str = "urdf2mjcf",
        metadata: Mapping[str, str] | None = None,
        noise: SensorNoise | None = None,
        sinks: Sequence[Callable[[str, str, dict, int], None]] = (),
    ) -> None:
        """``noise``: images and wrenches as the real sensors read them (a
        :class:`~urdf2mjcf.runner.noise.SensorNoise` of its own, so that recording draws
        nothing from the run's noise); None: ideal. Joint states, TF and IMU are exact."""
        self.sinks = list(sinks)
        self.m, self.d, self.src, self.noise = m, d, sources, noise
        self.rates = rates or Rates()
        self.counts: dict[str, int] = {}
        self._cams: dict[int, Camera] = {}
        self._far = float(m.vis.map.zfar * m.stat.extent)
        self._edges = self._tree_edges()
        self._attached = self._attached_frames()
        self._closed = False
        self._file: BinaryIO | None = None
        self._writer: Any = None
        self._slot: Reserved | None = None
        self._own_slot = not isinstance(path, Reserved)  # else the caller commits it
        given = path.path if isinstance(path, Reserved) else path
        self.path = None if given is None else Path(given)
        if path is not None:
            self._open(path, generator, metadata)
        self._jobs = self._clocks()
        self._joint_names = [self.m.joint(j).name for j in sources.joints]

    def _open(
        self, path: str | Path | Reserved, generator: str, metadata: Mapping[str, str] | None
    ) -> None:
        module = _writer_module()
        if module is None:
            raise OutputError(
                f"recording needs the MCAP libraries: {INSTALL}", file=self.path, element="--record"
            )
        # a temporary file named with our process id: one a kill -9 leaves is removed by the
        # next run writing beside it (output.clean_stale), never left for good
        self._slot = path if isinstance(path, Reserved) else reserve(Path(path))
        self._file = open(self._slot.tmp, "wb")  # noqa: SIM115 (closed by close or abort)
        self._writer = module.Writer(self._file)
        self._writer.add_metadata(METADATA, {"generator": generator, **(metadata or {})})
        self._schemas = {
            t: self._writer.register_msgdef(t, msgdef(t))
            for t in (
                "sensor_msgs/msg/JointState",
                "tf2_msgs/msg/TFMessage",
                "sensor_msgs/msg/Image",
                "sensor_msgs/msg/CameraInfo",
                "geometry_msgs/msg/WrenchStamped",
                "sensor_msgs/msg/Imu",
            )
        }

    def _clocks(self) -> list[tuple[_Clock, Callable[[dict], None]]]:
        m, d, sources = self.m, self.d, self.src
        t0, dt = float(d.time), float(m.opt.timestep)
        r = self.rates
        jobs: list[tuple[_Clock, Callable[[dict], None]]] = []
        if sources.joints:
            jobs.append((_Clock(r.joint_states, t0, dt), self._joint_states))
        if self._edges or sources.free or self._attached:
            jobs.append((_Clock(r.tf, t0, dt), self._tf))
        if sources.wrenches:
            jobs.append((_Clock(r.wrench, t0, dt), self._wrenches))
        if sources.imus:
            jobs.append((_Clock(r.imu, t0, dt), self._imus))
        if sources.cameras:
            jobs.append((_Clock(r.images, t0, dt), self._images))
        return jobs

    # ------------------------------------------------------------ frames
    def _tree_edges(self) -> list[tuple[int, int]]:
        """(parent, child) body pairs of every tree, root's parent the world."""
        m = self.m
        roots = set(self.src.trees)
        inside: set[int] = set()
        edges = []
        for b in range(1, m.nbody):  # parents come before children in MuJoCo's order
            if b in roots or m.body_parentid[b] in inside:
                inside.add(b)
                edges.append((int(m.body_parentid[b]) if b not in roots else 0, b))
        return edges

    def _attached_frames(self) -> list[_Attached]:
        """Frames of the cameras (optical) and sensor sites that are not a body's own frame."""
        m = self.m
        bodies = {_body_name(m, b) for b in range(m.nbody)}
        self._frames: dict[tuple[str, int], str] = {}
        out = []
        fixed: list[tuple[str, int, str, int, np.ndarray, np.ndarray]] = []
        for cam in self.src.cameras.values():
            quat = np.zeros(4)
            mujoco.mju_mulQuat(quat, m.cam_quat[cam], OPTICAL)
            fixed.append(
                ("cam", cam, m.camera(cam).name, int(m.cam_bodyid[cam]), m.cam_pos[cam], quat)
            )
        for s in [w.site for w in self.src.wrenches] + [i.site for i in self.src.imus]:
            fixed.append(
                ("site", s, m.site(s).name, int(m.site_bodyid[s]), m.site_pos[s], m.site_quat[s])
            )
        for kind, i, name, body, pos, quat in fixed:
            own = np.allclose(pos, 0, atol=1e-9) and abs(abs(quat[0]) - 1) < 1e-9
            if own and name == _body_name(m, body):
                self._frames[kind, i] = name  # the body is the frame (the converter's case)
                continue
            frame = name if name not in bodies else f"{name}_{'optical' if kind == 'cam' else kind}"
            self._frames[kind, i] = frame
            out.append(_Attached(frame, body, np.array(pos, float), np.array(quat, float)))
        return out

    def camera_frame(self, cam: int) -> str:
        """The frame id of a camera's images (its ROS optical frame)."""
        return self._frames["cam", cam]

    def site_frame(self, site: int) -> str:
        """The frame id of a sensor site's messages."""
        return self._frames["site", site]

    # ------------------------------------------------------------ writing
    def _write(self, topic: str, datatype: str, msg: dict) -> None:
        ns = int(round(float(self.d.time) * 1e9))
        if self._writer is not None:
            self._writer.write_message(
                topic,
                self._schemas[datatype],
                msg,
                log_time=ns,
                publish_time=ns,
                sequence=self.counts.get(topic, 0),
            )
        for sink in self.sinks:
            sink(topic, datatype, msg, ns)
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def step(self) -> None:
        """Record what is due at the current simulated time."""
        t = float(self.d.time)
        header = None
        for clock, job in self._jobs:
            if clock.due(t):
                header = header or {"stamp": _stamp(t), "frame_id": ""}
                job(header)

    def _joint_states(self, header: dict) -> None:
        if not self._watched("/joint_states"):
            return
        m, d = self.m, self.d
        js = self.src.joints
        q, v = m.jnt_qposadr[js], m.jnt_dofadr[js]
        msg = {
            "header": header,
            "name": self._joint_names,
            "position": d.qpos[q].tolist(),
            "velocity": d.qvel[v].tolist(),
            "effort": d.qfrc_actuator[v].tolist(),
        }
        self._write("/joint_states", "sensor_msgs/msg/JointState", msg)

    def _transform(
        self, header: dict, parent: str, child: str, p: np.ndarray, q: np.ndarray
    ) -> dict:
        return {
            "header": {"stamp": header["stamp"], "frame_id": parent},
            "child_frame_id": child,
            "transform": {"translation": _vec(p), "rotation": _xyzw(q)},
        }

    def _tf(self, header: dict) -> None:
        if not self._watched("/tf"):
            return
        m, d = self.m, self.d
        out = []
        for parent, child in self._edges:
            p, q = relative(d.xpos[parent], d.xquat[parent], d.xpos[child], d.xquat[child])
            out.append(self._transform(header, _body_name(m, parent), _body_name(m, child), p, q))
        for b in self.src.free:
            out.append(self._transform(header, "world", _body_name(m, b), d.xpos[b], d.xquat[b]))
        for a in self._attached:
            out.append(self._transform(header, _body_name(m, a.body), a.name, a.pos, a.quat))
        self._write("/tf", "tf2_msgs/msg/TFMessage", {"transforms": out})

    def _wrenches(self, header: dict) -> None:
        s = self.d.sensordata
        for w in self.src.wrenches:
            if not self._watched(w.topic):
                continue
            force, torque = s[w.force : w.force + 3], s[w.torque : w.torque + 3]
            if self.noise is not None:
                force, torque = self.noise.wrench(force, torque)
            msg = {
                "header": {"stamp": header["stamp"], "frame_id": self.site_frame(w.site)},
                "wrench": {"force": _vec(force), "torque": _vec(torque)},
            }
            self._write(w.topic, "geometry_msgs/msg/WrenchStamped", msg)

    def _imus(self, header: dict) -> None:
        s = self.d.sensordata
        for i in self.src.imus:
            if not self._watched(i.topic):
                continue
            msg = {
                "header": {"stamp": header["stamp"], "frame_id": self.site_frame(i.site)},
                "orientation": _xyzw(s[i.orientation : i.orientation + 4]),
                "orientation_covariance": [0.0] * 9,
                "angular_velocity": _vec(s[i.gyro : i.gyro + 3]),
                "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": _vec(s[i.accel : i.accel + 3]),
                "linear_acceleration_covariance": [0.0] * 9,
            }
            self._write(i.topic, "sensor_msgs/msg/Imu", msg)

    def _camera(self, cam: int) -> Camera:
        if cam not in self._cams:
            from .perception import Camera

            w, h = (int(x) for x in self.m.cam_resolution[cam])
            g = self.m.vis.global_  # the offscreen buffer must hold the camera's image
            g.offwidth, g.offheight = max(g.offwidth, w), max(g.offheight, h)
            self._cams[cam] = Camera(self.m, cam, noise=self.noise)
        return self._cams[cam]

    def _watched(self, prefix: str) -> bool:
        """Whether messages on the topics under ``prefix`` go anywhere: the file, or a
        sink that wants them (a sink without ``wants`` wants everything); a live stream
        nobody watches costs neither renders nor messages."""
        if self._writer is not None:
            return True
        return any(getattr(s, "wants", lambda _: True)(prefix) for s in self.sinks)

    def _images(self, header: dict) -> None:
        for role, cam in self.src.cameras.items():
            if not self._watched(f"/{role}_camera/"):
                continue  # a render nobody sees
            rgb, depth = self._camera(cam).rgbd(self.d)
            h, w = depth.shape
            head = {"stamp": header["stamp"], "frame_id": self.camera_frame(cam)}
            info = {**camera_info(self.m, cam, h, w), "header": head}
            # RealSense's convention: uint16 mm, 0 = no depth (here: nothing before the far plane)
            mm = np.where(depth < 0.999 * self._far, np.round(depth * 1000.0), 0.0)
            depth16 = np.clip(mm, 0, 65535).astype("<u2")
            base = f"/{role}_camera"
            for kind, encoding, pixels in (
                ("color", "rgb8", rgb),
                ("aligned_depth_to_color", "16UC1", depth16),
            ):
                image = {
                    "header": head,
                    "height": h,
                    "width": w,
                    "encoding": encoding,
                    "is_bigendian": 0,
                    "step": w * pixels.itemsize * (3 if pixels.ndim == 3 else 1),
                    "data": np.ascontiguousarray(pixels).tobytes(),
                }
                self._write(f"{base}/{kind}/image_raw", "sensor_msgs/msg/Image", image)
                self._write(f"{base}/{kind}/camera_info", "sensor_msgs/msg/CameraInfo", info)

    # ------------------------------------------------------------ end
    def _release(self) -> None:
        for c in self._cams.values():
            c.close()
        self._cams.clear()

    def close(self) -> None:
        """Finish the file and move it to ``path`` (given a reserved file: finish it; its
        owner renames it)."""
        if self._closed:
            return
        self._closed = True
        self._release()
        if self._file is None or self._slot is None:
            return
        try:
            self._writer.finish()
            self._file.close()
            if self._own_slot:
                self._slot.commit()
        except BaseException:
            self._file.close()
            if self._own_slot:
                self._slot.discard()
            raise

    def abort(self) -> None:
        """Stop without writing anything to ``path``."""
        if self._closed:
            return
        self._closed = True
        self._release()
        if self._file is None or self._slot is None:
            return
        self._file.close()
        if self._own_slot:
            self._slot.discard()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()
