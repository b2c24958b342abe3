"""An excitation for calibration (``urdf2mjcf excite``): position setpoints that a user runs
on the robot to record a log good for :mod:`urdf2mjcf.calibrate`.

Each joint follows a sum of sines (frequencies ``k / duration`` Hz up to ``max_hz``,
Schroeder phases for a low peak, a different set of frequencies per joint so that their
effects can be told apart) around the middle of its range. The amplitude is cut until the
setpoints stay within 80 % of the range, under ``max_velocity``, the model, replaying
them, asks each servo for at most 90 % of its force range, and the robot's bodies do not
touch each other (deeper than :data:`SELF_CONTACT_M`) at any of the configurations sampled
every :data:`SAMPLE_S` seconds.

:func:`bag` writes the setpoints as one ``trajectory_msgs/JointTrajectory`` in a rosbag2
folder (MCAP), which ``ros2 bag play`` hands to a joint trajectory controller."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from ..errors import InputError
from . import params

SELF_CONTACT_M = 1e-3
"""m: deeper than this, two of the robot's bodies collide (a contact the model allows)."""
SAMPLE_S = 0.02
"""s: how often the setpoints are checked for self-collision."""
CONTROLLER = "joint_trajectory_controller"
"""The controller whose ``joint_trajectory`` topic a bag is written for (ros2_control's)."""


@dataclass(frozen=True)
class ExciteConfig:
    duration: float = 30.0
    """Seconds."""
    amplitude: float = 0.5
    """Largest amplitude of a joint's setpoint about its centre, rad or m."""
    max_velocity: float = 1.0
    """Largest setpoint speed, rad/s or m/s."""
    max_hz: float = 2.0
    """Highest frequency, Hz."""
    rate: float = 100.0
    """Rows per second of the CSV."""


@dataclass(frozen=True)
class Excitation:
    joints: list[str]
    actuators: list[str]
    t: np.ndarray
    """(n,) s."""
    setpoints: np.ndarray
    """(n, nu) position setpoints."""
    amplitude: float
    """The amplitude used, after the limits cut it."""
    peak_force: np.ndarray
    """(nu,) largest |force| / force range of each servo in the model's replay."""


def excite(m: Any, cfg: ExciteConfig) -> Excitation:
    """The excitation of the compiled model ``m`` (position servos on every joint)."""
    joints, actuators = params.joint_names(m), params.actuator_names(m)
    if not m.nu or any(params.gain_field(m, a) != "kp" for a in range(m.nu)):
        raise InputError(
            "excite writes position setpoints: every actuator must be a position servo"
        )
    joint_of = [int(m.actuator_trnid[a, 0]) for a in range(m.nu)]
    lo = np.array([m.jnt_range[j, 0] if m.jnt_limited[j] else -math.pi for j in joint_of])
    hi = np.array([m.jnt_range[j, 1] if m.jnt_limited[j] else math.pi for j in joint_of])
    centre, half = (lo + hi) / 2, 0.8 * (hi - lo) / 2
    qadr = [int(m.jnt_qposadr[j]) for j in joint_of]
    dt = float(m.opt.timestep)
    t = np.arange(int(round(cfg.duration / dt))) * dt
    base = 1.0 / cfg.duration
    top = max(1, int(cfg.max_hz / base))
    shape = np.zeros((len(t), m.nu))
    for a in range(m.nu):
        # every nu-th harmonic, offset by the actuator's index: no two joints share one
        ks = np.arange(1 + a, top + 1, m.nu) if top >= m.nu else np.array([1 + a])
        phases = -np.pi * np.arange(len(ks)) * (np.arange(len(ks)) + 1) / len(ks)
        s = np.sin(2 * np.pi * base * ks[None, :] * t[:, None] + phases).sum(axis=1)
        shape[:, a] = s / np.abs(s).max()
    speed = np.abs(np.gradient(shape, dt, axis=0)).max(axis=0)
    amplitude = min(cfg.amplitude, float(np.min(cfg.max_velocity / np.maximum(speed, 1e-12))))
    for _ in range(8):
        setpoints = centre + np.minimum(amplitude, half) * shape
        forces = _forces(m, qadr, setpoints)
        limit = np.where(m.actuator_forcelimited, np.abs(m.actuator_forcerange).max(axis=1), np.inf)
        peak = forces / limit
        touching = _self_contact(m, qadr, setpoints[:: max(1, int(round(SAMPLE_S / dt)))])
        if peak.max() <= 0.9 and touching is None:
            break
        amplitude *= 0.7
    else:
        if touching is not None:
            raise InputError(
                f"no excitation keeps the robot clear of itself: {touching} at the smallest "
                "amplitude tried"
            )
        raise InputError("no excitation keeps every servo under 90 % of its force range")
    every = max(1, int(round(1.0 / (cfg.rate * dt))))
    return Excitation(joints, actuators, t[::every], setpoints[::every], float(amplitude), peak)


def _forces(m: Any, qadr: list[int], setpoints: np.ndarray) -> np.ndarray:
    """Largest |actuator force| of each servo while the model follows ``setpoints`` from
    their first row."""
    d = mujoco.MjData(m)
    d.qpos[qadr] = setpoints[0]
    peak = np.zeros(m.nu)
    for row in setpoints:
        d.ctrl[:] = row
        mujoco.mj_step(m, d)
        peak = np.maximum(peak, np.abs(d.actuator_force))
    return peak


def _self_contact(m: Any, qadr: list[int], configurations: np.ndarray) -> str | None:
    """``'body a' and 'body b' 3.2 mm deep`` for the first configuration where two of the
    robot's bodies (not the world's geoms) interpenetrate deeper than
    :data:`SELF_CONTACT_M`, else None. MuJoCo's own filters apply (parent and child, the
    model's excludes and contact bits): only contacts the model would make count."""
    d = mujoco.MjData(m)
    for row in configurations:
        d.qpos[qadr] = row
        mujoco.mj_forward(m, d)
        for c in d.contact[: d.ncon]:
            b1, b2 = (int(m.geom_bodyid[g]) for g in c.geom)
            if b1 == 0 or b2 == 0 or c.dist >= -SELF_CONTACT_M:
                continue
            a, b = sorted((m.body(b1).name, m.body(b2).name))
            return f"'{a}' and '{b}' {-c.dist * 1e3:.1f} mm deep"
    return None


def bag(e: Excitation, m: Any, dest: Any, controller: str = CONTROLLER) -> None:
    """Write the setpoints into a new rosbag2 folder ``dest`` (MCAP storage) as one
    ``trajectory_msgs/JointTrajectory`` on ``/<controller>/joint_trajectory``: the joints
    the actuators drive, each point's positions and velocities at its ``time_from_start``
    (needs the ``calibrate`` extra's rosbags)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    traj_t = types["trajectory_msgs/msg/JointTrajectory"]
    point_t = types["trajectory_msgs/msg/JointTrajectoryPoint"]
    time_t = types["builtin_interfaces/msg/Time"]
    duration_t = types["builtin_interfaces/msg/Duration"]
    header = types["std_msgs/msg/Header"](stamp=time_t(sec=0, nanosec=0), frame_id="")
    joints = [m.joint(int(m.actuator_trnid[a, 0])).name for a in range(m.nu)]
    velocities = np.gradient(e.setpoints, e.t, axis=0) if len(e.t) > 1 else e.setpoints * 0
    empty = np.zeros(0)
    points = []
    for t, q, v in zip(e.t, e.setpoints, velocities, strict=True):
        ns = int(round(float(t) * 1e9))
        points.append(
            point_t(
                positions=np.asarray(q, float),
                velocities=np.asarray(v, float),
                accelerations=empty,
                effort=empty,
                time_from_start=duration_t(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000),
            )
        )
    msg = traj_t(header=header, joint_names=joints, points=points)
    with Writer(dest, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        topic = f"/{controller}/joint_trajectory"
        conn = w.add_connection(topic, traj_t.__msgtype__, typestore=store)
        w.write(conn, 0, store.serialize_cdr(msg, traj_t.__msgtype__))


def csv_text(e: Excitation) -> str:
    """``t,u.<actuator>...``: the setpoints, one row per sample."""
    lines = [",".join(["t", *(f"u.{a}" for a in e.actuators)])]
    for t, row in zip(e.t, e.setpoints, strict=True):
        lines.append(",".join([repr(round(float(t), 9)), *(repr(float(x)) for x in row)]))
    return "\n".join(lines) + "\n"
