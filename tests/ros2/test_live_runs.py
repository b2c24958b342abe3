"""``rover-drive --ros2`` and ``facility-demo --ros2``: the run published to ROS 2 while it runs, watched by an
independent Zenoh session that decodes with rosbags; the run's report is the same
with and without it (but the wall-clock figures)."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time

import mujoco
import pytest

zenoh = pytest.importorskip("zenoh")

from tests.ros2.test_serve_e2e import STORE, _env, _free_port, _ros_key, _session  # noqa: E402
from tests.ros2.test_serve_rover import rover_world  # noqa: E402, F401 (a fixture)
from tests.runner.test_foxglove_live import _short_demo  # noqa: E402
from urdf2mjcf.runner.load import load  # noqa: E402

DRIVE = ("--distance", "0.3", "--turn", "0")


def _rover_drive(*args: str) -> list[str]:
    return [
        sys.executable,
        "-c",
        "from urdf2mjcf.cli import rover_drive_main; rover_drive_main()",
        *args,
    ]


def _subscribe(client, topic: str, type_name: str, got: list) -> object:
    return client.declare_subscriber(
        _ros_key(topic, type_name),
        lambda s: got.append(STORE.deserialize_cdr(s.payload.to_bytes(), type_name)),
    )


def _ros2_args(port: int) -> tuple[str, ...]:
    return ("--ros2", "--zenoh-listen", f"tcp/127.0.0.1:{port}", "--pace", "1")


def _watched(
    args: list[str], port: int, more: dict[str, str], code: int = 0
) -> tuple[list, list, list, list]:
    """Run ``args`` (a run with --ros2 listening on ``port``), subscribed from its
    "publishing" line to its end: /joint_states, the topic of ``more`` (one), /clock,
    and its stderr lines; the run must exit with ``code``."""
    proc = subprocess.Popen(
        args, env=_env(), stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True
    )
    lines: list[str] = []
    ready = threading.Event()

    def read() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.append(line)
            if line.startswith("publishing to ROS 2"):
                ready.set()

    threading.Thread(target=read, daemon=True).start()
    states: list = []
    other: list = []
    clock: list = []
    try:
        assert ready.wait(30), "".join(lines)
        client = _session(port)
        subs = [
            _subscribe(client, "/joint_states", "sensor_msgs/msg/JointState", states),
            *(_subscribe(client, t, k, other) for t, k in more.items()),
            _subscribe(client, "/clock", "rosgraph_msgs/msg/Clock", clock),
        ]
        assert proc.wait(60) == code, "".join(lines)
        time.sleep(0.2)
        for s in subs:
            s.undeclare()
        client.close()
    finally:
        if proc.poll() is None:
            proc.kill()
    return states, other, clock, lines


def _stamp(msg) -> float:
    return msg.sec + 1e-9 * msg.nanosec


def test_a_drive_published_live_keeps_its_report_and_is_watched(rover_world, tmp_path):  # noqa: F811
    plain, live = tmp_path / "plain.json", tmp_path / "live.json"
    subprocess.run(
        _rover_drive(str(rover_world), *DRIVE, "--report", str(plain)),
        env=_env(),
        check=True,
        capture_output=True,
        timeout=60,
    )
    states, odom, clock, lines = _watched(
        _rover_drive(
            str(rover_world), *DRIVE, "--report", str(live), *_ros2_args(port := _free_port())
        ),
        port,
        {"/rover/odom": "nav_msgs/msg/Odometry"},
    )
    # the verdict and the final state: the same bytes with --ros2 as without
    assert json.loads(live.read_text()) == json.loads(plain.read_text())
    assert len(states) > 50, "".join(lines)
    m = mujoco.MjModel.from_xml_path(str(rover_world / "scene.xml"))
    hinges = {
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        for j in range(m.njnt)
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE
    }
    assert set(states[-1].name) <= hinges and len(states[-1].name) > 0
    stamps = [_stamp(s.header.stamp) for s in states]
    assert stamps == sorted(stamps) and stamps[-1] > stamps[0]
    # the odometry's end is the distance driven (the report: the wheels' own figure)
    assert odom and abs(odom[-1].pose.pose.position.x - 0.3) < 0.03
    assert clock and abs(_stamp(clock[-1].clock) - stamps[-1]) < 0.02


WALL = ("planning_time_s", "real_time_factor", "wall_time")


def _without_wall(value: object) -> object:
    if isinstance(value, dict):
        return {k: _without_wall(v) for k, v in value.items() if k not in WALL}
    if isinstance(value, list):
        return [_without_wall(v) for v in value]
    return value


def test_a_demo_published_live_keeps_its_verdict_and_is_watched(imetro_bundle, tmp_path):
    waypoints = _short_demo(imetro_bundle, tmp_path)
    plain, live = tmp_path / "plain.json", tmp_path / "live.json"
    demo = ("-c", "from urdf2mjcf.cli import facility_demo_main; facility_demo_main()")
    run = [sys.executable, *demo, str(imetro_bundle), "--waypoints", str(waypoints)]
    # one gripper step: the CTB is not stowed, a FAILED verdict (exit 1) either way
    done = subprocess.run(
        [*run, "--report", str(plain)], env=_env(), capture_output=True, timeout=60
    )
    assert done.returncode == 1, done.stderr
    port = _free_port()
    states, wrench, clock, lines = _watched(
        [*run, "--report", str(live), *_ros2_args(port)],
        port,
        {"/ft_frame/wrench": "geometry_msgs/msg/WrenchStamped"},
        code=1,
    )
    assert _without_wall(json.loads(live.read_text())) == _without_wall(
        json.loads(plain.read_text())
    )
    fac = load(imetro_bundle)
    gripper = fac.manifest.components["robot"].roles["gripper"]["joints"][0]
    assert len(states) >= 10 and gripper in states[-1].name, "".join(lines)
    stamps = [_stamp(s.header.stamp) for s in states]
    assert stamps == sorted(stamps) and stamps[-1] >= 0.5  # the gripper's 0.5 s step
    assert wrench and wrench[-1].header.frame_id == "ft_frame"
    assert clock and abs(_stamp(clock[-1].clock) - stamps[-1]) < 0.02


def test_transport_options_without_ros2_or_with_trials_are_refused(rover_world, imetro_bundle):  # noqa: F811
    listen = ("--zenoh-listen", "tcp/127.0.0.1:7449")
    for args, said in (
        (_rover_drive(str(rover_world), *listen), "need --ros2"),
        (_rover_drive(str(rover_world), "--ros-domain", "3"), "need --ros2"),
        (_rover_drive(str(rover_world), "--ros2", "--task", "deliver"), "not a --task run"),
        (
            [
                sys.executable,
                "-c",
                "from urdf2mjcf.cli import facility_demo_main; facility_demo_main()",
                str(imetro_bundle),
                "--trials",
                "2",
                "--ros2",
                *listen,
            ],
            "--ros2 publishes one run, not --trials",
        ),
    ):
        done = subprocess.run(args, env=_env(), capture_output=True, text=True, timeout=60)
        assert done.returncode == 2 and said in done.stderr, done.stderr
        assert "Traceback" not in done.stderr
