"""``/<controller>/follow_joint_trajectory``: control_msgs' FollowJointTrajectory action
on a trajectory controller, as joint_trajectory_controller serves it to MoveIt.

rmw_zenoh carries an action as rcl_action lays it out: the services
``<action>/_action/send_goal``, ``cancel_goal`` and ``get_result`` and the topics
``<action>/_action/feedback`` and ``<action>/_action/status``. An accepted goal runs
through the server's trajectory follower on the simulated clock (one goal at a time:
a new one, a topic trajectory or a forward command on its joints ends it, aborted);
it succeeds at the trajectory's end once its joints are within the goal tolerance,
which it may take ``goal_time_tolerance`` longer to reach. Tolerances are control_msgs'
``JointTolerance``: position (rad or m), velocity and acceleration, each the largest
error allowed, on the way (``path_tolerance``: against the trajectory's own positions
and their derivatives) and at the end (``goal_tolerance``: against the last point, at
rest); 0 or -1 is not checked (the server has no defaults of its own). A cancel holds
the joints where they are.

Goal state lives in the simulation thread; get_result's reply waits there for the end.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from . import controllers, keyexpr

if TYPE_CHECKING:
    from .session import Node


class Server(Protocol):
    """What the action needs of the server that runs it (:class:`.server.Server`):
    declared here, so the server imports the action and not the other way round."""

    @property
    def m(self) -> Any: ...

    @property
    def d(self) -> Any: ...

    def submit(self, fn: Callable[[], Any], timeout: float = 30.0) -> Any: ...

    def post(self, fn: Callable[[], None]) -> None: ...

    def start_trajectory(self, name: str, traj: controllers.Trajectory) -> None: ...

    def stop_trajectory(self, name: str) -> None: ...

    def follows(self, name: str, traj: controllers.Trajectory) -> bool: ...


log = logging.getLogger(__name__)

ACTION = "control_msgs/action/FollowJointTrajectory"
# action_msgs/msg/GoalStatus
UNKNOWN, ACCEPTED, EXECUTING, CANCELING, SUCCEEDED, CANCELED, ABORTED = range(7)
TERMINAL = (SUCCEEDED, CANCELED, ABORTED)
# control_msgs/action/FollowJointTrajectory Result
SUCCESSFUL, INVALID_GOAL, INVALID_JOINTS = 0, -1, -2
PATH_TOLERANCE_VIOLATED, GOAL_TOLERANCE_VIOLATED = -4, -5
# action_msgs/srv/CancelGoal
ERROR_NONE, ERROR_REJECTED, ERROR_UNKNOWN_GOAL_ID, ERROR_GOAL_TERMINATED = range(4)
STATUS_QOS = keyexpr.QoS(depth=1, durability=keyexpr.TRANSIENT_LOCAL)
"""rcl_action's status topic QoS: reliable, transient local, depth 1."""
KEPT = 32
"""Ended goals kept (for their result and the status array), the oldest dropped first."""


def _seconds(d: dict[str, Any]) -> float:
    return float(d.get("sec", 0)) + float(d.get("nanosec", 0)) * 1e-9


def _stamp(t: float) -> dict[str, int]:
    ns = int(round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


@dataclass
class Goal:
    uuid: bytes
    stamp: float
    trajectory: controllers.Trajectory | None
    joints: tuple[str, ...]
    path_tolerance: np.ndarray
    """(n, 3) per goal joint: position, velocity, acceleration; 0: not checked."""
    goal_tolerance: np.ndarray
    goal_time_tolerance: float
    status: int = EXECUTING
    result: dict[str, Any] = field(default_factory=dict)
    waiting: list[Callable[[dict[str, Any]], None]] = field(default_factory=list)


COMPONENTS = ("position", "velocity", "acceleration")


def _tolerances(given: list[dict[str, Any]], joints: tuple[str, ...]) -> np.ndarray:
    """(n, 3): each joint's position, velocity and acceleration tolerance (0: unchecked;
    control_msgs' -1, "none", too)."""
    out = np.zeros((len(joints), len(COMPONENTS)))
    for tol in given:
        if tol.get("name") in joints:
            for k, part in enumerate(COMPONENTS):
                value = float(tol.get(part, 0.0))
                out[joints.index(tol["name"]), k] = value if np.isfinite(value) and value > 0 else 0
    return out


def _beyond(tolerance: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """Indices of the joints with an error beyond a checked tolerance; ``errors`` (n, 3)."""
    return np.flatnonzero(np.any((tolerance > 0) & (np.abs(errors) > tolerance), axis=1))


class TrajectoryAction:
    """The FollowJointTrajectory action of one trajectory controller."""

    def __init__(self, server: Server, group: controllers.Group) -> None:
        self.server, self.group = server, group
        self.name = f"/{group.name}/follow_joint_trajectory"
        self.goals: dict[bytes, Goal] = {}
        self.active: Goal | None = None

    # -- endpoints (Zenoh's threads) -----------------------------------------------------

    def open(self, node: Node, bad: Callable[[str], None]) -> None:
        base = f"{self.name}/_action"
        self._feedback = node.publisher(f"{base}/feedback", f"{ACTION}_FeedbackMessage")
        self._status = node.publisher(
            f"{base}/status", "action_msgs/msg/GoalStatusArray", STATUS_QOS
        )
        node.service(f"{base}/send_goal", f"{ACTION}_SendGoal", self.send_goal, on_bad=bad)
        node.service(
            f"{base}/cancel_goal", "action_msgs/srv/CancelGoal", self.cancel_goal, on_bad=bad
        )
        node.deferred_service(
            f"{base}/get_result", f"{ACTION}_GetResult", self.get_result, on_bad=bad
        )

    def send_goal(self, req: dict[str, Any]) -> dict[str, Any]:
        uuid = bytes(req["goal_id"]["uuid"])
        try:
            return dict(self.server.submit(lambda: self._accept(uuid, req["goal"])))
        except FutureTimeout:
            return {"accepted": False, "stamp": _stamp(0.0)}

    def cancel_goal(self, req: dict[str, Any]) -> dict[str, Any]:
        info = req["goal_info"]
        uuid, before = bytes(info["goal_id"]["uuid"]), _seconds(info["stamp"])
        try:
            return dict(self.server.submit(lambda: self._cancel(uuid, before)))
        except FutureTimeout:
            return {"return_code": ERROR_REJECTED, "goals_canceling": []}

    def get_result(self, req: dict[str, Any], reply: Callable[[dict[str, Any]], None]) -> None:
        uuid = bytes(req["goal_id"]["uuid"])

        def ask() -> None:
            goal = self.goals.get(uuid)
            if goal is None:
                reply({"status": UNKNOWN, "result": {}})
            elif goal.status in TERMINAL:
                reply({"status": goal.status, "result": goal.result})
            else:
                goal.waiting.append(reply)

        self.server.post(ask)

    # -- the simulation thread -----------------------------------------------------------

    def _accept(self, uuid: bytes, goal: dict[str, Any]) -> dict[str, Any]:
        d, group = self.server.d, self.group
        now = float(d.time)
        refused = {"accepted": False, "stamp": _stamp(now)}
        msg = goal.get("trajectory", {})
        names = tuple(msg.get("joint_names", []))
        if uuid in self.goals:
            log.warning("%s: goal rejected: its id is taken", self.name)
            return refused
        if goal.get("multi_dof_trajectory", {}).get("joint_names"):
            log.warning("%s: goal rejected: multi-DOF joints (the controller has none)", self.name)
            return refused
        try:
            current = d.ctrl[list(group.actuators)].copy()
            traj = controllers.trajectory(group, msg, now, current)
        except controllers.BadCommand as exc:
            log.warning("%s: goal rejected: %s", self.name, exc)
            return refused
        if self.active is not None:
            self._end(self.active, ABORTED, INVALID_GOAL, "preempted by a new goal")
        self.server.start_trajectory(group.name, traj)
        g = Goal(
            uuid,
            now,
            traj,
            names,
            _tolerances(goal.get("path_tolerance", []), names),
            _tolerances(goal.get("goal_tolerance", []), names),
            _seconds(goal.get("goal_time_tolerance", {})),
        )
        self.goals[uuid] = g
        self.active = g
        self._publish_status()
        return {"accepted": True, "stamp": _stamp(now)}

    def _cancel(self, uuid: bytes, before: float) -> dict[str, Any]:
        """rcl_action's rules: a zero id and a zero stamp cancel every goal, a zero id
        those accepted at or before the stamp, an id that goal (and those before the
        stamp, where one is given)."""
        zero = not any(uuid)
        picked = [
            g
            for g in self.goals.values()
            if (not zero and g.uuid == uuid)
            or (zero and before == 0.0)
            or (before > 0.0 and g.stamp <= before)
        ]
        if not zero and uuid not in self.goals:
            return {"return_code": ERROR_UNKNOWN_GOAL_ID, "goals_canceling": []}
        live = [g for g in picked if g.status not in TERMINAL]
        if not live:  # rcl_action: a named goal that has ended, else nothing to cancel
            code = ERROR_GOAL_TERMINATED if not zero else ERROR_REJECTED
            return {"return_code": code, "goals_canceling": []}
        for g in live:
            if g is self.active:
                self._hold()
            self._end(g, CANCELED, SUCCESSFUL, "canceled")
        return {
            "return_code": ERROR_NONE,
            "goals_canceling": [
                {"goal_id": {"uuid": g.uuid}, "stamp": _stamp(g.stamp)} for g in live
            ],
        }

    def _hold(self) -> None:
        """The goal's joints held where they are now."""
        m, d, group = self.server.m, self.server.d, self.group
        self.server.stop_trajectory(group.name)
        for a in group.actuators:
            d.ctrl[a] = d.qpos[m.jnt_qposadr[m.actuator_trnid[a, 0]]]

    def _end(self, goal: Goal, status: int, code: int, text: str) -> None:
        goal.status, goal.result = status, {"error_code": code, "error_string": text}
        if goal is self.active:
            self.active = None
        for reply in goal.waiting:
            reply({"status": status, "result": goal.result})
        goal.waiting.clear()
        ended = [k for k, g in self.goals.items() if g.status in TERMINAL]
        for k in ended[: max(0, len(ended) - KEPT)]:
            del self.goals[k]
        self._publish_status()

    def _publish_status(self) -> None:
        self._status.publish(
            {
                "status_list": [
                    {
                        "goal_info": {"goal_id": {"uuid": g.uuid}, "stamp": _stamp(g.stamp)},
                        "status": g.status,
                    }
                    for g in self.goals.values()
                ]
            }
        )

    def tick(self, publish: bool) -> None:
        """After each step: the active goal checked (and its feedback, on a publishing
        tick)."""
        goal = self.active
        if goal is None or goal.trajectory is None:
            return
        traj = goal.trajectory
        if not self.server.follows(self.group.name, traj):
            self._end(goal, ABORTED, INVALID_GOAL, "another command took the joints")
            return
        m, d, group = self.server.m, self.server.d, self.group
        cols = list(traj.columns)
        joints = [m.actuator_trnid[group.actuators[c], 0] for c in cols]
        actual = np.array([d.qpos[m.jnt_qposadr[j]] for j in joints])
        velocity = np.array([d.qvel[m.jnt_dofadr[j]] for j in joints])
        t = float(d.time)
        desired = traj.sample(t)
        error = desired - actual
        if publish and self._feedback.matched:
            self._feedback.publish(
                {
                    "goal_id": {"uuid": goal.uuid},
                    "feedback": {
                        "header": {"stamp": _stamp(t), "frame_id": ""},
                        "joint_names": list(goal.joints),
                        "desired": {"positions": desired.tolist()},
                        "actual": {"positions": actual.tolist(), "velocities": velocity.tolist()},
                        "error": {"positions": error.tolist()},
                    },
                }
            )
        dofs = [m.jnt_dofadr[j] for j in joints]
        acceleration = np.array([d.qacc[i] for i in dofs])
        if t <= traj.end:
            want_v, want_a = traj.rates(t)
            errors = np.column_stack([error, want_v - velocity, want_a - acceleration])
            off = _beyond(goal.path_tolerance, errors)
            if off.size:
                bad = ", ".join(goal.joints[i] for i in off)
                self._hold()
                self._end(goal, ABORTED, PATH_TOLERANCE_VIOLATED, f"off the path: {bad}")
                return
        if t < traj.end:
            return
        errors = np.column_stack([traj.positions[-1] - actual, velocity, acceleration])
        off = _beyond(goal.goal_tolerance, errors)
        if off.size == 0:
            self._end(goal, SUCCEEDED, SUCCESSFUL, "")
        elif t > traj.end + goal.goal_time_tolerance:
            far = ", ".join(goal.joints[i] for i in off)
            self._end(goal, ABORTED, GOAL_TOLERANCE_VIOLATED, f"not at the goal: {far}")

    def reset(self) -> None:
        """After reset_world: the active goal aborted (its trajectory was dropped)."""
        if self.active is not None:
            self._end(self.active, ABORTED, INVALID_GOAL, "the world was reset")
