"""A MIRA3D bundle's rovers on ROS 2, each under its own namespace, as the real
Innok base is driven: ``/<rover>/cmd_vel`` (geometry_msgs/Twist: forward speed and yaw
rate, through the wheels, kept for CMD_VEL_TIMEOUT), ``/<rover>/odom``
(nav_msgs/Odometry from the wheel encoders), ``/<rover>/imu`` (sensor_msgs/Imu) and an
emergency stop ``/<rover>/estop`` (std_msgs/Bool: true latches it, as the console's:
the wheels brake and hold, the arm holds, and commands are ignored until a false
releases it), and the arm's ``/<rover>/arm_controller/joint_trajectory``
(trajectory_msgs/JointTrajectory, its joints named as the model names them) with its
``/<rover>/arm_controller/follow_joint_trajectory`` action (as the robot's, see
:mod:`.trajectory_action`; the latched stop aborts a goal).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from ..runner.rover.sim import RoverSim
from ..runner.task_kinds import CMD_VEL
from . import controllers, keyexpr
from .server import Extension, Server, ros_time
from .session import Node, Publisher
from .trajectory_action import TrajectoryAction

CMD_VEL_TIMEOUT = 0.5
"""Simulated seconds a Twist drives the wheels: a teleop that goes silent stops the
rover (ros2_control's diff_drive_controller waits 0.5 s by default too)."""


class _Driven:
    def __init__(self) -> None:
        self.v = self.w = 0.0
        self.until = -math.inf
        self.estop = False
        self.trajectory: controllers.Trajectory | None = None
        self.finished: controllers.Trajectory | None = None
        """The last trajectory followed to its end, with no command since."""


def _arm_group(m: mujoco.MjModel, name: str, acts: np.ndarray) -> controllers.Group:
    """The rover's arm servos as the group its trajectory controller drives (joint names
    without the rover's prefix, as the roles and the console give them)."""
    joints = []
    low, high = [], []
    for a in acts:
        j = int(m.actuator_trnid[a, 0])
        joints.append(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or "")
        lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-np.inf, np.inf)
        if m.actuator_ctrllimited[a]:
            lo, hi = max(lo, m.actuator_ctrlrange[a, 0]), min(hi, m.actuator_ctrlrange[a, 1])
        low.append(lo)
        high.append(hi)
    return controllers.Group(
        f"{name}/arm_controller",
        "position",
        tuple(joints),
        tuple(int(a) for a in acts),
        np.array(low),
        np.array(high),
    )


class _ArmFollower:
    """One rover arm's trajectory controller as its FollowJointTrajectory action sees a
    server (:class:`.trajectory_action.Server`): the arm's targets follow the goal, and
    holding sets them where the joints are."""

    def __init__(self, rovers: Rovers, server: Server, name: str) -> None:
        self.rovers, self.server, self.rover = rovers, server, name

    @property
    def m(self) -> Any:
        return self.server.m

    @property
    def d(self) -> Any:
        return self.server.d

    def submit(self, fn: Callable[[], Any], timeout: float = 30.0) -> Any:
        return self.server.submit(fn, timeout)

    def post(self, fn: Callable[[], None]) -> None:
        self.server.post(fn)

    def start_trajectory(self, name: str, traj: controllers.Trajectory) -> None:
        c = self.rovers.driven[self.rover]
        if not c.estop:  # latched: the goal is not followed, and aborts at its next tick
            c.trajectory, c.finished = traj, None

    def stop_trajectory(self, name: str) -> None:
        c = self.rovers.driven[self.rover]
        c.trajectory = c.finished = None
        sim = self.rovers.sim
        sim.arm_targets[self.rover][:] = sim.d.qpos[sim.rovers[self.rover].arm_qpos]

    def follows(self, name: str, traj: controllers.Trajectory) -> bool:
        c = self.rovers.driven[self.rover]
        return c.trajectory is traj or c.finished is traj


class Rovers(Extension):
    def __init__(self, sim: RoverSim) -> None:
        self.sim = sim
        self.driven = {name: _Driven() for name in sim.rovers}
        acts: set[int] = set()
        for r in sim.rovers.values():
            acts.update(int(a) for a in (*r.left, *r.right, *r.arm))
        self.actuators = frozenset(acts)
        self.arms = {n: _arm_group(sim.m, n, r.arm) for n, r in sim.rovers.items() if len(r.arm)}
        sim.sim.control.append(self._control)

    def actions(self, server: Server) -> list[TrajectoryAction]:
        """``/<rover>/arm_controller/follow_joint_trajectory`` for each rover's arm."""
        return [TrajectoryAction(_ArmFollower(self, server, n), g) for n, g in self.arms.items()]

    def open(self, node: Node, server: Server) -> None:
        self.server = server
        self._odom: dict[str, Publisher] = {}
        self._imu: dict[str, Publisher] = {}
        for name in self.sim.rovers:
            node.subscribe(
                f"/{name}/cmd_vel",
                "geometry_msgs/msg/Twist",
                functools.partial(self._on_twist, name),
            )
            node.subscribe(
                f"/{name}/estop",
                "std_msgs/msg/Bool",
                functools.partial(self._on_estop, name),
                qos=keyexpr.LATCHED,
            )
            if name in self.arms:
                node.subscribe(
                    f"/{name}/arm_controller/joint_trajectory",
                    "trajectory_msgs/msg/JointTrajectory",
                    functools.partial(self._on_arm_trajectory, name),
                )
            self._odom[name] = node.publisher(f"/{name}/odom", "nav_msgs/msg/Odometry")
            self._imu[name] = node.publisher(f"/{name}/imu", "sensor_msgs/msg/Imu")

    def _on_twist(self, name: str, msg: dict[str, Any]) -> None:
        v = CMD_VEL.param("linear_x").number(msg["linear"]["x"])
        w = CMD_VEL.param("angular_z").number(msg["angular"]["z"])
        for field, x in (("linear.x", v), ("angular.z", w)):
            if isinstance(x, str):
                self.server.warn.drop(f"/{name}/cmd_vel", f"{field}: {x}")
                return
        assert isinstance(v, float) and isinstance(w, float)

        def apply() -> None:
            c = self.driven[name]
            if c.estop:
                self.server.warn.drop(f"/{name}/cmd_vel", "emergency stop latched")
                return
            c.v, c.w, c.until = v, w, self.sim.d.time + CMD_VEL_TIMEOUT

        self.server.post(apply)

    def _on_arm_trajectory(self, name: str, msg: dict[str, Any]) -> None:
        group = self.arms[name]

        def start() -> None:
            c = self.driven[name]
            if c.estop:
                self.server.warn.drop(f"/{name}/arm_controller", "emergency stop latched")
                return
            current = self.sim.arm_targets[name].copy()
            try:
                c.trajectory = controllers.trajectory(group, msg, self.sim.d.time, current)
                c.finished = None
            except controllers.BadCommand as exc:
                self.server.warn.drop(f"/{name}/arm_controller joint_trajectory", str(exc))

        self.server.post(start)

    def _on_estop(self, name: str, msg: dict[str, Any]) -> None:
        on = bool(msg["data"])
        self.server.post(lambda: self._set_estop(name, on))

    def _set_estop(self, name: str, on: bool) -> None:
        c = self.driven[name]
        if on and not c.estop:
            c.v = c.w = 0.0
            c.trajectory = c.finished = None
            targets = self.sim.arm_targets[name]
            targets[:] = self.sim.d.qpos[self.sim.rovers[name].arm_qpos]  # the arm holds
        c.estop = on

    def _control(self) -> None:
        """Before every physics step: each rover's wheels from its command."""
        t = self.sim.d.time
        for name, r in self.sim.rovers.items():
            c = self.driven[name]
            if c.trajectory is not None:  # the arm's targets along it, clipped to range
                g = self.arms[name]
                cols = list(c.trajectory.columns)
                targets = self.sim.arm_targets[name]
                targets[cols] = np.clip(c.trajectory.sample(t), g.low[cols], g.high[cols])
                if t > c.trajectory.end:
                    c.trajectory, c.finished = None, c.trajectory
            if c.estop or t > c.until or (c.v == 0.0 and c.w == 0.0):
                self.sim.brake(r)
            else:
                self.sim.drive(r, c.v, c.w)

    def reset(self) -> None:
        for name, q in self.sim.home.items():
            self.sim.arm_targets[name][:] = q
            self.driven[name] = _Driven()
        self.sim.reset_odometry()

    def publish(self) -> None:
        d, m = self.sim.d, self.sim.m
        stamp = ros_time(d.time)
        for name, r in self.sim.rovers.items():
            self._odom[name].publish(odometry(self.sim, name, stamp))
            base = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, r.base) or name
            q = d.sensordata[r.orientation : r.orientation + 4]
            gyro = d.sensordata[r.gyro : r.gyro + 3]
            acc = d.sensordata[r.accel : r.accel + 3]
            site = r.spec.imu.site or base
            self._imu[name].publish(
                {
                    "header": {"stamp": stamp, "frame_id": site},
                    "orientation": {"x": q[1], "y": q[2], "z": q[3], "w": q[0]},
                    "orientation_covariance": [0.0] * 9,
                    "angular_velocity": dict(zip("xyz", map(float, gyro), strict=True)),
                    "angular_velocity_covariance": [0.0] * 9,
                    "linear_acceleration": dict(zip("xyz", map(float, acc), strict=True)),
                    "linear_acceleration_covariance": [0.0] * 9,
                }
            )


def odometry(sim: RoverSim, name: str, stamp: dict[str, int]) -> dict[str, Any]:
    """``/<rover>/odom``: rover ``name``'s wheel odometry (its pose from the encoders,
    its twist from the wheels' speeds) as nav_msgs/Odometry."""
    d, m, r = sim.d, sim.m, sim.rovers[name]
    odo = sim.odometry[name]
    wl = float(np.mean(d.sensordata[r.left_vel]))
    wr = float(np.mean(d.sensordata[r.right_vel]))
    base = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, r.base) or name
    half = odo.yaw / 2
    return {
        "header": {"stamp": stamp, "frame_id": f"{name}/odom"},
        "child_frame_id": base,
        "pose": {
            "pose": {
                "position": {"x": odo.x, "y": odo.y, "z": 0.0},
                "orientation": {
                    "x": 0.0,
                    "y": 0.0,
                    "z": math.sin(half),
                    "w": math.cos(half),
                },
            },
            "covariance": [0.0] * 36,
        },
        "twist": {
            "twist": {
                "linear": {"x": r.radius * (wl + wr) / 2, "y": 0.0, "z": 0.0},
                "angular": {"x": 0.0, "y": 0.0, "z": r.radius * (wr - wl) / r.track},
            },
            "covariance": [0.0] * 36,
        },
    }
