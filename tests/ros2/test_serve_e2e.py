"""``urdf2mjcf serve robot.xml --ros2`` through the real command, against a second,
independent Zenoh session that does what an rmw_zenoh node does: it finds the node
and its endpoints in the liveliness tokens, reads CDR with rosbags' typestore (not
our decoder), writes commands the same way and calls the services."""

from __future__ import annotations

import math
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh")

from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SIM_ARM = ROOT / "tests" / "data" / "sim_robot" / "urdf" / "sim_arm.urdf.xacro"
STORE = get_typestore(Stores.ROS2_JAZZY)
# the services' halves as messages of their own (rosbags knows no service; CDR is the same)
_SRV = {
    "mujoco_ros2_control_msgs/msg/SetPause_Request": "bool paused",
    "mujoco_ros2_control_msgs/msg/StepSimulation_Request": "uint32 steps",
    "mujoco_ros2_control_msgs/msg/Result_Response": "bool success\nstring message",
}
for _name, _text in _SRV.items():
    STORE.register(get_types_from_msg(_text, _name))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT), "ROS_DOMAIN_ID": "0"}


def _command(*args: str) -> list[str]:
    return [
        sys.executable,
        "-c",
        # Ctrl-C as a terminal's shell gives it: a suite started in the background has SIGINT
        # ignored, and Python keeps an inherited ignored SIGINT ignored
        "import signal; signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "from urdf2mjcf.cli import urdf2mjcf_main; urdf2mjcf_main()",
        *args,
    ]


@pytest.fixture(scope="module")
def robot(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sim_arm") / "robot.xml"
    subprocess.run(
        _command(
            str(SIM_ARM),
            "lidar_samples:=3",
            "--package-path",
            str(SIM_ARM.parents[2]),
            "-o",
            str(out),
            "-q",
        ),
        check=True,
        env=_env(),
        capture_output=True,
    )
    return out


class Served:
    def __init__(self, robot: Path, port: int, *extra: str) -> None:
        self.port = port
        self.proc = subprocess.Popen(
            _command(
                "serve", str(robot), "--ros2", "--zenoh-listen", f"tcp/127.0.0.1:{port}", *extra
            ),
            env=_env(),
            stderr=subprocess.PIPE,
            text=True,
        )
        self.lines: list[str] = []
        self._ready = threading.Event()
        threading.Thread(target=self._read, daemon=True).start()
        assert self._ready.wait(30), "no 'serving' line: " + "".join(self.lines)

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.append(line)
            if line.startswith("serving "):
                self._ready.set()

    def stop(self) -> float:
        t = time.monotonic()
        self.proc.send_signal(signal.SIGTERM)
        self.proc.wait(10)
        return time.monotonic() - t


def _session(port: int):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", f'["tcp/127.0.0.1:{port}"]')
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


@pytest.fixture(scope="module")
def served(robot):
    s = Served(robot, _free_port())
    yield s
    if s.proc.poll() is None:
        s.stop()


@pytest.fixture(scope="module")
def client(served):
    session = _session(served.port)
    yield session
    session.close()


def _tokens(client) -> list[list[str]]:
    deadline = time.monotonic() + 5
    while True:
        found = [
            str(r.ok.key_expr).split("/") for r in client.liveliness().get("@ros2_lv/0/**") if r.ok
        ]
        if len(found) > 5 or time.monotonic() > deadline:
            return found
        time.sleep(0.1)


def _key(client, kind: str, topic: str) -> str:
    """The data key of the served endpoint on ``topic``, from its token alone."""
    for t in _tokens(client):
        if len(t) == 13 and t[5] == kind and t[9] == topic.replace("/", "%"):
            return f"{t[1]}/{topic[1:]}/{t[10]}/{t[11]}"
    raise AssertionError(f"no {kind} token for {topic}")


def _ros_key(topic: str, type_name: str) -> str:
    # the design document's format, the hash as rosbags computes it
    pkg, kind, name = type_name.split("/")
    return f"0/{topic[1:]}/{pkg}::{kind}::dds_::{name}_/{STORE.hash_rihs01(type_name)}"


def _collect(client, topic: str, type_name: str, seconds: float) -> list[tuple[object, bytes]]:
    got: list[tuple[object, bytes]] = []
    sub = client.declare_subscriber(
        _ros_key(topic, type_name),
        lambda s: got.append(
            (STORE.deserialize_cdr(s.payload.to_bytes(), type_name), s.attachment.to_bytes())
        ),
    )
    time.sleep(seconds)
    sub.undeclare()
    return got


def _last(client, topic: str, type_name: str) -> object:
    """The latest message on ``topic`` (a subscription needs a moment to be routed, and
    a loaded machine may publish late)."""
    for _ in range(40):
        got = _collect(client, topic, type_name, 0.1)
        if got:
            return got[-1][0]
    raise AssertionError(f"nothing on {topic}")


def _publish(client, topic: str, type_name: str, msg: object, seq: int = 1) -> None:
    att = struct.pack("<qqB", seq, time.time_ns(), 16) + bytes(range(16))
    client.put(
        _ros_key(topic, type_name), bytes(STORE.serialize_cdr(msg, type_name)), attachment=att
    )


def _call(client, key: str, request_type: str, request: object) -> object:
    att = struct.pack("<qqB", 42, time.time_ns(), 16) + bytes(16)
    replies = list(
        client.get(
            key,
            payload=bytes(STORE.serialize_cdr(request, request_type)),
            attachment=att,
            timeout=10,
        )
    )
    assert len(replies) == 1 and replies[0].ok is not None
    back = replies[0].ok.attachment.to_bytes()
    assert struct.unpack_from("<q", back)[0] == 42  # the request's sequence number, back
    return STORE.deserialize_cdr(
        replies[0].ok.payload.to_bytes(), "mujoco_ros2_control_msgs/msg/Result_Response"
    )


def _positions(client, names: list[str]) -> np.ndarray:
    js = _last(client, "/joint_states", "sensor_msgs/msg/JointState")
    return np.array([js.position[list(js.name).index(n)] for n in names])


def test_the_node_and_its_endpoints_are_in_the_graph_with_rosbags_type_hashes(client):
    tokens = _tokens(client)
    nodes = [t for t in tokens if t[5] == "NN"]
    assert [t[8] for t in nodes] == ["ros2_control_node"]
    endpoints = {(t[5], t[9].replace("%", "/")): (t[10], t[11]) for t in tokens if len(t) == 13}
    for topic, type_name in [
        ("/clock", "rosgraph_msgs/msg/Clock"),
        ("/joint_states", "sensor_msgs/msg/JointState"),
        ("/tf", "tf2_msgs/msg/TFMessage"),
        ("/tf_static", "tf2_msgs/msg/TFMessage"),
    ]:
        dds = "{}::{}::dds_::{}_".format(*type_name.split("/"))
        assert endpoints[("MP", topic)] == (dds, STORE.hash_rihs01(type_name))
    assert endpoints[("MS", "/forward_position_controller/commands")][1] == STORE.hash_rihs01(
        "std_msgs/msg/Float64MultiArray"
    )
    assert endpoints[("MS", "/joint_trajectory_controller/joint_trajectory")][
        1
    ] == STORE.hash_rihs01("trajectory_msgs/msg/JointTrajectory")
    for name in ("reset_world", "set_pause", "step_simulation"):
        assert ("SS", f"/ros2_control_node/{name}") in endpoints
    # every token names the one session: the node's id in the graph
    assert len({t[2] for t in tokens}) == 1


def test_joint_states_and_clock_decode_with_rosbags(client, robot):
    m = mujoco.MjModel.from_xml_path(str(robot))
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    states = _collect(client, "/joint_states", "sensor_msgs/msg/JointState", 0.5)
    clocks = _collect(client, "/clock", "rosgraph_msgs/msg/Clock", 0.5)
    assert len(states) >= 10 and len(clocks) >= 10  # 100 Hz of simulated time
    js, att = states[-1]
    assert list(js.name) == names  # every joint, the mimic follower too
    assert len(js.position) == len(js.velocity) == len(js.effort) == len(names)
    assert len(att) == 33 and att[16] == 16
    seqs = [struct.unpack_from("<q", a)[0] for _, a in states]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    times = [c.clock.sec + c.clock.nanosec * 1e-9 for c, _ in clocks]
    assert all(b > a for a, b in zip(times, times[1:], strict=False))
    # paced: never ahead of the wall clock (behind it only on a loaded machine)
    assert 0.1 < times[-1] - times[0] < 0.6


def test_tf_static_is_latched_for_a_late_subscriber(client):
    got: list[object] = []
    sub = zenoh.ext.declare_advanced_subscriber(
        client,
        _ros_key("/tf_static", "tf2_msgs/msg/TFMessage"),
        handler=lambda s: got.append(
            STORE.deserialize_cdr(s.payload.to_bytes(), "tf2_msgs/msg/TFMessage")
        ),
        history=zenoh.ext.HistoryConfig(detect_late_publishers=True),
    )
    deadline = time.monotonic() + 5
    while not got and time.monotonic() < deadline:
        time.sleep(0.05)
    sub.undeclare()
    assert got, "no /tf_static from the publisher's cache"
    frames = {(t.header.frame_id, t.child_frame_id) for t in got[0].transforms}
    assert ("world", "base_link") in frames
    moving = _last(client, "/tf", "tf2_msgs/msg/TFMessage")
    children = {t.child_frame_id for t in moving.transforms}
    assert {"shoulder_link", "tool0"} <= children  # named as the URDF's links


def test_a_forward_command_moves_the_joints_there_and_is_clipped_to_limits(client, served, robot):
    m = mujoco.MjModel.from_xml_path(str(robot))
    joints = [
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(m.actuator_trnid[a, 0]))
        for a in range(m.nu)
    ]
    target = np.array([0.4, 0.2, -0.8, 0.3, 0.5])  # the finger's range is 0..0.04: clipped
    Msg = STORE.types["std_msgs/msg/Float64MultiArray"]
    Layout = STORE.types["std_msgs/msg/MultiArrayLayout"]
    _publish(
        client,
        "/forward_position_controller/commands",
        "std_msgs/msg/Float64MultiArray",
        Msg(layout=Layout(dim=[], data_offset=0), data=target),
    )
    _wait_sim(client, 1.5)
    reached = _positions(client, joints)
    np.testing.assert_allclose(reached[:4], target[:4], atol=0.05)
    assert reached[4] == pytest.approx(0.04, abs=0.005)
    assert any("clipped" in line for line in served.lines)
    # a wrong length and a NaN are dropped, one warning, and the server goes on
    _publish(
        client,
        "/forward_position_controller/commands",
        "std_msgs/msg/Float64MultiArray",
        Msg(layout=Layout(dim=[], data_offset=0), data=np.array([1.0, 2.0])),
        seq=2,
    )
    _publish(
        client,
        "/forward_position_controller/commands",
        "std_msgs/msg/Float64MultiArray",
        Msg(layout=Layout(dim=[], data_offset=0), data=np.array([np.nan] * 5)),
        seq=3,
    )
    time.sleep(0.3)
    np.testing.assert_allclose(_positions(client, joints)[:4], target[:4], atol=0.05)
    assert sum("dropped" in line for line in served.lines) == 1
    assert served.proc.poll() is None


def _trajectory(names, points):
    T = STORE.types
    return T["trajectory_msgs/msg/JointTrajectory"](
        header=T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=""
        ),
        joint_names=names,
        points=[
            T["trajectory_msgs/msg/JointTrajectoryPoint"](
                positions=np.array(p),
                velocities=np.array([]),
                accelerations=np.array([]),
                effort=np.array([]),
                time_from_start=T["builtin_interfaces/msg/Duration"](
                    sec=int(t), nanosec=int((t % 1) * 1e9)
                ),
            )
            for t, p in points
        ],
    )


def _sim_time(client) -> float:
    c = _last(client, "/clock", "rosgraph_msgs/msg/Clock")
    return c.clock.sec + c.clock.nanosec * 1e-9


def _wait_sim(client, seconds: float) -> None:
    """Until ``seconds`` of simulated time have passed (the machine may be loaded)."""
    t0 = _sim_time(client)
    deadline = time.monotonic() + 20 * seconds
    while _sim_time(client) < t0 + seconds and time.monotonic() < deadline:
        pass


def test_a_joint_trajectory_is_followed_on_the_simulated_clock(client):
    names = ["shoulder_pan_joint", "elbow_joint"]
    start = _positions(client, names)
    end = np.array([-0.4, -1.2])
    msg = _trajectory(names, [(0.5, [0.0, -1.0]), (1.0, end)])
    _publish(
        client,
        "/joint_trajectory_controller/joint_trajectory",
        "trajectory_msgs/msg/JointTrajectory",
        msg,
    )
    _wait_sim(client, 0.5)
    mid = _positions(client, names)
    # on its way: past the start, short of the end
    assert np.all(np.abs(mid - start) > 0.05) and np.all(np.abs(mid - end) > 0.05)
    _wait_sim(client, 1.0)
    np.testing.assert_allclose(_positions(client, names), end, atol=0.05)
    # times going back: dropped, the joints stay
    back = _trajectory(names, [(1.0, [0.5, 0.5]), (0.5, [0.6, 0.6])])
    _publish(
        client,
        "/joint_trajectory_controller/joint_trajectory",
        "trajectory_msgs/msg/JointTrajectory",
        back,
        seq=2,
    )
    _wait_sim(client, 0.5)
    np.testing.assert_allclose(_positions(client, names), end, atol=0.05)


def test_pause_step_and_reset_world_services(client, robot):
    m = mujoco.MjModel.from_xml_path(str(robot))
    T = STORE.types
    pause = _key(client, "SS", "/ros2_control_node/set_pause")
    step = _key(client, "SS", "/ros2_control_node/step_simulation")
    reset = _key(client, "SS", "/ros2_control_node/reset_world")
    SetPause = T["mujoco_ros2_control_msgs/msg/SetPause_Request"]
    Step = T["mujoco_ros2_control_msgs/msg/StepSimulation_Request"]
    # stepping while running is refused
    assert not _call(
        client, step, "mujoco_ros2_control_msgs/msg/StepSimulation_Request", Step(steps=10)
    ).success
    assert _call(
        client, pause, "mujoco_ros2_control_msgs/msg/SetPause_Request", SetPause(paused=True)
    ).success
    a = _collect(client, "/clock", "rosgraph_msgs/msg/Clock", 0.2)
    time.sleep(0.2)
    assert not _collect(client, "/clock", "rosgraph_msgs/msg/Clock", 0.2)  # paused: no time passes
    t0 = a[-1][0].clock.sec + a[-1][0].clock.nanosec * 1e-9 if a else None
    got = []
    sub = client.declare_subscriber(
        _ros_key("/clock", "rosgraph_msgs/msg/Clock"),
        lambda s: got.append(
            STORE.deserialize_cdr(s.payload.to_bytes(), "rosgraph_msgs/msg/Clock")
        ),
    )
    reply = _call(
        client, step, "mujoco_ros2_control_msgs/msg/StepSimulation_Request", Step(steps=100)
    )
    time.sleep(0.1)
    sub.undeclare()
    assert reply.success, reply.message
    t1 = got[-1].clock.sec + got[-1].clock.nanosec * 1e-9
    if t0 is not None:
        assert t1 - t0 == pytest.approx(100 * m.opt.timestep, abs=1e-9)
    # reset to the home keyframe: the arm back where the conversion put it
    empty = _empty_reset()
    assert _call(client, reset, "mujoco_ros2_control_msgs/msg/ResetWorld_Request", empty).success
    _call(client, step, "mujoco_ros2_control_msgs/msg/StepSimulation_Request", Step(steps=2))
    home = m.key_qpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")]
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    time.sleep(0.05)
    assert _call(
        client, pause, "mujoco_ros2_control_msgs/msg/SetPause_Request", SetPause(paused=False)
    ).success
    np.testing.assert_allclose(_positions(client, names), home, atol=0.02)
    bad = _empty_reset(keyframe="nowhere")
    reply = _call(client, reset, "mujoco_ros2_control_msgs/msg/ResetWorld_Request", bad)
    assert not reply.success and "home" in reply.message


def _empty_reset(keyframe: str = ""):
    T = STORE.types
    if "mujoco_ros2_control_msgs/msg/ResetWorld_Request" not in T:
        STORE.register(
            get_types_from_msg(
                "string keyframe\nmujoco_ros2_control_msgs/msg/SimulationState state_overrides",
                "mujoco_ros2_control_msgs/msg/ResetWorld_Request",
            )
            | get_types_from_msg(
                "sensor_msgs/msg/JointState joint_states\n"
                "mujoco_ros2_control_msgs/msg/FreeJointState[] free_joints",
                "mujoco_ros2_control_msgs/msg/SimulationState",
            )
            | get_types_from_msg(
                "string name\ngeometry_msgs/msg/PoseStamped pose\ngeometry_msgs/msg/TwistStamped twist",
                "mujoco_ros2_control_msgs/msg/FreeJointState",
            )
        )
        T = STORE.types
    stamp = T["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    js = T["sensor_msgs/msg/JointState"](
        header=T["std_msgs/msg/Header"](stamp=stamp, frame_id=""),
        name=[],
        position=np.array([]),
        velocity=np.array([]),
        effort=np.array([]),
    )
    state = T["mujoco_ros2_control_msgs/msg/SimulationState"](joint_states=js, free_joints=[])
    return T["mujoco_ros2_control_msgs/msg/ResetWorld_Request"](
        keyframe=keyframe, state_overrides=state
    )


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_sigterm_or_ctrl_c_ends_the_server_within_2_s_and_the_node_leaves_the_graph(
    robot, sig, code
):
    s = Served(robot, _free_port())
    watcher = _session(s.port)
    try:
        assert [t for t in _tokens(watcher) if t[5] == "NN"]
        t = time.monotonic()
        s.proc.send_signal(sig)
        assert s.proc.wait(10) == code
        assert time.monotonic() - t < 2.0
        left = [str(r.ok.key_expr) for r in watcher.liveliness().get("@ros2_lv/**") if r.ok]
        assert left == []
    finally:
        watcher.close()
        if s.proc.poll() is None:  # failed: no server left running for the rest of the suite
            s.proc.kill()
            s.proc.wait(10)


def test_velocity_and_effort_groups_drive_their_actuators(tmp_path):
    from tests.ros2.test_serve_command import MODEL

    path = tmp_path / "robot.xml"
    path.write_text(MODEL)
    s = Served(path, _free_port())
    client = _session(s.port)
    try:
        keys = {t[9].replace("%", "/") for t in _tokens(client) if len(t) == 13 and t[5] == "MS"}
        assert {
            "/forward_position_controller/commands",
            "/forward_velocity_controller/commands",
            "/forward_effort_controller/commands",
        } <= keys
        Msg = STORE.types["std_msgs/msg/Float64MultiArray"]
        Layout = STORE.types["std_msgs/msg/MultiArrayLayout"]

        def send(group: str, values: list[float]) -> None:
            _publish(
                client,
                f"/{group}/commands",
                "std_msgs/msg/Float64MultiArray",
                Msg(layout=Layout(dim=[], data_offset=0), data=np.array(values)),
            )

        send("forward_velocity_controller", [0.5])
        send("forward_effort_controller", [5.0])  # the motor's range is -2..2: clipped
        _wait_sim(client, 1.0)
        js = _last(client, "/joint_states", "sensor_msgs/msg/JointState")
        assert list(js.name) == ["j1", "j2", "j3"]
        assert js.velocity[1] == pytest.approx(0.5, abs=0.05), (
            list(js.velocity),
            list(js.effort),
            s.lines,
        )
        assert js.effort[2] == pytest.approx(2.0, abs=1e-9)  # MuJoCo's qfrc_actuator
        assert any("clipped" in line and "j3" in line for line in s.lines)
    finally:
        client.close()
        s.stop()


SIM_ARM_CONTROLLERS = """controller_manager:
  ros__parameters:
    joint_state_broadcaster: {type: joint_state_broadcaster/JointStateBroadcaster}
    arm_controller: {type: joint_trajectory_controller/JointTrajectoryController}
    gripper_controller: {type: position_controllers/JointGroupPositionController}
arm_controller:
  ros__parameters:
    joints: [shoulder_pan_joint, shoulder_lift_joint, elbow_joint, wrist_joint]
    command_interfaces: [position]
gripper_controller:
  ros__parameters:
    joints: [finger_left_joint]
"""


def test_the_bringups_controllers_file_names_the_controllers(robot, tmp_path):
    path = tmp_path / "controllers.yaml"
    path.write_text(SIM_ARM_CONTROLLERS)
    s = Served(robot, _free_port(), "--controllers", str(path))
    client = _session(s.port)
    try:
        subs = {t[9].replace("%", "/") for t in _tokens(client) if len(t) == 13 and t[5] == "MS"}
        assert subs == {"/arm_controller/joint_trajectory", "/gripper_controller/commands"}
        names = ["shoulder_pan_joint", "elbow_joint"]
        _publish(
            client,
            "/arm_controller/joint_trajectory",
            "trajectory_msgs/msg/JointTrajectory",
            _trajectory(names, [(0.5, [0.5, -1.1])]),
        )
        Msg = STORE.types["std_msgs/msg/Float64MultiArray"]
        Layout = STORE.types["std_msgs/msg/MultiArrayLayout"]
        _publish(
            client,
            "/gripper_controller/commands",
            "std_msgs/msg/Float64MultiArray",
            Msg(layout=Layout(dim=[], data_offset=0), data=np.array([0.02])),
        )
        _wait_sim(client, 1.5)
        got = _positions(client, [*names, "finger_left_joint"])
        np.testing.assert_allclose(got[:2], [0.5, -1.1], atol=0.05)
        assert got[2] == pytest.approx(0.02, abs=0.004)
    finally:
        client.close()
        s.stop()


def test_the_imu_and_the_force_torque_sensor_are_published(client, robot):
    m = mujoco.MjModel.from_xml_path(str(robot))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    site = m.site("imu_link").id
    imu = _last(client, "/imu_link/imu", "sensor_msgs/msg/Imu")
    assert imu.header.frame_id == "imu_link"
    q = imu.orientation
    # the IMU is fixed to the base: its orientation is the site's in the world
    np.testing.assert_allclose(
        np.abs(np.dot([q.w, q.x, q.y, q.z], _site_quat(d, site))), 1.0, atol=1e-6
    )
    a = imu.linear_acceleration
    assert math.hypot(a.x, a.y, a.z) == pytest.approx(9.81, abs=0.05)  # standing still
    ft = _last(client, "/ft_frame/wrench", "geometry_msgs/msg/WrenchStamped")
    assert ft.header.frame_id == "ft_frame"
    f = ft.wrench.force
    # held still: the sensor carries the weight of everything beyond it
    beyond = m.body_subtreemass[m.site_bodyid[m.site("ft_frame").id]]
    assert math.hypot(f.x, f.y, f.z) == pytest.approx(beyond * 9.81, rel=0.05)


def _site_quat(d, site: int) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, d.site_xmat[site])
    return q


def test_cameras_are_rendered_as_mujoco_renders_them(robot):
    from urdf2mjcf import headless

    if headless.gl_context_error():
        pytest.skip(f"no offscreen OpenGL here: {headless.gl_context_error()}")
    m = mujoco.MjModel.from_xml_path(str(robot))
    cam = 0
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_CAMERA, cam)
    w, h = (int(v) for v in m.cam_resolution[cam])
    s = Served(robot, _free_port(), "--camera-rate", "5")
    client = _session(s.port)
    try:
        image = _last(client, f"/{name}/image_raw", "sensor_msgs/msg/Image")
        info = _last(client, f"/{name}/camera_info", "sensor_msgs/msg/CameraInfo")
    finally:
        client.close()
        s.stop()
    assert (image.height, image.width, image.encoding, image.step) == (h, w, "rgb8", 3 * w)
    assert image.header.frame_id == name == info.header.frame_id
    # the pinhole MuJoCo renders: f = (h / 2) / tan(fovy / 2), centre at ((w-1)/2, (h-1)/2)
    f = (h / 2) / math.tan(math.radians(m.cam_fovy[cam]) / 2)
    np.testing.assert_allclose(
        np.reshape(info.k, (3, 3)), [[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]]
    )
    # the arm held at home: the image is MuJoCo's own render of that state
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    with mujoco.Renderer(m, h, w) as r:
        r.update_scene(d, camera=cam)
        ours = r.render().astype(float)
    theirs = np.frombuffer(bytes(image.data), np.uint8).reshape(h, w, 3).astype(float)
    assert np.mean(np.abs(ours - theirs)) < 3.0


def test_through_a_zenoh_router_as_rmw_zenohd_runs_one(robot):
    # rmw_zenoh's deployment: a router (rmw_zenohd: mode router, tcp/[::]:7447 there; a
    # free loopback port here), the server and a ROS node both connecting to it
    port = _free_port()
    conf = zenoh.Config()
    conf.insert_json5("mode", '"router"')
    conf.insert_json5("listen/endpoints", f'["tcp/127.0.0.1:{port}"]')
    conf.insert_json5("scouting/multicast/enabled", "false")
    router = zenoh.open(conf)
    proc = subprocess.Popen(
        _command("serve", str(robot), "--ros2", "--zenoh-connect", f"tcp/127.0.0.1:{port}"),
        env=_env(),
        stderr=subprocess.PIPE,
        text=True,
    )
    client = _session(port)
    try:
        tokens = _tokens(client)
        assert [t[8] for t in tokens if t[5] == "NN"] == ["ros2_control_node"]
        assert _last(client, "/joint_states", "sensor_msgs/msg/JointState").name
    finally:
        client.close()
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)
        router.close()
    assert "connecting to tcp/127.0.0.1:" in proc.stderr.read()


def test_the_lidar_is_a_laser_scan_as_its_gazebo_tag_says(client, robot):
    # the test arm's Gazebo ray sensor: samples:=3 from -pi/2 to pi/2, range 10 m
    scan = _last(client, "/laser_link/scan", "sensor_msgs/msg/LaserScan")
    assert scan.header.frame_id == "laser_link"
    assert scan.angle_min == pytest.approx(-math.pi / 2, abs=1e-6)
    assert scan.angle_increment == pytest.approx(math.pi / 2, abs=1e-6)
    assert scan.range_max == pytest.approx(10.0)
    m = mujoco.MjModel.from_xml_path(str(robot))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    ours = [d.sensor(f"laser_link_ray_{k}").data[0] for k in range(3)]
    expect = [math.inf if r < 0 else r for r in ours]
    np.testing.assert_allclose(scan.ranges, expect, atol=1e-3)


def test_the_ros_domain_is_in_every_key(robot):
    port = _free_port()
    proc = subprocess.Popen(
        _command("serve", str(robot), "--ros2", "--zenoh-listen", f"tcp/127.0.0.1:{port}"),
        env={**_env(), "ROS_DOMAIN_ID": "7"},
        stderr=subprocess.PIPE,
        text=True,
    )
    client = _session(port)
    try:
        deadline = time.monotonic() + 20
        found: list[str] = []
        while not found and time.monotonic() < deadline:
            found = [str(r.ok.key_expr) for r in client.liveliness().get("@ros2_lv/**") if r.ok]
            time.sleep(0.1)
        assert found and all(k.startswith("@ros2_lv/7/") for k in found)
        got: list[bytes] = []
        key = "7/clock/rosgraph_msgs::msg::dds_::Clock_/" + STORE.hash_rihs01(
            "rosgraph_msgs/msg/Clock"
        )
        sub = client.declare_subscriber(key, lambda s: got.append(s.payload.to_bytes()))
        other = client.declare_subscriber("0/**", lambda s: got.append(b"domain 0"))
        time.sleep(0.5)
        sub.undeclare()
        other.undeclare()
        assert got and b"domain 0" not in got
    finally:
        client.close()
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)
