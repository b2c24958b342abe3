"""ros2_control's forward and trajectory controllers, on a MuJoCo model's actuators.

The groups come from the actuators the conversion made (a position, velocity or
motor actuator on one joint): ``forward_position_controller``,
``forward_velocity_controller`` and ``forward_effort_controller`` (the names of
ros2_control's demos) each take a ``std_msgs/Float64MultiArray`` on
``/<group>/commands``, one value per joint in the model's actuator order;
``joint_trajectory_controller`` takes ``trajectory_msgs/JointTrajectory`` on
``/joint_trajectory_controller/joint_trajectory`` for the position group. A command
that cannot be one (wrong length, NaN, unknown joint, times not increasing) raises
:class:`BadCommand`, and the caller drops it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from ..errors import BadCommand

KINDS = ("position", "velocity", "effort")
GROUP_NAME = {k: f"forward_{k}_controller" for k in KINDS}
TRAJECTORY_CONTROLLER = "joint_trajectory_controller"


@dataclass(frozen=True)
class Group:
    """One forward controller: its actuators and their joints, in model order."""

    name: str
    kind: str
    """``position``, ``velocity`` or ``effort``."""
    joints: tuple[str, ...]
    actuators: tuple[int, ...]
    low: np.ndarray = field(repr=False)
    """(n,) the actuators' lowest command (-inf where unlimited)."""
    high: np.ndarray = field(repr=False)


def actuator_kind(m: mujoco.MjModel, a: int) -> str | None:
    """What ros2_control command interface actuator ``a`` is: a position servo (bias
    -kp q), a velocity servo (bias -kv qdot only), a motor (no bias); None for an
    actuator on anything but one joint."""
    if m.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
        return None
    if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE:
        return "effort"
    if m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE:
        if m.actuator_biasprm[a, 1] != 0:
            return "position"
        if m.actuator_biasprm[a, 2] != 0:
            return "velocity"
    return None


def groups(m: mujoco.MjModel, exclude: frozenset[int] = frozenset()) -> list[Group]:
    """The forward controllers the model's actuators (but ``exclude``) make, one per
    kind present."""
    by_kind: dict[str, list[int]] = {k: [] for k in KINDS}
    for a in range(m.nu):
        kind = None if a in exclude else actuator_kind(m, a)
        if kind is not None:
            by_kind[kind].append(a)
    out = []
    for kind, acts in by_kind.items():
        if not acts:
            continue
        low = np.array(
            [m.actuator_ctrlrange[a, 0] if m.actuator_ctrllimited[a] else -np.inf for a in acts]
        )
        high = np.array(
            [m.actuator_ctrlrange[a, 1] if m.actuator_ctrllimited[a] else np.inf for a in acts]
        )
        joints = tuple(
            mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(m.actuator_trnid[a, 0])) or ""
            for a in acts
        )
        out.append(Group(GROUP_NAME[kind], kind, joints, tuple(acts), low, high))
    return out


def forward_command(group: Group, data: Sequence[float]) -> np.ndarray:
    """A ``Float64MultiArray``'s data as the group's commands (unclipped)."""
    if len(data) != len(group.joints):
        raise BadCommand(f"{len(data)} values for the {len(group.joints)} joints of {group.name}")
    values = np.asarray(data, dtype=float)
    if not np.all(np.isfinite(values)):
        raise BadCommand("a value that is not a finite number")
    return values


@dataclass(frozen=True)
class Trajectory:
    """A trajectory to follow on the simulated clock: joint indices into the group,
    knot times (s, simulated) and positions, velocities where given."""

    columns: tuple[int, ...]
    times: np.ndarray
    """(k,) simulated seconds, increasing; times[0] is when it starts, from the
    commands held then."""
    positions: np.ndarray
    """(k, n)"""
    velocities: np.ndarray | None
    """(k, n), or None: straight segments."""

    def sample(self, t: float) -> np.ndarray:
        """Positions at simulated time ``t`` (held at either end)."""
        ts = self.times
        if t <= ts[0]:
            return self.positions[0].copy()
        if t >= ts[-1]:
            return self.positions[-1].copy()
        i = int(np.searchsorted(ts, t, side="right")) - 1
        h = ts[i + 1] - ts[i]
        s = (t - ts[i]) / h
        p0, p1 = self.positions[i], self.positions[i + 1]
        if self.velocities is None:
            return p0 + s * (p1 - p0)
        v0, v1 = self.velocities[i] * h, self.velocities[i + 1] * h
        # cubic Hermite: positions and velocities at both knots
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * p0 + h10 * v0 + h01 * p1 + h11 * v1

    def rates(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Velocities and accelerations at simulated time ``t``: the derivatives of
        :meth:`sample` (zero where it holds, before the start and after the end)."""
        ts = self.times
        n = self.positions.shape[1]
        if t <= ts[0] or t >= ts[-1]:
            return np.zeros(n), np.zeros(n)
        i = int(np.searchsorted(ts, t, side="right")) - 1
        h = ts[i + 1] - ts[i]
        s = (t - ts[i]) / h
        p0, p1 = self.positions[i], self.positions[i + 1]
        if self.velocities is None:
            return (p1 - p0) / h, np.zeros(n)
        v0, v1 = self.velocities[i] * h, self.velocities[i + 1] * h
        d00, d10, d01, d11 = (
            6 * s**2 - 6 * s,
            3 * s**2 - 4 * s + 1,
            -6 * s**2 + 6 * s,
            3 * s**2 - 2 * s,
        )
        a00, a10, a01, a11 = 12 * s - 6, 6 * s - 4, -12 * s + 6, 6 * s - 2
        velocity = (d00 * p0 + d10 * v0 + d01 * p1 + d11 * v1) / h
        acceleration = (a00 * p0 + a10 * v0 + a01 * p1 + a11 * v1) / h**2
        return velocity, acceleration

    @property
    def end(self) -> float:
        return float(self.times[-1])


def _seconds(d: dict) -> float:
    return float(d.get("sec", 0)) + float(d.get("nanosec", 0)) * 1e-9


def trajectory(group: Group, msg: dict, now: float, current: np.ndarray) -> Trajectory:
    """A ``JointTrajectory`` message for the position ``group``: it starts at its
    header's stamp (simulated time; zero: now) from the ``current`` commands."""
    names = list(msg.get("joint_names", []))
    points = msg.get("points", [])
    if not names or not points:
        raise BadCommand("a trajectory without joints or points")
    unknown = [n for n in names if n not in group.joints]
    if unknown:
        raise BadCommand(
            f"joint(s) {', '.join(unknown)} not in {group.name}: {', '.join(group.joints)}"
        )
    if len(set(names)) != len(names):
        raise BadCommand("a joint named twice")
    columns = tuple(group.joints.index(n) for n in names)
    stamp = _seconds(msg.get("header", {}).get("stamp", {}))
    start = stamp if stamp > 0 else now
    times = [start + _seconds(p.get("time_from_start", {})) for p in points]
    pos = [list(p.get("positions", [])) for p in points]
    if any(len(p) != len(names) for p in pos):
        raise BadCommand(f"a point whose positions are not one per joint ({len(names)})")
    vel_given = all(len(p.get("velocities", [])) == len(names) for p in points)
    if not vel_given and any(p.get("velocities") for p in points):
        raise BadCommand("velocities given for some points or joints only")
    if any(math.isnan(t) for t in times) or times[0] < start:
        raise BadCommand("a point before the trajectory's start")
    if any(b <= a for a, b in zip(times, times[1:], strict=False)):
        raise BadCommand("point times that do not increase")
    positions = np.array(pos, dtype=float)
    velocities = np.array([p["velocities"] for p in points], dtype=float) if vel_given else None
    if not np.all(np.isfinite(positions)) or (
        velocities is not None and not np.all(np.isfinite(velocities))
    ):
        raise BadCommand("a value that is not a finite number")
    here = current[list(columns)]
    if times[0] > start:  # from where the joints are commanded now to the first point
        times = [start, *times]
        positions = np.vstack([here, positions])
        if velocities is not None:
            velocities = np.vstack([np.zeros(len(names)), velocities])
    return Trajectory(columns, np.array(times), positions, velocities)
