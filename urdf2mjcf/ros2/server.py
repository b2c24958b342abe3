"""A MuJoCo model served to ROS 2 as mujoco_ros2_control serves one.

Published: ``/clock`` (simulated time), ``/joint_states`` and
``/mujoco_actuators_states`` (every 1-DoF joint: position, velocity, actuator
effort), ``/tf`` (the frames a joint moves, each body named as the URDF's link, in
its parent's frame) and ``/tf_static`` (the others, latched). Taken: the forward
controllers' ``/<group>/commands`` and ``/joint_trajectory_controller/joint_trajectory``
(:mod:`.controllers`), or those a controllers file names (:mod:`.controller_file`);
each trajectory controller's ``/<controller>/follow_joint_trajectory`` action
(:mod:`.trajectory_action`).
Services of the node: ``~/reset_world``, ``~/set_pause``, ``~/step_simulation``, with
mujoco_ros2_control's types and meaning. What a world adds (sensors, scans, cameras,
rovers) comes in as an :class:`Extension`.

One thread owns MuJoCo: it steps, applies the commands the Zenoh callbacks queued
and publishes; a service call waits for its answer from that thread.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from . import controllers, keyexpr
from .session import Endpoints, Node
from .trajectory_action import TrajectoryAction

log = logging.getLogger(__name__)

SYNC_MISALIGN = 0.1
"""Simulated seconds behind the wall clock after which pacing gives up catching up
(mujoco_ros2_control's kSyncMisalign): it re-syncs instead of running flat out."""
WARN_EVERY = 5.0
"""Wall seconds between two warnings of one kind (each says how many it dropped)."""


@dataclass(frozen=True)
class ServeConfig:
    endpoints: Endpoints
    domain: int = 0
    node_name: str = "ros2_control_node"
    namespace: str = "/"
    pace: float = 1.0
    """Simulated seconds per wall-clock second."""
    rate: float = 100.0
    """Hz of /clock, /joint_states and /tf, in simulated time."""
    camera_rate: float = 0.0
    """Hz (simulated time) each camera is rendered at; 0: none."""
    controllers: Path | None = None
    """ros2_control's controller_manager YAML (:mod:`.controller_file`); None: a
    forward controller per actuator kind and a trajectory controller over the
    position servos."""


class Warnings:
    """One warning per kind, then at most one each WARN_EVERY seconds with the count."""

    def __init__(self) -> None:
        self._last: dict[str, float] = {}
        self._count: dict[str, int] = {}
        self._once: set[str] = set()
        self._lock = threading.Lock()

    def drop(self, kind: str, reason: str) -> None:
        with self._lock:
            now = time.monotonic()
            self._count[kind] = self._count.get(kind, 0) + 1
            if now - self._last.get(kind, -math.inf) < WARN_EVERY:
                return
            n, self._count[kind] = self._count[kind], 0
            self._last[kind] = now
        log.warning("dropped %s (%d since the last warning): %s", kind, n, reason)

    def once(self, kind: str, text: str) -> None:
        with self._lock:
            if kind in self._once:
                return
            self._once.add(kind)
        log.warning("%s", text)


def ros_time(t: float) -> dict[str, int]:
    """``builtin_interfaces/Time`` of ``t`` seconds."""
    ns = int(round(t * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


@dataclass
class _Frames:
    """Which bodies go to /tf, which to /tf_static."""

    moving: list[int] = field(default_factory=list)
    fixed: list[int] = field(default_factory=list)


class Extension:
    """What a served world adds to the robot's interface (sensors, scans, cameras,
    rovers): its endpoints,
    its actuators (left out of the forward groups), and hooks into the loop, all run
    in the simulation thread but :meth:`open`."""

    actuators: frozenset[int] = frozenset()

    def open(self, node: Node, server: Server) -> None:
        """Declare the endpoints (callbacks queue through ``server.post``)."""

    def publish(self) -> None:
        """At each publishing tick."""

    def reset(self) -> None:
        """After ``reset_world``."""

    def actions(self, server: Server) -> list[TrajectoryAction]:
        """The FollowJointTrajectory actions of its own trajectory controllers (opened,
        ticked and reset with the server's)."""
        return []


class Server:
    def __init__(
        self,
        m: mujoco.MjModel,
        config: ServeConfig,
        d: mujoco.MjData | None = None,
        step: Callable[[], None] | None = None,
        extensions: tuple[Extension, ...] = (),
    ) -> None:
        self.m, self.config = m, config
        self.d = mujoco.MjData(m) if d is None else d
        self._physics = step or (lambda: mujoco.mj_step(self.m, self.d))
        self.extensions = extensions
        self.warn = Warnings()
        J = mujoco.mjtObj.mjOBJ_JOINT
        one_dof = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        self.joints = [
            j for j in range(m.njnt) if int(m.jnt_type[j]) in one_dof and mujoco.mj_id2name(m, J, j)
        ]
        self.joint_names = [mujoco.mj_id2name(m, J, j) or "" for j in self.joints]
        self._qadr = np.array([m.jnt_qposadr[j] for j in self.joints], dtype=int)
        self._vadr = np.array([m.jnt_dofadr[j] for j in self.joints], dtype=int)
        taken = frozenset().union(*(e.actuators for e in extensions))
        if config.controllers is None:
            self.groups = {g.name: g for g in controllers.groups(m, exclude=taken)}
            position = self.groups.get(controllers.GROUP_NAME["position"])
            self.trajectory_groups = (
                {}
                if position is None
                else {
                    controllers.TRAJECTORY_CONTROLLER: dataclasses.replace(
                        position, name=controllers.TRAJECTORY_CONTROLLER
                    )
                }
            )
        else:
            from .controller_file import read

            kinds = {a: controllers.actuator_kind(m, a) for a in range(m.nu) if a not in taken}
            given = read(config.controllers, m, {a: k for a, k in kinds.items() if k})
            self.groups = {g.name: g for g in given.forward}
            self.trajectory_groups = {g.name: g for g in given.trajectory}
        self._trajectories: dict[str, controllers.Trajectory] = {}
        self._finished: dict[str, controllers.Trajectory] = {}  # followed to their end
        self.actions = [TrajectoryAction(self, g) for g in self.trajectory_groups.values()]
        self.actions += [a for e in extensions for a in e.actions(self)]
        self._frames = self._split_frames()
        self._inbox: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self.paused = False
        self.stop = threading.Event()
        self.steps = 0
        self.published = 0
        self._resync = True
        self._next_publish = 0.0
        self.home = self._home_state()

    # -- state ---------------------------------------------------------------------------

    def _split_frames(self) -> _Frames:
        m, f = self.m, _Frames()
        moved = np.zeros(m.nbody, dtype=bool)
        for b in range(1, m.nbody):
            moved[b] = (
                moved[m.body_parentid[b]] or m.body_jntnum[b] > 0 or bool(m.body_mocapid[b] >= 0)
            )
            if mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b):
                (f.moving if moved[b] else f.fixed).append(b)
        return f

    def _home_state(self) -> int:
        """The keyframe the simulation starts from and ``reset_world`` returns to
        (``home`` where the model has one, else none: -1)."""
        k = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_KEY, "home")
        return int(k)

    def reset(self, key: int, overrides: dict[str, Any] | None = None) -> None:
        t = self.d.time
        if key >= 0:
            mujoco.mj_resetDataKeyframe(self.m, self.d, key)
        else:
            mujoco.mj_resetData(self.m, self.d)
        self.d.time = t  # the clock goes on: ROS nodes on /clock see no jump back
        if overrides:
            for i, name in enumerate(overrides["name"]):
                j = self.joints[self.joint_names.index(name)]
                if overrides["position"]:
                    self.d.qpos[self.m.jnt_qposadr[j]] = overrides["position"][i]
                if overrides["velocity"]:
                    self.d.qvel[self.m.jnt_dofadr[j]] = overrides["velocity"][i]
        mujoco.mj_forward(self.m, self.d)
        # the command interfaces re-synced: position servos hold where the joints are
        self._trajectories.clear()
        self._finished.clear()
        for g in [*self.groups.values(), *self.trajectory_groups.values()]:
            for a in g.actuators:
                jq = self.m.jnt_qposadr[self.m.actuator_trnid[a, 0]]
                self.d.ctrl[a] = self.d.qpos[jq] if g.kind == "position" else 0.0
        for e in self.extensions:
            e.reset()
        for action in self.actions:
            action.reset()
        self._resync = True

    # -- commands (queued from Zenoh's threads, run in the simulation's) ----------------

    def submit(self, fn: Callable[[], Any], timeout: float = 30.0) -> Any:
        """Run ``fn`` in the simulation thread; its result (raises TimeoutError)."""
        fut: Future[Any] = Future()

        def run() -> None:
            try:
                fut.set_result(fn())
            except Exception as exc:  # noqa: BLE001 - handed to the caller
                fut.set_exception(exc)

        self._inbox.put(run)
        # in slices: a call that lands as the server stops must not hold Zenoh's thread
        # (and so the session's close) for its whole timeout
        deadline = time.monotonic() + timeout
        while True:
            try:
                return fut.result(min(0.1, max(0.0, deadline - time.monotonic())))
            except FutureTimeout:
                if self.stop.is_set() or time.monotonic() >= deadline:
                    raise

    def post(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` in the simulation thread, before its next step."""
        self._inbox.put(fn)

    def on_forward(self, group: controllers.Group, msg: dict[str, Any]) -> None:
        try:
            values = controllers.forward_command(group, msg.get("data", []))
        except controllers.BadCommand as exc:
            self.warn.drop(f"{group.name} commands", str(exc))
            return
        self._inbox.put(lambda: self._apply_forward(group, values))

    def _clip(self, group: controllers.Group, values: np.ndarray, what: str) -> np.ndarray:
        clipped = np.clip(values, group.low, group.high)
        if np.any(clipped != values):
            bad = [group.joints[i] for i in np.flatnonzero(clipped != values)]
            self.warn.once(
                f"clip {group.name}",
                f"{what} outside the actuators' limits clipped to them ({', '.join(bad)}; "
                "said once)",
            )
        return clipped

    def _apply_forward(self, group: controllers.Group, values: np.ndarray) -> None:
        taken = set(group.actuators)  # the latest command on an interface wins
        for name in [
            n for n in self._trajectories if taken & set(self.trajectory_groups[n].actuators)
        ]:
            del self._trajectories[name]
            self._finished.pop(name, None)
        self.d.ctrl[list(group.actuators)] = self._clip(group, values, f"{group.name} commands")

    def on_trajectory(self, group: controllers.Group, msg: dict[str, Any]) -> None:
        def start() -> None:
            current = self.d.ctrl[list(group.actuators)].copy()
            try:
                self.start_trajectory(
                    group.name, controllers.trajectory(group, msg, self.d.time, current)
                )
            except controllers.BadCommand as exc:
                self.warn.drop(f"{group.name} joint_trajectory", str(exc))

        self._inbox.put(start)

    def start_trajectory(self, name: str, traj: controllers.Trajectory) -> None:
        """Trajectory controller ``name`` follows ``traj`` from now on."""
        self._trajectories[name] = traj
        self._finished.pop(name, None)

    def stop_trajectory(self, name: str) -> None:
        self._trajectories.pop(name, None)
        self._finished.pop(name, None)

    def follows(self, name: str, traj: controllers.Trajectory) -> bool:
        """Whether ``traj`` is controller ``name``'s, still or followed to its end with
        no command since."""
        return self._trajectories.get(name) is traj or self._finished.get(name) is traj

    def _follow(self) -> None:
        for name, traj in list(self._trajectories.items()):
            group = self.trajectory_groups[name]
            cols = list(traj.columns)
            acts = [group.actuators[c] for c in cols]
            sub = controllers.Group(
                group.name,
                group.kind,
                tuple(group.joints[c] for c in cols),
                tuple(acts),
                group.low[cols],
                group.high[cols],
            )
            self.d.ctrl[acts] = self._clip(sub, traj.sample(self.d.time), "trajectory positions")
            if self.d.time > traj.end:
                del self._trajectories[name]
                self._finished[name] = traj

    # -- services ------------------------------------------------------------------------

    def set_pause(self, req: dict[str, Any]) -> dict[str, Any]:
        def run() -> dict[str, Any]:
            if self.paused and not req["paused"]:
                self._resync = True  # no catch-up steps after a pause
            self.paused = bool(req["paused"])
            return {"success": True, "message": "paused" if self.paused else "running"}

        try:
            return self.submit(run)
        except FutureTimeout:
            return {"success": False, "message": "timed out"}

    def step_simulation(self, req: dict[str, Any]) -> dict[str, Any]:
        steps = int(req["steps"])
        if steps < 1:
            return {"success": False, "message": "steps must be at least 1"}

        def run() -> dict[str, Any]:
            if not self.paused:
                return {"success": False, "message": "the simulation is running: pause it first"}
            for _ in range(steps):
                self._step()
            return {"success": True, "message": f"{steps} steps, now at t={self.d.time:.6f} s"}

        try:
            return self.submit(run, timeout=max(30.0, 0.01 * steps))
        except FutureTimeout:
            return {"success": False, "message": "timed out"}

    def reset_world(self, req: dict[str, Any]) -> dict[str, Any]:
        name = req.get("keyframe", "")
        key = self.home
        if name:
            key = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_KEY, name)
            if key < 0:
                keys = [
                    mujoco.mj_id2name(self.m, mujoco.mjtObj.mjOBJ_KEY, k) or str(k)
                    for k in range(self.m.nkey)
                ]
                return {
                    "success": False,
                    "message": f"no keyframe '{name}'; keyframes: {', '.join(keys) or 'none'}",
                }
        state = req.get("state_overrides", {})
        js = state.get("joint_states", {})
        if state.get("free_joints"):
            return {"success": False, "message": "free_joints overrides are not supported"}
        names = list(js.get("name", []))
        unknown = [n for n in names if n not in self.joint_names]
        if unknown:
            return {"success": False, "message": f"unknown joint(s): {', '.join(unknown)}"}
        for f in ("position", "velocity"):
            if js.get(f) and len(js[f]) != len(names):
                return {"success": False, "message": f"joint_states.{f}: one per name, or none"}
            if not all(math.isfinite(v) for v in js.get(f, [])):
                return {"success": False, "message": f"joint_states.{f}: not finite"}
        if js.get("effort"):
            return {"success": False, "message": "joint_states.effort is not supported"}
        overrides = {
            "name": names,
            "position": list(js.get("position", [])),
            "velocity": list(js.get("velocity", [])),
        }
        try:
            self.submit(lambda: self.reset(key, overrides if names else None))
        except FutureTimeout:
            return {"success": False, "message": "timed out"}
        return {
            "success": True,
            "message": f"reset to {'keyframe ' + repr(name) if name else 'the start'}",
        }

    # -- messages ------------------------------------------------------------------------

    def joint_state(self) -> dict[str, Any]:
        d = self.d
        return {
            "header": {"stamp": ros_time(d.time), "frame_id": ""},
            "name": self.joint_names,
            "position": d.qpos[self._qadr].tolist(),
            "velocity": d.qvel[self._vadr].tolist(),
            "effort": d.qfrc_actuator[self._vadr].tolist(),
        }

    def transforms(self, bodies: list[int]) -> dict[str, Any]:
        m, d = self.m, self.d
        stamp = ros_time(d.time)
        out = []
        q_inv, q = np.zeros(4), np.zeros(4)
        for b in bodies:
            p = m.body_parentid[b]
            r_p = d.xmat[p].reshape(3, 3)
            pos = r_p.T @ (d.xpos[b] - d.xpos[p])
            mujoco.mju_negQuat(q_inv, d.xquat[p])
            mujoco.mju_mulQuat(q, q_inv, d.xquat[b])
            out.append(
                {
                    "header": {
                        "stamp": stamp,
                        "frame_id": mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, p) or "world",
                    },
                    "child_frame_id": mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b),
                    "transform": {
                        "translation": dict(zip("xyz", pos.tolist(), strict=True)),
                        "rotation": {"x": q[1], "y": q[2], "z": q[3], "w": q[0]},
                    },
                }
            )
        return {"transforms": out}

    # -- the loop ------------------------------------------------------------------------

    def _step(self) -> None:
        self._follow()
        self._physics()
        self.steps += 1
        tick = self.d.time + 1e-12 >= self._next_publish
        for action in self.actions:
            action.tick(publish=tick)
        if tick:
            self._publish()
            self._next_publish += 1.0 / self.config.rate
            if self._next_publish < self.d.time:
                self._next_publish = self.d.time + 1.0 / self.config.rate

    def _drain(self) -> None:
        while True:
            try:
                fn = self._inbox.get_nowait()
            except queue.Empty:
                return
            fn()

    def open(self, node: Node) -> None:
        """Declare every endpoint on ``node`` (publishers first: a subscriber's first
        command may come at once)."""
        self._node = node
        self._clock = node.publisher("/clock", "rosgraph_msgs/msg/Clock", keyexpr.CLOCK)
        self._js = node.publisher("/joint_states", "sensor_msgs/msg/JointState")
        self._as = node.publisher("/mujoco_actuators_states", "sensor_msgs/msg/JointState")
        self._tf = node.publisher("/tf", "tf2_msgs/msg/TFMessage", keyexpr.TF)
        self._tf_static = node.publisher("/tf_static", "tf2_msgs/msg/TFMessage", keyexpr.LATCHED)

        def bad(reason: str) -> None:
            self.warn.drop("undecodable samples", reason)

        for g in self.groups.values():
            node.subscribe(
                f"/{g.name}/commands",
                "std_msgs/msg/Float64MultiArray",
                functools.partial(self.on_forward, g),
                on_bad=bad,
            )
        for g in self.trajectory_groups.values():
            node.subscribe(
                f"/{g.name}/joint_trajectory",
                "trajectory_msgs/msg/JointTrajectory",
                functools.partial(self.on_trajectory, g),
                on_bad=bad,
            )
        base = (
            node.info.name
            if node.info.namespace == "/"
            else f"{node.info.namespace[1:]}/{node.info.name}"
        )
        for name, handler in (
            ("reset_world", self.reset_world),
            ("set_pause", self.set_pause),
            ("step_simulation", self.step_simulation),
        ):
            srv = "".join(p.capitalize() for p in name.split("_"))
            node.service(
                f"/{base}/{name}", f"mujoco_ros2_control_msgs/srv/{srv}", handler, on_bad=bad
            )
        for action in self.actions:
            action.open(node, bad)
        for e in self.extensions:
            e.open(node, self)

    def _publish(self) -> None:
        self._clock.publish({"clock": ros_time(self.d.time)})
        js = self.joint_state()
        self._js.publish(js)
        self._as.publish(js)
        if self._frames.moving:
            self._tf.publish(self.transforms(self._frames.moving))
        for e in self.extensions:
            e.publish()
        self.published += 1

    def run(self, ready: Callable[[], None] | None = None) -> None:
        """Step in real time (times the pace) until :attr:`stop` is set."""
        self.reset(self.home)
        self._next_publish = self.d.time
        self._tf_static.publish(self.transforms(self._frames.fixed))
        self._publish()
        if ready is not None:
            ready()
        wall0 = sim0 = 0.0
        while not self.stop.is_set():
            self._drain()
            if self.paused:
                self.stop.wait(0.005)
                continue
            if self._resync:
                wall0, sim0, self._resync = time.monotonic(), self.d.time, False
            self._step()
            ahead = (self.d.time - sim0) / self.config.pace - (time.monotonic() - wall0)
            if ahead > 0:
                self.stop.wait(ahead)
            elif ahead < -SYNC_MISALIGN:
                self._resync = True  # slower than real time: go on from here


def serve(server: Server, ready: Callable[[Server], None] | None = None) -> Server:
    """Serve until the server's :attr:`Server.stop` is set (or Ctrl-C)."""
    config = server.config
    node = Node(config.endpoints, config.domain, config.node_name, config.namespace)
    try:
        server.open(node)
        server.run(None if ready is None else lambda: ready(server))
    finally:
        server.stop.set()
        node.close()
    return server
