"""``urdf2mjcf serve BUNDLE --ros2`` of a MIRA3D bundle: the rover under its namespace,
driven with geometry_msgs/Twist and stopped by its latched emergency stop, watched by
an independent Zenoh session decoding with rosbags; the odometry against the base's
true motion as /tf reports MuJoCo's state."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh")

from tests.ros2.test_serve_e2e import (  # noqa: E402
    STORE,
    Served,
    _free_port,
    _last,
    _publish,
    _session,
    _tokens,
)


@pytest.fixture(scope="module")
def rover_world(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-floor")


@pytest.fixture(scope="module")
def served(rover_world):
    s = Served(rover_world, _free_port())
    yield s
    if s.proc.poll() is None:
        s.stop()


@pytest.fixture(scope="module")
def client(served):
    session = _session(served.port)
    yield session
    session.close()


def _twist(v: float, w: float):
    T = STORE.types
    V = T["geometry_msgs/msg/Vector3"]
    return T["geometry_msgs/msg/Twist"](linear=V(x=v, y=0.0, z=0.0), angular=V(x=0.0, y=0.0, z=w))


def _odom(client):
    return _last(client, "/rover/odom", "nav_msgs/msg/Odometry")


def _base_xy(client) -> tuple[float, float]:
    for t in _last(client, "/tf", "tf2_msgs/msg/TFMessage").transforms:
        if t.child_frame_id == "base_link":
            return t.transform.translation.x, t.transform.translation.y
    raise AssertionError("no base_link in /tf")


def _drive(client, v: float, seconds: float) -> None:
    """Twist at 10 Hz for ``seconds`` of wall time (cmd_vel lapses after 0.5 s)."""
    end = time.monotonic() + seconds
    seq = 0
    while time.monotonic() < end:
        seq += 1
        _publish(client, "/rover/cmd_vel", "geometry_msgs/msg/Twist", _twist(v, 0.0), seq=seq)
        time.sleep(0.1)


def _estop(client, on: bool) -> None:
    _publish(client, "/rover/estop", "std_msgs/msg/Bool", STORE.types["std_msgs/msg/Bool"](data=on))


def test_the_rover_is_under_its_namespace(client):
    endpoints = {(t[5], t[9].replace("%", "/")) for t in _tokens(client) if len(t) == 13}
    assert {
        ("MS", "/rover/cmd_vel"),
        ("MS", "/rover/estop"),
        ("MP", "/rover/odom"),
        ("MP", "/rover/imu"),
    } <= endpoints
    # the wheels and the arm are the rover's: no forward group takes them
    assert not any(topic.startswith("/forward_velocity") for _, topic in endpoints)
    imu = _last(client, "/rover/imu", "sensor_msgs/msg/Imu")
    q = imu.orientation
    assert math.isclose(q.x**2 + q.y**2 + q.z**2 + q.w**2, 1.0, abs_tol=1e-6)
    assert imu.linear_acceleration.z == pytest.approx(9.81, abs=0.5)  # standing on the floor


def test_twist_drives_the_rover_and_the_odometry_follows_its_true_motion(client):
    x0, y0 = _base_xy(client)
    o0 = _odom(client).pose.pose.position
    _drive(client, 0.3, 2.0)
    x1, y1 = _base_xy(client)
    o1 = _odom(client).pose.pose.position
    moved = math.hypot(x1 - x0, y1 - y0)
    assert moved > 0.15
    assert math.hypot(o1.x - o0.x, o1.y - o0.y) == pytest.approx(moved, rel=0.15)
    # the odometry's speed read while the Twists still come (each lapses after 0.5 s of
    # simulated time: read after the last one, a loaded machine sees the rover stopped)
    speeds = []
    end = time.monotonic() + 2.0
    seq = 1000
    while time.monotonic() < end and max(speeds, default=0.0) <= 0.1:
        seq += 1
        _publish(client, "/rover/cmd_vel", "geometry_msgs/msg/Twist", _twist(0.3, 0.0), seq=seq)
        speeds.append(_odom(client).twist.twist.linear.x)
        time.sleep(0.05)
    assert max(speeds) > 0.1, speeds


def test_the_latched_estop_stops_it_until_released(client):
    _drive(client, 0.3, 0.5)
    _estop(client, True)
    _drive(client, 0.3, 1.5)  # commands keep coming: the stop holds
    x0, y0 = _base_xy(client)
    _drive(client, 0.3, 0.5)
    x1, y1 = _base_xy(client)
    assert math.hypot(x1 - x0, y1 - y0) < 0.01
    assert abs(_odom(client).twist.twist.linear.x) < 0.02
    _estop(client, False)
    _drive(client, 0.3, 1.0)
    x2, y2 = _base_xy(client)
    assert math.hypot(x2 - x1, y2 - y1) > 0.05


def test_a_twist_out_of_the_declared_range_is_dropped(client, served):
    """A speed past the task registry's bound for ``cmd_vel`` (1e6 m/s) is dropped, not
    driven at the servos' limit; the rover stands still."""
    time.sleep(1.0)  # the last drive's Twist lapses
    x0, y0 = _base_xy(client)
    _drive(client, 2e6, 1.0)
    x1, y1 = _base_xy(client)
    assert math.hypot(x1 - x0, y1 - y0) < 0.01


def test_the_rovers_arm_follows_its_trajectory_controller(client):
    from tests.ros2.test_serve_e2e import _positions, _trajectory, _wait_sim

    _estop(client, False)
    names = ["ur_shoulder_pan_joint", "ur_elbow_joint"]
    start = _positions(client, names)
    goal = start + np.array([0.3, -0.2])
    _publish(
        client,
        "/rover/arm_controller/joint_trajectory",
        "trajectory_msgs/msg/JointTrajectory",
        _trajectory(names, [(1.0, list(goal))]),
    )
    _wait_sim(client, 2.0)
    np.testing.assert_allclose(_positions(client, names), goal, atol=0.05)


def test_the_rovers_arm_takes_follow_joint_trajectory_goals(client):
    """``/rover/arm_controller/follow_joint_trajectory`` as MoveIt sends it: a goal
    reaches its point and SUCCEEDS within its goal tolerance, as MuJoCo's joint states
    say; with the emergency stop latched a goal is not followed and is ABORTED."""
    from tests.ros2.test_follow_joint_trajectory import ABORTED, SUCCEEDED, _call, _goal
    from tests.ros2.test_serve_e2e import _positions, _wait_sim

    action = "/rover/arm_controller/follow_joint_trajectory"
    fjt = "control_msgs/action/FollowJointTrajectory"

    def send(n: int, points) -> bool:
        req = _goal(n, names, points, tolerance=0.03, late=2)
        res = _call(client, "send_goal", f"{fjt}_SendGoal_Request",
                    f"{fjt}_SendGoal_Response", req, action=action)  # fmt: skip
        return bool(res.accepted)

    def result(n: int):
        from tests.ros2.test_follow_joint_trajectory import T, _uuid

        req = T[f"{fjt}_GetResult_Request"](goal_id=_uuid(n))
        return _call(client, "get_result", f"{fjt}_GetResult_Request",
                     f"{fjt}_GetResult_Response", req, action=action)  # fmt: skip

    _estop(client, False)
    names = ["ur_shoulder_pan_joint", "ur_elbow_joint"]
    start = _positions(client, names)
    goal = start + np.array([-0.25, 0.15])
    assert send(41, [(1.0, goal.tolist())])
    res = result(41)
    assert res.status == SUCCEEDED and res.result.error_code == 0
    np.testing.assert_allclose(_positions(client, names), goal, atol=0.03)
    _estop(client, True)
    assert send(42, [(1.0, start.tolist())])
    res = result(42)
    assert res.status == ABORTED
    _wait_sim(client, 0.5)
    np.testing.assert_allclose(_positions(client, names), goal, atol=0.03)  # held
    _estop(client, False)
