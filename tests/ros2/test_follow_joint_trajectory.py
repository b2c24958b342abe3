"""``/joint_trajectory_controller/follow_joint_trajectory`` of ``urdf2mjcf serve --ros2``
driven as MoveIt drives it: an independent Zenoh session sends goals, cancels one and
waits for results on the action's rmw_zenoh services, encoding and decoding with
rosbags (control_msgs' types registered from their definitions), and checks the
joints against MuJoCo's /joint_states."""

from __future__ import annotations

import struct
import threading
import time

import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh")

from rosbags.typesys import get_types_from_msg  # noqa: E402

from tests.ros2.test_serve_e2e import (  # noqa: E402
    STORE,
    Served,
    _free_port,
    _key,
    _positions,
    _session,
    _trajectory,
    _wait_sim,
    robot,  # noqa: F401 - the module's fixture
)
from urdf2mjcf.ros2 import interfaces, type_hash  # noqa: E402

ACTION = "/joint_trajectory_controller/follow_joint_trajectory"
FJT = "control_msgs/action/FollowJointTrajectory"
NAMES = ["shoulder_pan_joint", "elbow_joint"]
# control_msgs' messages, and the services' halves as messages (CDR is the same)
_TYPES = {
    "control_msgs/msg/JointTolerance": interfaces.MESSAGES["control_msgs/msg/JointTolerance"],
    "control_msgs/msg/JointComponentTolerance": interfaces.MESSAGES[
        "control_msgs/msg/JointComponentTolerance"
    ],
    **{f"{FJT}{p}": interfaces.MESSAGES[f"{FJT}{p}"] for p in ("_Goal", "_Result", "_Feedback")},
    **{f"{FJT}{p}": interfaces.MESSAGES[f"{FJT}{p}"] for p in ("_FeedbackMessage",)},
    f"{FJT}_SendGoal_Request": (f"unique_identifier_msgs/UUID goal_id\n{FJT}_Goal goal"),
    f"{FJT}_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp",
    f"{FJT}_GetResult_Request": "unique_identifier_msgs/UUID goal_id",
    f"{FJT}_GetResult_Response": f"int8 status\n{FJT}_Result result",
    "action_msgs/msg/CancelGoal_Request": "action_msgs/GoalInfo goal_info",
    "action_msgs/msg/CancelGoal_Response": "int8 return_code\naction_msgs/GoalInfo[] goals_canceling",
}
for _name, _text in _TYPES.items():
    if _name not in STORE.types:
        STORE.register(get_types_from_msg(_text, _name))
T = STORE.types
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6


@pytest.fixture(scope="module")
def served(robot):  # noqa: F811
    s = Served(robot, _free_port())
    yield s
    if s.proc.poll() is None:
        s.stop()


@pytest.fixture(scope="module")
def client(served):
    session = _session(served.port)
    yield session
    session.close()


def _uuid(n: int):
    return T["unique_identifier_msgs/msg/UUID"](uuid=np.full(16, n, dtype=np.uint8))


def _call(
    client, service: str, request_type: str, response_type: str, request, timeout=20,
    action: str = ACTION,
):  # fmt: skip
    att = struct.pack("<qqB", 7, time.time_ns(), 16) + bytes(16)
    replies = list(
        client.get(
            _key(client, "SS", f"{action}/_action/{service}"),
            payload=bytes(STORE.serialize_cdr(request, request_type)),
            attachment=att,
            timeout=timeout,
        )
    )
    assert len(replies) == 1 and replies[0].ok is not None
    return STORE.deserialize_cdr(replies[0].ok.payload.to_bytes(), response_type)


def _goal(
    n: int, names, points, tolerance: float = 0.0, path: float = 0.0, late: int = 1,
    path_v: float = 0.0, goal_v: float = 0.0,
):  # fmt: skip
    def tolerances(position: float, velocity: float):
        return [
            T["control_msgs/msg/JointTolerance"](
                name=n_, position=position, velocity=velocity, acceleration=0.0
            )
            for n_ in (names if position or velocity else [])
        ]

    goal = T[f"{FJT}_Goal"](
        trajectory=_trajectory(names, points),
        multi_dof_trajectory=T["trajectory_msgs/msg/MultiDOFJointTrajectory"](
            header=T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=""
            ),
            joint_names=[],
            points=[],
        ),
        path_tolerance=tolerances(path, path_v),
        component_path_tolerance=[],
        goal_tolerance=tolerances(tolerance, goal_v),
        component_goal_tolerance=[],
        goal_time_tolerance=T["builtin_interfaces/msg/Duration"](sec=late, nanosec=0),
    )
    return T[f"{FJT}_SendGoal_Request"](goal_id=_uuid(n), goal=goal)


def _send(client, n, names, points, tolerance=0.0, path=0.0, late=1, **rates) -> bool:
    req = _goal(n, names, points, tolerance, path, late, **rates)
    res = _call(client, "send_goal", f"{FJT}_SendGoal_Request", f"{FJT}_SendGoal_Response", req)
    return bool(res.accepted)


def _result(client, n):
    req = T[f"{FJT}_GetResult_Request"](goal_id=_uuid(n))
    return _call(client, "get_result", f"{FJT}_GetResult_Request", f"{FJT}_GetResult_Response", req)


def test_the_actions_endpoints_have_rmw_zenohs_names_and_type_hashes(client):
    for service, kind in (
        ("send_goal", f"{FJT}_SendGoal"),
        ("get_result", f"{FJT}_GetResult"),
        ("cancel_goal", "action_msgs/srv/CancelGoal"),
    ):
        key = _key(client, "SS", f"{ACTION}/_action/{service}")
        pkg, sub, name = kind.split("/")
        assert key.endswith(f"/{pkg}::{sub}::dds_::{name}_/{type_hash.type_hash(kind)}")
    for topic, kind in (
        ("feedback", f"{FJT}_FeedbackMessage"),
        ("status", "action_msgs/msg/GoalStatusArray"),
    ):
        key = _key(client, "MP", f"{ACTION}/_action/{topic}")
        assert key.endswith(f"/{STORE.hash_rihs01(kind)}")


def test_a_goal_is_followed_with_feedback_to_success_at_its_final_point(client):
    feedback: list = []
    status: list = []
    fb_key = _key(client, "MP", f"{ACTION}/_action/feedback")
    st_key = _key(client, "MP", f"{ACTION}/_action/status")
    subs = [
        client.declare_subscriber(
            fb_key,
            lambda s: feedback.append(
                STORE.deserialize_cdr(s.payload.to_bytes(), f"{FJT}_FeedbackMessage")
            ),
        ),
        client.declare_subscriber(
            st_key,
            lambda s: status.append(
                STORE.deserialize_cdr(s.payload.to_bytes(), "action_msgs/msg/GoalStatusArray")
            ),
        ),
    ]
    time.sleep(0.3)  # the subscriptions routed
    end = [0.3, -0.8]
    assert _send(client, 1, NAMES, [(0.4, [0.15, -0.5]), (0.8, end)], tolerance=0.03)
    res = _result(client, 1)  # blocks until the goal's end

    def ends() -> list[int]:
        return [
            g.status
            for a in list(status)
            for g in a.status_list
            if g.goal_info.goal_id.uuid.tolist() == [1] * 16
        ]

    # the result's reply and the final status are two messages: on a loaded machine the
    # reply can come first, so the status is awaited before the subscriptions go
    deadline = time.monotonic() + 10.0
    while SUCCEEDED not in ends() and time.monotonic() < deadline:
        time.sleep(0.05)
    for s in subs:
        s.undeclare()
    assert res.status == SUCCEEDED and res.result.error_code == 0
    np.testing.assert_allclose(_positions(client, NAMES), end, atol=0.03)
    mine = [f for f in feedback if f.goal_id.uuid.tolist() == [1] * 16]
    assert len(mine) >= 5 and list(mine[0].feedback.joint_names) == NAMES
    # the feedback's actual positions move from the start towards the goal
    first, last = mine[0].feedback.actual.positions, mine[-1].feedback.actual.positions
    assert np.abs(last - end).max() < np.abs(first - end).max()
    seen = ends()
    assert seen[0] == 2 and seen[-1] == SUCCEEDED  # executing, then succeeded


def test_unknown_joints_empty_goals_and_times_going_back_are_rejected(client):
    assert not _send(client, 2, ["no_such_joint"], [(0.5, [0.1])])
    assert not _send(client, 3, [], [])
    assert not _send(client, 4, NAMES, [(1.0, [0.1, 0.1]), (0.5, [0.2, 0.2])])
    assert _result(client, 2).status == 0  # unknown to the server: never accepted


def test_a_cancel_holds_the_joints_where_they_are(client):
    start = _positions(client, NAMES)
    goal = np.array([-0.5, -1.4])
    assert _send(client, 5, NAMES, [(3.0, goal.tolist())])
    got: list = []
    waiter = threading.Thread(target=lambda: got.append(_result(client, 5)))
    waiter.start()
    _wait_sim(client, 1.0)
    info = T["action_msgs/msg/GoalInfo"](
        goal_id=_uuid(5), stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    )
    res = _call(
        client,
        "cancel_goal",
        "action_msgs/msg/CancelGoal_Request",
        "action_msgs/msg/CancelGoal_Response",
        T["action_msgs/msg/CancelGoal_Request"](goal_info=info),
    )
    assert res.return_code == 0
    assert [g.goal_id.uuid.tolist() for g in res.goals_canceling] == [[5] * 16]
    waiter.join(20)
    assert got and got[0].status == CANCELED
    again = _call(
        client,
        "cancel_goal",
        "action_msgs/msg/CancelGoal_Request",
        "action_msgs/msg/CancelGoal_Response",
        T["action_msgs/msg/CancelGoal_Request"](goal_info=info),
    )
    assert again.return_code == 3  # ERROR_GOAL_TERMINATED
    _wait_sim(client, 0.3)
    held = _positions(client, NAMES)
    _wait_sim(client, 0.5)
    now = _positions(client, NAMES)
    np.testing.assert_allclose(now, held, atol=0.01)  # stopped
    assert np.all(np.abs(now - start) > 0.05) and np.all(np.abs(now - goal) > 0.05)  # mid-way


def test_tolerances_violated_abort_with_control_msgs_error_codes(client):
    # 1e-6 rad: no servo is that close, at the end (no time allowed past it) nor on the way
    here = _positions(client, NAMES)
    assert _send(client, 6, NAMES, [(0.3, (here + 0.1).tolist())], tolerance=1e-6, late=0)
    res = _result(client, 6)
    assert res.status == ABORTED and res.result.error_code == -5  # GOAL_TOLERANCE_VIOLATED
    assert _send(client, 7, NAMES, [(2.0, (here - 0.3).tolist())], path=1e-6)
    res = _result(client, 7)
    assert res.status == ABORTED and res.result.error_code == -4  # PATH_TOLERANCE_VIOLATED
    _wait_sim(client, 0.3)
    held = _positions(client, NAMES)
    np.testing.assert_allclose(held, here + 0.1, atol=0.05)  # stopped near where it was


def test_velocity_tolerances_on_the_way_and_at_rest(client):
    """A path velocity tolerance no servo meets (1e-6 rad/s off the trajectory's own
    speed) aborts with PATH_TOLERANCE_VIOLATED; a goal velocity tolerance of 0.05 rad/s
    succeeds once the joints have come to rest within the position tolerance."""
    here = _positions(client, NAMES)
    assert _send(client, 8, NAMES, [(1.0, (here + 0.2).tolist())], path_v=1e-6)
    res = _result(client, 8)
    assert res.status == ABORTED and res.result.error_code == -4  # PATH_TOLERANCE_VIOLATED
    _wait_sim(client, 0.3)
    here = _positions(client, NAMES)
    assert _send(client, 9, NAMES, [(1.0, (here - 0.1).tolist())], tolerance=0.02, goal_v=0.05)
    res = _result(client, 9)
    assert res.status == SUCCEEDED and res.result.error_code == 0
    np.testing.assert_allclose(_positions(client, NAMES), here - 0.1, atol=0.02)
