"""A robot described for ROS 2 converts with one command into a model whose
actuators, sensors and cameras exist with the described names and
parameters, and which behaves like the description in simulation.

The robot (tests/data/sim_robot): a 4-DoF arm with position-controlled
joints, a two-finger gripper whose right finger mimics the left, a wrist
force-torque sensor (ros2_control), an RGBD camera on an optical frame, an
IMU and a 2D lidar (Gazebo sensor blocks).
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

SOURCE = Path(__file__).parent / "data" / "sim_robot" / "urdf" / "sim_arm.urdf.xacro"
ARM = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_joint"]
ACTUATED = ARM + ["finger_left_joint"]
LIDAR_SAMPLES = 181


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    """One command, as a user types it."""
    out = tmp_path_factory.mktemp("sim_arm") / "robot.xml"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "urdf2mjcf",
            str(SOURCE),
            "-o",
            str(out),
            "--gravcomp",
            "--no-ros-env",
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    return out


def _model(path: Path, extra=None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    spec = mujoco.MjSpec.from_file(str(path))
    if extra is not None:
        extra(spec)
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    d.ctrl[:] = [d.qpos[m.joint(m.actuator(i).trnid[0]).qposadr[0]] for i in range(m.nu)]
    mujoco.mj_forward(m, d)
    return m, d


def _sensor(m, d, name: str) -> np.ndarray:
    s = m.sensor(name)
    return d.sensordata[s.adr[0] : s.adr[0] + s.dim[0]].copy()


def test_actuators_sensors_and_cameras_exist_with_described_names_and_parameters(converted):
    m = mujoco.MjModel.from_xml_path(str(converted))
    actuators = {m.actuator(i).name: m.actuator(i) for i in range(m.nu)}
    assert sorted(actuators) == sorted(ACTUATED), "the mimic finger has no actuator of its own"
    for name in ACTUATED:
        a, j = actuators[name], m.joint(name)
        assert a.trnid[0] == j.id
        assert a.biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE, "position servo"
        np.testing.assert_allclose(a.ctrlrange, j.range)
    np.testing.assert_allclose(actuators["elbow_joint"].forcerange, [-80, 80])
    np.testing.assert_allclose(actuators["finger_left_joint"].forcerange, [-100, 100])
    for frame in ("ft_frame",):
        assert m.sensor(f"{frame}_force").type[0] == mujoco.mjtSensor.mjSENS_FORCE
        assert m.sensor(f"{frame}_torque").type[0] == mujoco.mjtSensor.mjSENS_TORQUE
    assert m.sensor("imu_link_accelerometer").type[0] == mujoco.mjtSensor.mjSENS_ACCELEROMETER
    assert m.sensor("imu_link_gyro").type[0] == mujoco.mjtSensor.mjSENS_GYRO
    assert m.sensor("imu_link_orientation").type[0] == mujoco.mjtSensor.mjSENS_FRAMEQUAT
    rays = [
        m.sensor(i).name
        for i in range(m.nsensor)
        if m.sensor(i).type[0] == mujoco.mjtSensor.mjSENS_RANGEFINDER
    ]
    assert len(rays) == LIDAR_SAMPLES and all(r.startswith("laser_link_ray_") for r in rays)
    for joint in ACTUATED:
        assert m.sensor(f"{joint}_pos").type[0] == mujoco.mjtSensor.mjSENS_JOINTPOS
        assert m.sensor(f"{joint}_vel").type[0] == mujoco.mjtSensor.mjSENS_JOINTVEL
    cam = m.camera("camera_optical_frame")
    np.testing.assert_array_equal(m.cam_resolution[cam.id], [320, 240])
    expected_fovy = math.degrees(2 * math.atan(math.tan(1.2 / 2) * 240 / 320))
    assert cam.fovy[0] == pytest.approx(expected_fovy, rel=1e-9)
    for frame in ("tool0", "camera_optical_frame", "ft_frame", "imu_link"):
        assert m.site(frame).id >= 0, "frames are kept as sites"


def test_home_keyframe_is_the_described_initial_pose_and_servos_hold_it(converted):
    m = mujoco.MjModel.from_xml_path(str(converted))
    key = m.key("home")
    assert key.qpos[m.joint("shoulder_lift_joint").qposadr[0]] == pytest.approx(0.3)
    assert key.qpos[m.joint("elbow_joint").qposadr[0]] == pytest.approx(-0.6)
    assert key.ctrl[m.actuator("shoulder_lift_joint").id] == pytest.approx(0.3)
    assert key.ctrl[m.actuator("elbow_joint").id] == pytest.approx(-0.6)


def test_arm_holds_home_pose_under_gravity_within_1mm_for_5s(converted):
    m, d = _model(converted)
    tool = m.site("tool0").id
    start = d.site_xpos[tool].copy()
    worst = 0.0
    for _ in range(int(5.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        worst = max(worst, float(np.linalg.norm(d.site_xpos[tool] - start)))
    assert worst < 1e-3
    assert not any(d.warning[i].number for i in range(len(d.warning)))


@pytest.mark.parametrize("joint", ACTUATED)
def test_step_command_settles_without_oscillation(converted, joint):
    m, d = _model(converted)
    act = m.actuator(joint).id
    qadr = m.joint(joint).qposadr[0]
    q0 = d.qpos[qadr]
    step = 0.01 if joint == "finger_left_joint" else 0.2
    target = q0 + step
    d.ctrl[act] = target
    trace = []
    for _ in range(int(2.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        trace.append(d.qpos[qadr])
    trace = np.array(trace)
    overshoot = (trace.max() - target) / step
    assert overshoot < 0.02, f"overshoot {overshoot:.1%}"
    assert abs(trace[-1] - target) < 0.01 * step, "settled within 1% of the step"
    err = trace - target
    crossings = np.count_nonzero(np.diff(np.sign(err[np.abs(err) > 1e-3 * step])))
    assert crossings <= 1, "no oscillation around the target"


def test_force_torque_sensor_reads_the_weight_of_a_1kg_payload(converted):
    def with_payload(spec: mujoco.MjSpec) -> None:
        tool = spec.body("tool0")
        payload = tool.add_body(name="payload", pos=[0.02, 0, 0])
        payload.add_geom(
            type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.02, 0.02], contype=0, conaffinity=0
        )
        payload.explicitinertial = True
        payload.mass = 1.0
        payload.inertia = [1e-4, 1e-4, 1e-4]

    readings = []
    for extra in (None, with_payload):
        m, d = _model(converted, extra)
        for _ in range(int(2.0 / m.opt.timestep)):
            mujoco.mj_step(m, d)
        site = m.site("ft_frame").id
        force_world = d.site_xmat[site].reshape(3, 3) @ _sensor(m, d, "ft_frame_force")
        readings.append(force_world)
    delta = readings[1] - readings[0]
    assert np.linalg.norm(delta) == pytest.approx(9.81, rel=0.01)
    assert abs(delta[2]) == pytest.approx(9.81, rel=0.01), "the payload's weight is vertical"


def test_imu_reads_gravity_upward_at_rest(converted):
    m, d = _model(converted)
    for _ in range(100):
        mujoco.mj_step(m, d)
    site = m.site("imu_link").id
    acc_world = d.site_xmat[site].reshape(3, 3) @ _sensor(m, d, "imu_link_accelerometer")
    np.testing.assert_allclose(acc_world, [0, 0, 9.81], atol=0.0981)
    assert np.linalg.norm(_sensor(m, d, "imu_link_gyro")) < 1e-3


def test_lidar_returns_distance_to_a_wall(converted):
    wall_x = 2.0

    def with_wall(spec: mujoco.MjSpec) -> None:
        spec.worldbody.add_geom(
            name="wall",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=[wall_x + 0.05, 0, 1],
            size=[0.05, 5, 1],
        )

    m, d = _model(converted, with_wall)
    laser = m.site("laser_link").id
    x0 = d.site_xpos[laser][0]
    middle = LIDAR_SAMPLES // 2
    for k in (middle, middle - 20, middle + 30):
        name = f"laser_link_ray_{k:03d}"
        angle = -math.pi / 2 + k * math.pi / (LIDAR_SAMPLES - 1)
        assert _sensor(m, d, name)[0] == pytest.approx((wall_x - x0) / math.cos(angle), abs=0.01), (
            name
        )


def _render(m, d, camera: str, depth: bool) -> np.ndarray:
    with mujoco.Renderer(m, 240, 320) as r:
        if depth:
            r.enable_depth_rendering()
        r.update_scene(d, camera=camera)
        return r.render()


def test_camera_renders_rgb_and_depth_and_a_known_object_lands_where_intrinsics_predict(
    converted, gl_context
):
    m0, d0 = _model(converted)
    frame = m0.site("camera_optical_frame").id
    r_opt = d0.site_xmat[frame].reshape(3, 3)
    p_opt = d0.site_xpos[frame].copy()
    target_cam = np.array([0.12, -0.15, 0.8])  # ROS optical frame: x right, y down, z forward
    target_world = p_opt + r_opt @ target_cam

    def with_ball(spec: mujoco.MjSpec) -> None:
        spec.worldbody.add_geom(
            name="ball",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[0.03, 0, 0],
            pos=target_world,
            rgba=[1, 0, 0, 1],
            contype=0,
            conaffinity=0,
        )

    m, d = _model(converted, with_ball)
    rgb = _render(m, d, "camera_optical_frame", depth=False)
    depth = _render(m, d, "camera_optical_frame", depth=True)
    assert rgb.shape == (240, 320, 3) and depth.shape == (240, 320)
    red = (
        (rgb[..., 0] > 80)
        & (rgb[..., 0] > 3 * rgb[..., 1].astype(int))
        & (rgb[..., 0] > 3 * rgb[..., 2].astype(int))
    )
    assert red.sum() > 20, "the ball is in view"
    vs, us = np.nonzero(red)
    fovy = math.radians(m.camera("camera_optical_frame").fovy[0])
    f = (240 / 2) / math.tan(fovy / 2)
    u = f * target_cam[0] / target_cam[2] + 320 / 2
    v = f * target_cam[1] / target_cam[2] + 240 / 2
    assert abs(us.mean() + 0.5 - u) < 2 and abs(vs.mean() + 0.5 - v) < 2
    centre = depth[int(round(v - 0.5)), int(round(u - 0.5))]
    assert centre == pytest.approx(target_cam[2] - 0.03, abs=0.02), "depth along the optical axis"
