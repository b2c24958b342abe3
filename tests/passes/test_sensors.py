"""Sensors pass: described cameras, IMUs, force-torque sensors, lidars and contact
sensors become MuJoCo cameras, sites and sensors that measure what the
description promises. Oracles: pinhole projection, gravity, statics and ray
geometry computed here from the URDF numbers (scipy rotations), never from the
pass's own placement.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from lxml import etree
from scipy.spatial.transform import Rotation

from urdf2mjcf.ir import Actuator, Model, Note
from urdf2mjcf.passes import collision, emit, inertia, meshes, parse, sensors, xacro
from urdf2mjcf.passes.sensors import SensorConfig

G = 9.81

# ---------------------------------------------------------------------------
# Building blocks
# ---------------------------------------------------------------------------


def box_link(name: str, size: str = "0.1 0.1 0.1", mass: float = 1.0, xyz: str = "0 0 0") -> str:
    return f"""
  <link name="{name}">
    <inertial><origin xyz="{xyz}"/><mass value="{mass}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
    <visual><origin xyz="{xyz}"/><geometry><box size="{size}"/></geometry></visual>
    <collision><origin xyz="{xyz}"/><geometry><box size="{size}"/></geometry></collision>
  </link>"""


def fixed(
    child: str, parent: str, xyz: str = "0 0 0", rpy: str = "0 0 0", name: str | None = None
) -> str:
    return f"""
  <joint name="{name or child + "_joint"}" type="fixed"><parent link="{parent}"/><child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/></joint>"""


def frame(name: str, parent: str, xyz: str = "0 0 0", rpy: str = "0 0 0") -> str:
    return fixed(name, parent, xyz, rpy) + f'\n  <link name="{name}"/>'


GROUNDED = (
    '<link name="world"/>' + fixed("base_link", "world") + box_link("base_link", "0.1 0.1 0.1")
)
"""A base fixed to the world at the origin."""


def pipeline(tmp_path: Path, body: str, *, actuators: tuple[Actuator, ...] = ()) -> Model:
    """The real passes up to (not including) the sensors pass."""
    path = tmp_path / "robot.urdf"
    path.write_text(f'<?xml version="1.0"?>\n<robot name="r">{body}\n</robot>\n')
    doc = xacro.run(path, xacro.XacroConfig(use_environment=False))
    model = meshes.run(parse.run(doc), meshes.MeshConfig())
    model = inertia.run(collision.run(model, collision.CollisionConfig()), inertia.InertiaConfig())
    return replace(model, actuators=actuators) if actuators else model


def convert(tmp_path: Path, body: str, cfg: SensorConfig | None = None, **kwargs) -> Model:
    return sensors.run(pipeline(tmp_path, body, **kwargs), cfg or SensorConfig())


def mjcf(model: Model, world: str = "", assets: str = "") -> tuple[str, dict[str, bytes]]:
    """The emitted MJCF with test objects added to the world body and assets."""
    res = emit.run(model, emit.EmitConfig())
    root = etree.fromstring(res.xml)
    if assets:
        asset = root.find("asset")
        if asset is None:
            asset = etree.Element("asset")
            root.insert(list(root).index(root.find("worldbody")), asset)
        asset.extend(etree.fromstring(f"<a>{assets}</a>"))
    root.find("worldbody").extend(etree.fromstring(f"<w>{world}</w>"))
    return etree.tostring(root, encoding="unicode"), dict(res.files)


def simulate(model: Model, world: str = "", assets: str = "", seconds: float = 0.0):
    xml, files = mjcf(model, world, assets)
    m = mujoco.MjModel.from_xml_string(xml, files)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    for _ in range(int(seconds / m.opt.timestep)):
        mujoco.mj_step(m, d)
    return m, d


def read(m: mujoco.MjModel, d: mujoco.MjData, name: str) -> np.ndarray:
    s = m.sensor(name)
    return d.sensordata[s.adr[0] : s.adr[0] + s.dim[0]].copy()


def rot(rpy) -> np.ndarray:
    """URDF/SDF rpy: fixed axes, R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return Rotation.from_euler("xyz", rpy).as_matrix()


def tf(xyz, rpy) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rot(rpy)
    t[:3, 3] = xyz
    return t


def vec(v) -> str:
    return " ".join(repr(float(x)) for x in v)


def notes(model: Model, kind: str | None = None) -> list[Note]:
    return [n for n in model.notes if kind is None or n.kind == kind]


def gazebo(reference: str | None, sensor: str) -> str:
    ref = f' reference="{reference}"' if reference is not None else ""
    return f"\n  <gazebo{ref}>{sensor}</gazebo>"


# ---------------------------------------------------------------------------
# Cameras
# ---------------------------------------------------------------------------

OPTICAL_CAMERA_LINK = ((0.1, -0.2, 1.0), (0.1, 0.4, -0.3))
OPTICAL_RPY = (-math.pi / 2, 0.0, -math.pi / 2)
OPTICAL_ROBOT = (
    GROUNDED
    + frame("camera_link", "base_link", "0.1 -0.2 1.0", "0.1 0.4 -0.3")
    + frame("camera_optical_frame", "camera_link", rpy=" ".join(map(repr, OPTICAL_RPY)))
    + gazebo(
        "camera_link",
        """<sensor type="depth" name="head_rgbd">
      <camera>
        <horizontal_fov>1.1</horizontal_fov>
        <image><width>320</width><height>240</height></image>
        <clip><near>0.05</near><far>8.0</far></clip>
      </camera>
      <plugin name="cam" filename="libgazebo_ros_camera.so"><frame_name>camera_optical_frame</frame_name></plugin>
    </sensor>""",
    )
)

GAZEBO_CAMERA_LINK = ((0.0, 0.3, 0.8), (0.0, 0.2, 0.5))
GAZEBO_SENSOR_POSE = ((0.05, 0.01, 0.02), (0.0, -0.1, 0.15))
GAZEBO_ROBOT = (
    GROUNDED
    + frame("camera_link", "base_link", "0 0.3 0.8", "0 0.2 0.5")
    + gazebo(
        "camera_link",
        """<sensor type="camera" name="front_camera">
      <pose>0.05 0.01 0.02 0 -0.1 0.15</pose>
      <camera>
        <horizontal_fov>1.3</horizontal_fov>
        <image><width>256</width><height>160</height></image>
      </camera>
    </sensor>""",
    )
)


def test_depth_camera_on_optical_frame_maps_resolution_fovy_depth_and_clip(tmp_path):
    model = convert(tmp_path, OPTICAL_ROBOT)
    (cam,) = model.cameras
    assert cam.name == cam.body == "camera_optical_frame"
    assert cam.resolution == (320, 240)
    assert cam.fovy == pytest.approx(
        math.degrees(2 * math.atan(math.tan(1.1 / 2) * 240 / 320)), rel=1e-12
    )
    assert cam.depth and (cam.near, cam.far) == (0.05, 8.0)
    assert any(n.kind == "info" and "head_rgbd" in n.element for n in model.notes)
    m, _ = simulate(model)
    mc = m.camera("camera_optical_frame")
    assert list(m.cam_resolution[mc.id]) == [320, 240]
    assert mc.fovy[0] == pytest.approx(cam.fovy)
    assert m.vis.global_.offwidth >= 320 and m.vis.global_.offheight >= 240


def test_plain_camera_in_gazebo_convention_sits_on_the_reference_link(tmp_path):
    model = convert(tmp_path, GAZEBO_ROBOT)
    (cam,) = model.cameras
    assert (cam.name, cam.body, cam.resolution, cam.depth) == (
        "camera_link",
        "camera_link",
        (256, 160),
        False,
    )
    assert cam.pos == pytest.approx(GAZEBO_SENSOR_POSE[0])


def test_camera_on_a_frame_named_optical_frame_needs_no_plugin(tmp_path):
    body = (
        GROUNDED
        + frame("eye_optical_frame", "base_link", "0 0 1", "0.3 0.2 0.1")
        + gazebo(
            "eye_optical_frame",
            '<sensor type="camera" name="eye"><camera><image><width>64</width><height>48</height></image></camera></sensor>',
        )
    )
    (cam,) = convert(tmp_path, body).cameras
    assert cam.body == "eye_optical_frame"
    assert cam.quat == pytest.approx((0.0, 1.0, 0.0, 0.0)), "optical frame turned 180 deg about x"
    assert cam.fovy == pytest.approx(math.degrees(2 * math.atan(math.tan(1.047 / 2) * 48 / 64))), (
        "SDF default hfov"
    )


_RENDER = r"""
import sys
import numpy as np
import mujoco
xml, camera, out = sys.argv[1:4]
m = mujoco.MjModel.from_xml_path(xml)
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
w, h = m.cam_resolution[m.camera(camera).id]
renderer = mujoco.Renderer(m, int(h), int(w))
with renderer:
    renderer.update_scene(d, camera=camera)
    rgb = renderer.render().copy()
    renderer.enable_depth_rendering()
    renderer.update_scene(d, camera=camera)
    depth = renderer.render().copy()
np.savez(out, rgb=rgb, depth=depth)
"""

MARKERS = """
  <material name="red" rgba="1 0 0 1" emission="1" specular="0" shininess="0"/>
  <material name="green" rgba="0 1 0 1" emission="1" specular="0" shininess="0"/>"""
RADIUS = 0.025


def render(
    tmp_path: Path, model: Model, camera: str, targets: dict[str, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """RGB and depth images of ``camera`` with a small sphere per colour at world points."""
    world = "".join(
        f'<geom name="{c}" type="sphere" size="{RADIUS}" pos="{vec(p)}" material="{c}" contype="0" conaffinity="0"/>'
        for c, p in targets.items()
    )
    xml, files = mjcf(model, world, MARKERS)
    out = tmp_path / "render"
    out.mkdir()
    (out / "robot.xml").write_text(xml)
    for name, data in files.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_bytes(data)
    # MuJoCo picks its OpenGL backend at import: render in a fresh interpreter.
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    done = subprocess.run(
        [sys.executable, "-c", _RENDER, str(out / "robot.xml"), camera, str(out / "img.npz")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    images = np.load(out / "img.npz")
    return images["rgb"], images["depth"]


def centroid(rgb: np.ndarray, channel: int) -> tuple[float, float]:
    """(u, v) of a colour blob in continuous pixel coordinates (pixel i spans [i, i+1))."""
    c = rgb.astype(float)
    others = [k for k in range(3) if k != channel]
    mask = (
        (c[..., channel] > 100)
        & (c[..., channel] > 2 * c[..., others[0]])
        & (c[..., channel] > 2 * c[..., others[1]])
    )
    assert mask.sum() >= 9, "the marker is visible"
    v, u = np.nonzero(mask)
    return float(u.mean() + 0.5), float(v.mean() + 0.5)


def check_projection(rgb, depth, fovy_deg, targets_optical: dict[str, np.ndarray], size):
    width, height = size
    assert rgb.shape == (height, width, 3) and depth.shape == (height, width)
    f = (height / 2) / math.tan(math.radians(fovy_deg) / 2)
    for colour, channel in (("red", 0), ("green", 1)):
        x, y, z = targets_optical[colour]
        expected = (f * x / z + width / 2, f * y / z + height / 2)
        assert centroid(rgb, channel) == pytest.approx(expected, abs=2.0), colour
        u, v = expected
        dist = float(np.linalg.norm(targets_optical[colour]))
        # the centre ray meets the sphere at |p| - r; depth images hold the z component
        assert depth[int(v), int(u)] == pytest.approx((dist - RADIUS) * z / dist, abs=0.01), colour


@pytest.mark.usefixtures("gl_context")  # skips only where no GL context can be made
def test_camera_on_optical_frame_renders_markers_where_pinhole_intrinsics_predict(tmp_path):
    model = convert(tmp_path, OPTICAL_ROBOT)
    (cam,) = model.cameras
    world_optical = tf(*OPTICAL_CAMERA_LINK) @ tf((0, 0, 0), OPTICAL_RPY)
    targets = {
        "red": np.array([0.15, -0.08, 1.3]),
        "green": np.array([-0.2, 0.1, 1.6]),
    }  # x right, y down
    world = {c: world_optical[:3, :3] @ p + world_optical[:3, 3] for c, p in targets.items()}
    rgb, depth = render(tmp_path, model, cam.name, world)
    check_projection(rgb, depth, cam.fovy, targets, cam.resolution)


@pytest.mark.usefixtures("gl_context")  # skips only where no GL context can be made
def test_camera_in_gazebo_convention_renders_markers_where_pinhole_intrinsics_predict(tmp_path):
    model = convert(tmp_path, GAZEBO_ROBOT)
    (cam,) = model.cameras
    world_sensor = tf(*GAZEBO_CAMERA_LINK) @ tf(*GAZEBO_SENSOR_POSE)
    gazebo_points = {
        "red": np.array([1.4, 0.12, -0.05]),
        "green": np.array([1.8, -0.25, 0.2]),
    }  # x fwd, y left
    world = {c: world_sensor[:3, :3] @ p + world_sensor[:3, 3] for c, p in gazebo_points.items()}
    optical = {c: np.array([-p[1], -p[2], p[0]]) for c, p in gazebo_points.items()}
    rgb, depth = render(tmp_path, model, cam.name, world)
    check_projection(rgb, depth, cam.fovy, optical, cam.resolution)


def test_optical_frame_away_from_the_gazebo_sensor_pose_is_warned_about(tmp_path):
    body = OPTICAL_ROBOT.replace("<camera>", "<pose>0 0 0 0 0.5 0</pose><camera>", 1)
    model = convert(tmp_path, body)
    assert model.cameras[0].body == "camera_optical_frame"
    assert any(n.kind == "warning" and "camera_optical_frame" in n.message for n in model.notes)
    assert not notes(convert(tmp_path, OPTICAL_ROBOT), "warning"), (
        "the consistent one is not warned about"
    )


def test_optical_frame_that_is_not_a_link_falls_back_to_gazebo_convention(tmp_path):
    body = OPTICAL_ROBOT.replace("<frame_name>camera_optical_frame", "<frame_name>missing_frame")
    model = convert(tmp_path, body)
    assert model.cameras[0].body == "camera_link"
    assert model.cameras[0].quat == pytest.approx((0.5, 0.5, -0.5, -0.5))
    assert any(n.kind == "warning" and "missing_frame" in n.message for n in model.notes)


# ---------------------------------------------------------------------------
# IMU
# ---------------------------------------------------------------------------


IMU_NOISE = """<imu>
        <angular_velocity><x><noise type="gaussian"><mean>0</mean><stddev>0.0002</stddev></noise></x>
          <z><noise type="gaussian"><mean>0</mean><stddev>0.0003</stddev></noise></z></angular_velocity>
        <linear_acceleration><y><noise type="gaussian"><stddev>0.017</stddev></noise></y></linear_acceleration>
      </imu>"""


@pytest.mark.parametrize(
    ("link_rpy", "pose"),
    [
        ((0, 0, 0), None),
        ((0.3, -0.5, 0.7), None),
        ((0.3, -0.5, 0.7), ((0.01, 0.02, 0.03), (1.2, 0.4, -2.0))),
    ],
    ids=["level", "rotated-frame", "rotated-frame-and-pose"],
)
def test_imu_at_rest_reads_gravity_upward(tmp_path, link_rpy, pose):
    pose_xml = f"<pose>{' '.join(map(repr, pose[0] + pose[1]))}</pose>" if pose else ""
    body = (
        GROUNDED
        + frame("imu_link", "base_link", "0.05 0.05 0.05", " ".join(map(repr, link_rpy)))
        + gazebo("imu_link", f'<sensor type="imu" name="base_imu">{pose_xml}{IMU_NOISE}</sensor>')
    )
    model = convert(tmp_path, body)
    site = "imu_link" if pose is None else "imu_link_imu"
    assert [s.name for s in model.sites] == [site]
    by_name = {s.name: s for s in model.sensors}
    assert [s.name for s in model.sensors] == [
        "imu_link_accelerometer",
        "imu_link_gyro",
        "imu_link_orientation",
    ]
    assert by_name["imu_link_accelerometer"].noise == 0.017
    assert by_name["imu_link_gyro"].noise == 0.0003
    assert (by_name["imu_link_orientation"].objtype, by_name["imu_link_orientation"].objname) == (
        "site",
        site,
    )

    m, d = simulate(model, seconds=0.05)
    r_sensor = rot(link_rpy) @ (rot(pose[1]) if pose else np.eye(3))
    acc = read(m, d, "imu_link_accelerometer")
    np.testing.assert_allclose(r_sensor @ acc, [0, 0, G], atol=0.01 * G)
    np.testing.assert_allclose(acc, r_sensor.T @ [0, 0, G], atol=0.01 * G)
    assert np.linalg.norm(read(m, d, "imu_link_gyro")) < 1e-9
    w, x, y, z = read(m, d, "imu_link_orientation")
    expected = Rotation.from_matrix(r_sensor).as_quat()  # x y z w
    assert abs(np.dot([x, y, z, w], expected)) == pytest.approx(1.0, abs=1e-9)
    assert m.sensor("imu_link_accelerometer").noise[0] == pytest.approx(0.017)


# ---------------------------------------------------------------------------
# Force-torque
# ---------------------------------------------------------------------------

FT_FRAME = ((0.0, 0.0, -0.1), (0.3, -0.2, 0.4))
PAYLOAD = ((0.05, 0.0, -0.05), (0.0, 0.5, 0.0))
PAYLOAD_COM = (0.1, 0.0, 0.0)
PAYLOAD_MASS = 2.0
FT_ROBOT = (
    GROUNDED
    + frame("ft_frame", "base_link", "0 0 -0.1", "0.3 -0.2 0.4")
    + fixed("payload", "ft_frame", "0.05 0 -0.05", "0 0.5 0")
    + box_link("payload", "0.04 0.04 0.04", PAYLOAD_MASS, "0.1 0 0")
)
ROS2_FT = """
  <ros2_control name="system" type="system">
    <hardware><plugin>mujoco_ros2_control/MujocoSystem</plugin></hardware>
    <sensor name="wrist_ft">
      <state_interface name="force.x"/><state_interface name="force.y"/><state_interface name="force.z"/>
      <state_interface name="torque.x"/><state_interface name="torque.y"/><state_interface name="torque.z"/>
      <param name="frame_id">ft_frame</param>
    </sensor>
  </ros2_control>"""


def expected_wrench_world() -> tuple[np.ndarray, np.ndarray]:
    """What holds the payload: force (0, 0, m g) and torque (c - s) x F about the sensor."""
    t_ft = tf(*FT_FRAME)
    com = t_ft @ tf(*PAYLOAD) @ np.array([*PAYLOAD_COM, 1.0])
    force = np.array([0.0, 0.0, PAYLOAD_MASS * G])
    return force, np.cross(com[:3] - t_ft[:3, 3], force)


def test_ros2_control_force_torque_sensor_reads_the_weight_hanging_below(tmp_path):
    model = convert(tmp_path, FT_ROBOT + ROS2_FT)
    assert [s.name for s in model.sites] == ["ft_frame"]
    assert [(s.name, s.type, s.site) for s in model.sensors] == [
        ("ft_frame_force", "force", "ft_frame"),
        ("ft_frame_torque", "torque", "ft_frame"),
    ]
    m, d = simulate(model)
    force, torque = expected_wrench_world()
    r = rot(FT_FRAME[1])
    measured = read(m, d, "ft_frame_force")
    assert np.linalg.norm(measured) == pytest.approx(PAYLOAD_MASS * G, rel=0.01)
    np.testing.assert_allclose(measured, r.T @ force, atol=0.01 * PAYLOAD_MASS * G)
    np.testing.assert_allclose(read(m, d, "ft_frame_torque"), r.T @ torque, atol=1e-3)


@pytest.mark.parametrize("gz_frame", ["child", "parent", "sensor"])
def test_gazebo_force_torque_on_a_joint_reads_in_the_described_frame(tmp_path, gz_frame):
    sensor = f"""<sensor name="wrist_ft" type="force_torque">
      <pose>0.5 0.5 0.5 0 0 1.0</pose>
      <force_torque><frame>{gz_frame}</frame><measure_direction>child_to_parent</measure_direction></force_torque>
    </sensor>"""
    model = convert(tmp_path, FT_ROBOT + gazebo("ft_frame_joint", sensor))
    site = "ft_frame" if gz_frame == "child" else "ft_frame_ft"
    assert [s.name for s in model.sites] == [site]
    assert model.sites[0].pos == (0.0, 0.0, 0.0), "at the joint frame, whatever the pose"
    assert any("negate" in n.message for n in notes(model, "info")), (
        "child_to_parent is the negation"
    )
    m, d = simulate(model)
    axes = {
        "child": rot(FT_FRAME[1]),
        "parent": np.eye(3),
        "sensor": rot(FT_FRAME[1]) @ rot((0, 0, 1.0)),
    }[gz_frame]
    force, torque = expected_wrench_world()
    np.testing.assert_allclose(
        read(m, d, "ft_frame_force"), axes.T @ force, atol=0.01 * PAYLOAD_MASS * G
    )
    np.testing.assert_allclose(read(m, d, "ft_frame_torque"), axes.T @ torque, atol=1e-3)


def test_ros1_ft_sensor_plugin_on_a_joint_maps_to_the_child_link(tmp_path):
    plugin = '<plugin name="ft" filename="libgazebo_ros_ft_sensor.so"><jointName>ft_frame_joint</jointName><gaussianNoise>0.01</gaussianNoise></plugin>'
    model = convert(tmp_path, FT_ROBOT + gazebo(None, plugin) + ROS2_FT)
    assert [(s.name, s.noise) for s in model.sensors] == [
        ("ft_frame_force", 0.01),
        ("ft_frame_torque", 0.01),
    ]
    assert any("not duplicated" in n.message for n in model.notes), (
        "ros2_control repeats the same sensor"
    )


# ---------------------------------------------------------------------------
# Lidar
# ---------------------------------------------------------------------------

LIDAR_AT = (0.1, 0.2, 0.3)
LIDAR_POSE_Z = 0.05


def lidar_robot(
    yaw: float = 0.0,
    samples: int = 181,
    vertical: str = "",
    sensor_type: str = "ray",
    element: str = "ray",
) -> str:
    scan = f"""<{element}>
        <scan><horizontal><samples>{samples}</samples><resolution>1</resolution><min_angle>{-math.pi / 2!r}</min_angle><max_angle>{math.pi / 2!r}</max_angle></horizontal>{vertical}</scan>
        <range><min>0.05</min><max>10.0</max><resolution>0.01</resolution></range>
        <noise><type>gaussian</type><mean>0</mean><stddev>0.01</stddev></noise>
      </{element}>"""
    return (
        GROUNDED
        + frame("laser_link", "base_link", " ".join(map(repr, LIDAR_AT)), f"0 0 {yaw!r}")
        + gazebo(
            "laser_link",
            f'<sensor type="{sensor_type}" name="scan"><pose>0 0 {LIDAR_POSE_Z} 0 0 0</pose>{scan}</sensor>',
        )
    )


@pytest.mark.parametrize("yaw", [0.0, 0.4])
def test_2d_lidar_reads_the_distance_to_a_wall_head_on_and_obliquely(tmp_path, yaw):
    n = 181
    model = convert(tmp_path, lidar_robot(yaw))
    rays = [s for s in model.sensors if s.type == "rangefinder"]
    assert [s.name for s in rays] == [f"laser_link_ray_{k:03d}" for k in range(n)]
    assert all(s.site == s.name and s.cutoff == 10.0 and s.noise == 0.01 for s in rays)
    wall_x = 2.5
    wall = f'<geom name="wall" type="box" pos="{wall_x + 0.05} 0 0.5" size="0.05 20 1"/>'
    m, d = simulate(model, wall)
    d_wall = wall_x - LIDAR_AT[0]
    angles = np.linspace(-math.pi / 2, math.pi / 2, n)
    head_on = int(np.argmin(np.abs(angles + yaw)))
    if yaw == 0.0:
        assert head_on == 90
        assert read(m, d, "laser_link_ray_090")[0] == pytest.approx(d_wall, abs=0.01)
    for k in (head_on, head_on - 30, head_on + 25, head_on + 60, 10):
        expected = min(d_wall / math.cos(angles[k] + yaw), 10.0)  # clamped at <range><max>
        assert read(m, d, f"laser_link_ray_{k:03d}")[0] == pytest.approx(expected, abs=0.01), k
    away = n - 1 if yaw > 0 else 0
    assert read(m, d, f"laser_link_ray_{away:03d}")[0] == -1, (
        "a ray parallel to the wall sees nothing"
    )


def test_lidar_beyond_its_range_reads_the_range_limit(tmp_path):
    model = convert(tmp_path, lidar_robot())
    m, d = simulate(model, '<geom type="box" pos="20 0 0.5" size="0.05 20 1"/>')
    assert read(m, d, "laser_link_ray_090")[0] == pytest.approx(10.0)


def test_3d_lidar_rows_pitch_up_and_down_like_gazebo(tmp_path):
    vertical = "<vertical><samples>3</samples><min_angle>-0.3</min_angle><max_angle>0.3</max_angle></vertical>"
    body = lidar_robot(samples=5, vertical=vertical, sensor_type="gpu_lidar", element="lidar")
    body = body.replace(
        f"{-math.pi / 2!r}</min_angle><max_angle>{math.pi / 2!r}", "-0.4</min_angle><max_angle>0.4"
    )
    model = convert(tmp_path, body)
    names = [s.name for s in model.sensors]
    assert names == [f"laser_link_ray_{k:02d}" for k in range(15)], (
        "width of the ray count, rows outer"
    )
    m, d = simulate(model, '<geom type="plane" size="5 5 0.1"/>')
    height = LIDAR_AT[2] + LIDAR_POSE_Z
    for row, pitch in enumerate((-0.3, 0.0, 0.3)):
        for col, yaw in enumerate(np.linspace(-0.4, 0.4, 5)):
            k = row * 5 + col
            site = m.site(f"laser_link_ray_{k:02d}").id
            direction = [
                math.cos(pitch) * math.cos(yaw),
                math.cos(pitch) * math.sin(yaw),
                math.sin(pitch),
            ]
            np.testing.assert_allclose(d.site_xmat[site].reshape(3, 3)[:, 2], direction, atol=1e-12)
            reading = read(m, d, f"laser_link_ray_{k:02d}")[0]
            if pitch < 0:
                assert reading == pytest.approx(height / math.sin(-pitch), abs=0.01)
            else:
                assert reading == -1


def test_large_lidar_fan_compiles_and_is_noted(tmp_path):
    model = convert(tmp_path, lidar_robot(samples=720))
    assert sum(s.type == "rangefinder" for s in model.sensors) == 720
    assert model.sensors[-1].name == "laser_link_ray_719"
    assert any("720 rays" in n.message for n in model.notes)
    m, _ = simulate(model)
    assert m.nsensor == 720


# ---------------------------------------------------------------------------
# Contact
# ---------------------------------------------------------------------------

CONTACT = gazebo(
    "pad",
    '<sensor name="bumper" type="contact"><contact><collision>pad_collision</collision></contact></sensor>',
)


def test_contact_sensor_reads_the_weight_of_a_resting_object_and_zero_without(tmp_path):
    body = (
        GROUNDED + fixed("pad", "base_link", "0 0 0.1") + box_link("pad", "0.3 0.3 0.02") + CONTACT
    )
    model = convert(tmp_path, body)
    (site,) = model.sites
    assert (site.name, site.body, site.type) == ("pad_touch", "pad", "box")
    assert site.size == pytest.approx((0.155, 0.155, 0.015)), "collision box + 5 mm"
    assert [(s.name, s.type, s.site) for s in model.sensors] == [
        ("pad_touch", "touch", "pad_touch")
    ]
    obj = '<body name="obj" pos="0 0 0.135"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1e-3 1e-3 1e-3"/><geom type="box" size="0.05 0.05 0.02"/></body>'
    m, d = simulate(model, obj, seconds=1.0)
    assert read(m, d, "pad_touch")[0] == pytest.approx(G, rel=0.05)
    m, d = simulate(model, seconds=1.0)
    assert read(m, d, "pad_touch")[0] == 0.0


def test_contact_zone_of_a_mesh_link_encloses_its_vertices(tmp_path):
    mesh = trimesh.creation.box((0.3, 0.2, 0.04))
    mesh.apply_translation((0.02, 0.0, 0.01))
    mesh.export(tmp_path / "pad.stl")
    origin = ((0.0, 0.01, 0.0), (0.0, 0.0, math.pi / 2))
    pad = f"""
  <link name="pad">
    <inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
    <collision><origin xyz="0 0.01 0" rpy="0 0 {math.pi / 2!r}"/><geometry><mesh filename="pad.stl"/></geometry></collision>
  </link>"""
    model = convert(tmp_path, GROUNDED + fixed("pad", "base_link", "0 0 0.1") + pad + CONTACT)
    (site,) = model.sites
    corners = mesh.vertices @ rot(origin[1]).T + origin[0]
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    assert site.pos == pytest.approx((lo + hi) / 2, abs=1e-6)
    assert site.size == pytest.approx((hi - lo) / 2 + 0.005, abs=1e-6)
    obj = '<body name="obj" pos="0.01 0.03 0.16"><freejoint/><inertial pos="0 0 0" mass="0.5" diaginertia="2e-4 2e-4 2e-4"/><geom type="sphere" size="0.03"/></body>'
    m, d = simulate(model, obj, seconds=1.0)
    assert read(m, d, "pad_touch")[0] == pytest.approx(0.5 * G, rel=0.05)


def test_contact_sensor_on_a_link_without_collision_is_skipped_with_a_warning(tmp_path):
    model = convert(tmp_path, GROUNDED + frame("pad", "base_link") + CONTACT)
    assert not model.sensors and not model.sites
    assert any(n.kind == "warning" and "collision" in n.message for n in model.notes)


# ---------------------------------------------------------------------------
# Spellings, deduplication, names, joints
# ---------------------------------------------------------------------------


def test_gz_sim_spellings_map_like_classic(tmp_path):
    body = (
        GROUNDED
        + frame("cam_link", "base_link", "0 0 1")
        + frame("cam_optical", "cam_link", rpy=" ".join(map(repr, OPTICAL_RPY)))
        + frame("imu_link", "base_link")
        + gazebo(
            "cam_link",
            """<sensor name="rgbd" type="rgbd_camera">
      <camera><horizontal_fov>1.5</horizontal_fov><image><width>160</width><height>120</height></image>
        <depth_camera><clip><near>0.2</near><far>5</far></clip></depth_camera>
        <optical_frame_id>cam_optical</optical_frame_id></camera>
    </sensor>""",
        )
        + gazebo(
            "imu_link",
            f'<sensor name="imu" type="imu"><pose degrees="true">0 0 0 0 0 90</pose>{IMU_NOISE}</sensor>',
        )
    )
    model = convert(tmp_path, body)
    (cam,) = model.cameras
    assert (cam.body, cam.depth, cam.near, cam.far) == ("cam_optical", True, 0.2, 5.0)
    (site,) = model.sites
    assert site.quat == pytest.approx((math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)))
    assert {s.name for s in model.sensors} == {
        "imu_link_accelerometer",
        "imu_link_gyro",
        "imu_link_orientation",
    }


def test_ros1_spellings_frame_name_and_imu_plugin(tmp_path):
    body = (
        GROUNDED
        + frame("kinect_link", "base_link", "0 0 1")
        + frame("kinect_depth_optical_frame", "kinect_link", rpy=" ".join(map(repr, OPTICAL_RPY)))
        + frame("imu_link", "base_link")
        + gazebo(
            "kinect_link",
            """<sensor type="depth" name="kinect"><camera><image><width>64</width><height>48</height></image></camera>
      <plugin name="kinect_controller" filename="libgazebo_ros_openni_kinect.so"><frameName>kinect_depth_optical_frame</frameName></plugin></sensor>""",
        )
        + gazebo(
            None,
            '<plugin name="imu" filename="libgazebo_ros_imu.so"><bodyName>imu_link</bodyName><gaussianNoise>0.005</gaussianNoise></plugin>',
        )
    )
    model = convert(tmp_path, body)
    assert model.cameras[0].body == "kinect_depth_optical_frame"
    assert {(s.name, s.noise) for s in model.sensors if s.type in ("accelerometer", "gyro")} == {
        ("imu_link_accelerometer", 0.005),
        ("imu_link_gyro", 0.005),
    }


ROS2_IMU = """
  <ros2_control name="system" type="system">
    <hardware><plugin>x</plugin></hardware>
    <sensor name="{name}">
      <state_interface name="orientation.x"/><state_interface name="angular_velocity.x"/><state_interface name="linear_acceleration.x"/>
      {param}
    </sensor>
  </ros2_control>"""


def test_ros2_control_imu_is_not_duplicated_when_a_gazebo_block_made_it(tmp_path):
    body = (
        GROUNDED
        + frame("imu_link", "base_link")
        + gazebo("imu_link", '<sensor type="imu" name="imu"/>')
        + ROS2_IMU.format(name="imu_sensor", param='<param name="frame_id">imu_link</param>')
    )
    model = convert(tmp_path, body)
    assert [s.name for s in model.sensors] == [
        "imu_link_accelerometer",
        "imu_link_gyro",
        "imu_link_orientation",
    ]
    assert any(n.kind == "info" and "not duplicated" in n.message for n in model.notes)


def test_ros2_control_sensor_frame_falls_back_to_its_name_then_is_skipped(tmp_path):
    body = GROUNDED + frame("imu_link", "base_link") + ROS2_IMU.format(name="imu_link", param="")
    assert [s.name for s in convert(tmp_path, body).sensors][:1] == ["imu_link_accelerometer"]
    model = convert(tmp_path, GROUNDED + ROS2_IMU.format(name="imu_sensor", param=""))
    assert not model.sensors
    assert any(n.kind == "warning" and "frame_id" in n.message for n in model.notes)


def test_missing_references_are_warned_about_and_skipped(tmp_path):
    body = (
        GROUNDED
        + gazebo("no_such_link", '<sensor type="imu" name="imu"/>')
        + gazebo(None, '<sensor type="imu" name="robot_imu"/>')
        + gazebo("base_link", '<sensor type="gps" name="gps"/>')
    )
    model = convert(tmp_path, body)
    assert not model.sensors and not model.sites and not model.cameras
    warnings = {n.element: n.message for n in notes(model, "warning")}
    assert "no_such_link" in warnings["gazebo sensor 'imu'"]
    assert "reference" in warnings["gazebo sensor 'robot_imu'"]
    assert any("gps" in n.message for n in notes(model, "info"))
    simulate(model)


def test_colliding_names_get_numeric_suffixes_and_notes(tmp_path):
    body = (
        GROUNDED
        + frame("imu_link", "base_link")
        + frame("laser_ray_0", "base_link")  # a frame whose site name a ray would take
        + frame("laser", "base_link")
        + gazebo("imu_link", '<sensor type="imu" name="a"/><sensor type="imu" name="b"/>')
        + gazebo(
            "laser",
            '<sensor type="ray" name="l"><ray><scan><horizontal><samples>2</samples><min_angle>0</min_angle><max_angle>1</max_angle></horizontal></scan></ray></sensor>',
        )
    )
    model = convert(tmp_path, body)
    names = [s.name for s in model.sensors]
    assert names[:6] == [
        "imu_link_accelerometer",
        "imu_link_gyro",
        "imu_link_orientation",
        "imu_link_accelerometer_2",
        "imu_link_gyro_2",
        "imu_link_orientation_2",
    ]
    assert names[6:] == ["laser_ray_0_2", "laser_ray_1"]
    assert [s.name for s in model.sites] == ["imu_link", "laser_ray_0_2", "laser_ray_1"], (
        "identical IMU sites shared"
    )
    assert sum("taken" in n.message for n in model.notes) == 4
    m, _ = simulate(model)
    assert m.site("laser_ray_0").bodyid[0] == m.body("laser_ray_0").id, (
        "the frame keeps its own site"
    )


def test_actuated_joints_get_position_and_velocity_sensors_after_frame_sensors(tmp_path):
    body = (
        GROUNDED
        + box_link("arm")
        + box_link("slider")
        + """
  <joint name="shoulder" type="revolute"><parent link="base_link"/><child link="arm"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="arm"/><child link="slider"/><axis xyz="1 0 0"/><limit lower="0" upper="0.1" effort="10" velocity="1"/></joint>"""
        + frame("imu_link", "base_link")
        + gazebo("imu_link", '<sensor type="imu" name="imu"/>')
    )
    actuators = (
        Actuator("slide", "slide", "position", kp=100.0),
        Actuator("shoulder", "shoulder", "motor"),
    )
    model = convert(tmp_path, body, actuators=actuators)
    assert [(s.name, s.type, s.joint) for s in model.sensors[3:]] == [
        ("slide_pos", "jointpos", "slide"),
        ("slide_vel", "jointvel", "slide"),
        ("shoulder_pos", "jointpos", "shoulder"),
        ("shoulder_vel", "jointvel", "shoulder"),
    ]
    xml, files = mjcf(model)
    m = mujoco.MjModel.from_xml_string(xml, files)
    d = mujoco.MjData(m)
    d.qpos[m.joint("shoulder").qposadr[0]], d.qpos[m.joint("slide").qposadr[0]] = 0.3, 0.07
    d.qvel[m.joint("shoulder").dofadr[0]], d.qvel[m.joint("slide").dofadr[0]] = -0.2, 0.05
    mujoco.mj_forward(m, d)
    assert [
        read(m, d, n)[0] for n in ("shoulder_pos", "shoulder_vel", "slide_pos", "slide_vel")
    ] == pytest.approx([0.3, -0.2, 0.07, 0.05])
    assert not convert(
        tmp_path, body, SensorConfig(joint_sensors=False), actuators=actuators
    ).sensors[3:]


def test_robot_without_sensor_tags_is_unchanged(tmp_path):
    before = pipeline(tmp_path, GROUNDED + frame("tool0", "base_link", "0 0 0.2"))
    after = sensors.run(before, SensorConfig())
    assert after is before
    assert emit.run(after, emit.EmitConfig()).xml == emit.run(before, emit.EmitConfig()).xml


def test_links_carrying_body_dependent_sensors_are_listed_for_emit(tmp_path):
    model = convert(
        tmp_path, lidar_robot(samples=3) + gazebo("base_link", '<sensor type="imu" name="i"/>')
    )
    assert model.sensor_bodies() == {"laser_link"}, "an IMU does not care which body it is on"
