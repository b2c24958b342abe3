"""A robot's log (CSV) as typed arrays, checked against the model and resampled.

The CSV's header is ``t`` (seconds), then ``q.<joint>`` and ``v.<joint>`` (measured
position and velocity, rad or m and per second) and ``u.<actuator>`` (the command sent to
each actuator, in its own unit); a floating base's state is ``q.<base>.x`` ..
``q.<base>.qz`` and ``v.<base>.vx`` .. ``v.<base>.wz`` (:data:`.params.BASE_Q`,
:data:`.params.BASE_V`). Samples need not be sorted or evenly spaced: a sample with
a NaN is dropped from that column, repeated times keep their first sample, and every column
is interpolated onto the model's timestep (positions and velocities linearly, commands held
as a real drive holds the last command it received).
"""

from __future__ import annotations

import csv
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .. import untrusted
from ..errors import InputError
from .params import BASE_Q, BASE_V, Base

log = logging.getLogger(__name__)

MAX_GAP = 10.0
"""A gap longer than this many median sample intervals is warned about (bridged, not
measured)."""


@dataclass(frozen=True)
class Log:
    """One log as read: each column's own samples (NaNs dropped, times sorted)."""

    path: Path
    q: dict[str, tuple[np.ndarray, np.ndarray]]
    """joint -> (times (n,) s, positions (n,) rad or m)."""
    v: dict[str, tuple[np.ndarray, np.ndarray]]
    """joint -> (times (n,) s, velocities (n,) rad/s or m/s)."""
    u: dict[str, tuple[np.ndarray, np.ndarray]]
    """actuator -> (times (n,) s, commands (n,), in the actuator's unit)."""
    start: float
    """First time of the log, s."""
    end: float
    """Last time of the log, s."""


@dataclass(frozen=True)
class Trajectory:
    """A log on the model's time grid: row ``k`` is time ``t0 + k * dt``."""

    name: str
    """Where it came from (the file, and the part of it)."""
    dt: float
    """Model timestep, s."""
    q: np.ndarray
    """(n, njoint) measured positions, the model's joint order."""
    v: np.ndarray
    """(n, njoint) measured velocities."""
    u: np.ndarray
    """(n, nu) commands, the model's actuator order; row k acts from step k to k + 1."""
    base_q: np.ndarray | None = None
    """(n, 7) a floating base's measured position and unit quaternion (``params.BASE_Q``);
    None for a fixed base."""
    base_v: np.ndarray | None = None
    """(n, 6) its measured velocity (``params.BASE_V``)."""
    sampled: np.ndarray | None = None
    """(n,) whether each row's state is a sample of every signal (within a quarter step), not
    interpolated between samples (a log slower than the model, a gap, a NaN); None: all."""

    def rows(self, name: str, part: slice) -> Trajectory:
        """The rows ``part`` of this trajectory, named ``name``."""
        base_q = None if self.base_q is None else self.base_q[part]
        base_v = None if self.base_v is None else self.base_v[part]
        sampled = None if self.sampled is None else self.sampled[part]
        return Trajectory(
            name, self.dt, self.q[part], self.v[part], self.u[part], base_q, base_v, sampled
        )

    def split(self, fraction: float) -> tuple[Trajectory, Trajectory]:
        """The first ``1 - fraction`` of the rows and the rest (held out)."""
        cut = int(round(len(self.q) * (1.0 - fraction)))
        return (
            self.rows(f"{self.name} (fitted part)", slice(None, cut)),
            self.rows(f"{self.name} (held out)", slice(cut, None)),
        )


def read_csv(path: Path) -> Log:
    """The CSV log at ``path``; :class:`InputError` naming the file and column (or line)
    when it cannot be used."""
    raw = untrusted.read_file(path, "log", error=InputError, what="log")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError("cannot read log: not a text file", file=path) from None
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise InputError("log is empty: expected a header 't,q.<joint>,...'", file=path)
    header = [h.strip() for h in rows[0]]
    if not header or header[0] != "t":
        raise InputError(
            "the first column of the header must be 't' (seconds), then q.<joint>, "
            "v.<joint>, u.<actuator>",
            file=path,
            element="line 1",
        )
    seen: set[str] = set()
    for name in header[1:]:
        kind, _, target = name.partition(".")
        if kind not in ("q", "v", "u") or not target:
            raise InputError(
                f"column {untrusted.excerpt(name, 60)!r}: expected q.<joint>, v.<joint> or "
                "u.<actuator>",
                file=path,
                element="line 1",
            )
        if name in seen:
            raise InputError(f"column {name!r} given twice", file=path, element="line 1")
        seen.add(name)
    data = np.full((len(rows) - 1, len(header)), np.nan)
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputError(
                f"{len(row)} values where the header has {len(header)} columns",
                file=path,
                element=f"line {i + 2}",
            )
        for j, cell in enumerate(row):
            cell = cell.strip()
            if cell.lower() in ("", "nan"):
                continue
            try:
                data[i, j] = float(cell)
            except ValueError:
                raise InputError(
                    f"column {header[j]!r}: {untrusted.excerpt(cell, 30)!r} is not a number",
                    file=path,
                    element=f"line {i + 2}",
                ) from None
            if not math.isfinite(data[i, j]):
                raise InputError(
                    f"column {header[j]!r}: {cell!r} is not a finite number",
                    file=path,
                    element=f"line {i + 2}",
                )
    return _columns(path, header, data, sparse=False)


def _columns(path: Path, header: list[str], data: np.ndarray, *, sparse: bool) -> Log:
    """A :class:`Log` of the rows ``data`` under ``header`` (``t`` first; NaN: no sample);
    ``sparse``: rows of messages that each fill only some columns (a bag), so a NaN is no
    lost sample."""
    t = data[:, 0]
    keep = np.isfinite(t)
    if not keep.all():
        log.warning("%s: %d samples without a time dropped", path, int((~keep).sum()))
    data = data[keep]
    if len(data) < 2:
        raise InputError("log has fewer than two samples", file=path)
    order = np.argsort(data[:, 0], kind="stable")
    if (order != np.arange(len(order))).any() and not sparse:
        log.warning("%s: samples are not in time order; sorted", path)
    data = data[order]
    t = data[:, 0]
    firsts = np.concatenate(([True], np.diff(t) > 0))
    if sparse:  # messages at one time on different topics are one sample
        firsts[:] = True
    if not firsts.all():
        log.warning(
            "%s: %d samples repeat a time; the first of each kept", path, int((~firsts).sum())
        )
    data, t = data[firsts], t[firsts]
    apart = np.diff(t)
    # a bag's messages on several topics share times: the step is between distinct times
    step = float(np.median(apart[apart > 0])) if (apart > 0).any() else 0.0
    gaps = apart > MAX_GAP * max(step, 1e-9)
    if gaps.any():
        at = float(t[:-1][gaps][0])
        log.warning(
            "%s: %d gaps longer than %g samples (the first at t=%.3f s) are bridged by "
            "interpolation",
            path,
            int(gaps.sum()),
            MAX_GAP,
            at,
        )
    columns: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {"q": {}, "v": {}, "u": {}}
    for j, name in enumerate(header[1:], start=1):
        kind, _, target = name.partition(".")
        ok = np.isfinite(data[:, j])
        if ok.sum() < 2:
            raise InputError(f"column {name!r} has fewer than two numbers", file=path)
        if not ok.all() and not sparse:
            log.warning("%s: column %s: %d NaN samples dropped", path, name, int((~ok).sum()))
        columns[kind][target] = (t[ok], data[ok, j])
    return Log(path, columns["q"], columns["v"], columns["u"], float(t[0]), float(t[-1]))


BAG_SUFFIXES = (".mcap", ".db3")
JOINT_STATE = "sensor_msgs/msg/JointState"
COMMANDS = "std_msgs/msg/Float64MultiArray"
ODOMETRY = "nav_msgs/msg/Odometry"
TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
TRAJECTORY_RATE = 1000.0
"""Hz: a trajectory's setpoints are sampled this often between its points (linearly, as a
joint trajectory controller interpolates them) before the log is resampled."""


def read(
    path: Path,
    actuators: list[str],
    servos: Mapping[str, str] | None = None,
    base: Base | None = None,
) -> Log:
    """A log: a ROS 2 bag (a folder, ``.mcap`` or ``.db3``) or else a CSV file."""
    if path.is_dir() or path.suffix.lower() in BAG_SUFFIXES:
        return read_bag(path, actuators, servos or {}, base)
    return read_csv(path)


def read_bag(
    path: Path,
    actuators: list[str],
    servos: Mapping[str, str] | None = None,
    base: Base | None = None,
) -> Log:
    """A rosbag2 (MCAP or SQLite): ``sensor_msgs/JointState`` messages give each joint's
    position and velocity at their header stamp (the bag's time where it is zero); the
    commands come from one ``std_msgs/Float64MultiArray`` topic (a ros2_control forward
    command controller's: one value per actuator in the model's order) or, where the bag has
    none, from ``trajectory_msgs/JointTrajectory`` messages (a joint trajectory
    controller's: each point's positions at its ``time_from_start`` after the message's
    stamp, interpolated linearly, a later trajectory replacing the rest of an earlier one)
    for the position servos ``servos`` names (joint -> actuator). A floating ``base``'s
    state comes from one ``nav_msgs/Odometry`` topic (:func:`_odometry`). Messages are
    sorted by time."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    if not path.is_dir():  # a regular file within the log size limit (a FIFO never blocks)
        untrusted.check_regular(path, "log", error=InputError, what="bag")
    try:
        reader = AnyReader([path], default_typestore=store)
        reader.open()
    except Exception as exc:  # rosbags' own errors name what it could not read
        raise InputError(f"cannot read bag: {exc}", file=path) from None
    try:
        states = [c for c in reader.connections if c.msgtype == JOINT_STATE]
        commands = [c for c in reader.connections if c.msgtype == COMMANDS]
        trajectories = [c for c in reader.connections if c.msgtype == TRAJECTORY]
        odometry = _odometry_topic(path, reader, base)
        if not states:
            raise InputError(f"bag has no {JOINT_STATE} topic", file=path)
        if not commands and trajectories:
            return _with_trajectories(
                path, reader, states + odometry, trajectories, servos or {}, base
            )
        if len(commands) != 1:
            found = ", ".join(sorted(c.topic for c in commands)) or "none"
            raise InputError(
                f"bag needs one {COMMANDS} topic of commands (a forward command "
                f"controller's); it has {found}",
                file=path,
            )
        index: dict[str, int] = {"t": 0}
        rows: list[dict[int, float]] = []
        frames: set[str] = set()
        for conn, stamp, raw in reader.messages(connections=states + odometry + commands):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            row: dict[int, float] = {}
            if conn.msgtype in (JOINT_STATE, ODOMETRY):
                head = msg.header.stamp
                t_ns = head.sec * 1_000_000_000 + head.nanosec or stamp
                _state(path, conn.msgtype, conn.topic, msg, base, index, row, frames)
            else:
                t_ns = stamp
                if len(msg.data) != len(actuators):
                    raise InputError(
                        f"{conn.topic}: a command of {len(msg.data)} values; the model has "
                        f"{len(actuators)} actuators",
                        file=path,
                    )
                for name, value in zip(actuators, msg.data, strict=True):
                    row[index.setdefault(f"u.{name}", len(index))] = float(value)
            row[0] = t_ns * 1e-9
            rows.append(row)
    finally:
        reader.close()
    _check_frames(path, frames, base)
    data = np.full((len(rows), len(index)), np.nan)
    for i, row in enumerate(rows):
        for j, value in row.items():
            data[i, j] = value
    return _columns(path, list(index), data, sparse=True)


def _with_trajectories(
    path: Path,
    reader: Any,
    states: list,
    trajectories: list,
    servos: Mapping[str, str],
    base: Base | None,
) -> Log:
    """:func:`read_bag`'s log where the commands are joint trajectories (``states``: the
    JointState and Odometry topics)."""
    index: dict[str, int] = {"t": 0}
    rows: list[dict[int, float]] = []
    frames: set[str] = set()
    plans: list[tuple[float, list[str], np.ndarray, np.ndarray]] = []
    for conn, stamp, raw in reader.messages(connections=states + trajectories):
        msg: Any = reader.deserialize(raw, conn.msgtype)
        head = msg.header.stamp
        t_ns = head.sec * 1_000_000_000 + head.nanosec or stamp
        if conn.msgtype in (JOINT_STATE, ODOMETRY):
            row: dict[int, float] = {0: t_ns * 1e-9}
            _state(path, conn.msgtype, conn.topic, msg, base, index, row, frames)
            rows.append(row)
            continue
        unknown = [j for j in msg.joint_names if j not in servos]
        if unknown:
            raise InputError(
                f"{conn.topic}: joint {untrusted.excerpt(unknown[0], 40)!r} has no position "
                f"servo in the model; its position servos drive {_names(sorted(servos))}",
                file=path,
            )
        offsets = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points]
        if not offsets:
            continue
        positions = np.array([list(p.positions) for p in msg.points], dtype=float)
        if positions.shape != (len(offsets), len(msg.joint_names)) or np.any(
            np.diff(offsets) <= 0
        ):
            raise InputError(
                f"{conn.topic}: a trajectory whose points do not each give every joint's "
                "position at increasing times",
                file=path,
            )
        plans.append((t_ns * 1e-9, list(msg.joint_names), np.asarray(offsets), positions))
    _check_frames(path, frames, base)
    plans.sort(key=lambda p: p[0])
    for k, (start, names, times, positions) in enumerate(plans):
        end = start + times[-1]
        if k + 1 < len(plans):
            end = min(end, plans[k + 1][0] - 1.0 / TRAJECTORY_RATE)
        grid = np.arange(start + times[0], end + 1e-12, 1.0 / TRAJECTORY_RATE)
        for t in grid:
            rows.append({0: float(t)})
        cols = [index.setdefault(f"u.{servos[n]}", len(index)) for n in names]
        first = len(rows) - len(grid)
        for c, j in zip(cols, range(len(names)), strict=True):
            values = np.interp(grid - start, times, positions[:, j])
            for i, value in enumerate(values):
                rows[first + i][c] = float(value)
    data = np.full((len(rows), len(index)), np.nan)
    for i, row in enumerate(rows):
        for j, value in row.items():
            data[i, j] = value
    return _columns(path, list(index), data, sparse=True)


def _odometry_topic(path: Path, reader: Any, base: Base | None) -> list:
    """The bag's one ``nav_msgs/Odometry`` connection for a floating ``base`` (none for a
    fixed base, whose bag's odometry is not the model's to replay)."""
    found = [c for c in reader.connections if c.msgtype == ODOMETRY]
    if base is None or not found:
        return []
    if len({c.topic for c in found}) > 1:
        raise InputError(
            f"bag has {ODOMETRY} on {_names(sorted({c.topic for c in found}))}: the base's "
            "state must come from one topic (record only the odometry of the base's own "
            "pose, such as a motion-capture system's or the simulator's ground truth)",
            file=path,
        )
    return found


def _state(
    path: Path,
    msgtype: str,
    topic: str,
    msg: Any,
    base: Base | None,
    index: dict[str, int],
    row: dict[int, float],
    frames: set[str],
) -> None:
    """Fill ``row`` (column index -> value, ``index`` growing as columns appear) from one
    JointState or Odometry message (whose ``child_frame_id`` joins ``frames``)."""
    if msgtype == JOINT_STATE:
        for i, name in enumerate(msg.name):
            for kind, values in (("q", msg.position), ("v", msg.velocity)):
                if i < len(values):
                    row[index.setdefault(f"{kind}.{name}", len(index))] = float(values[i])
        return
    assert base is not None  # _odometry_topic reads none for a fixed base
    frames.add(str(msg.child_frame_id))
    pose, twist = _odometry(path, topic, msg, base)
    for kind, names, values in (("q", BASE_Q, pose), ("v", BASE_V, twist)):
        for name, value in zip(names, values, strict=True):
            row[index.setdefault(f"{kind}.{base.joint}.{name}", len(index))] = float(value)


def _check_frames(path: Path, frames: set[str], base: Base | None) -> None:
    """Warn where the odometry is of another frame than the base's body (read as the
    body's: a ``base_footprint`` under a ``base_link`` differs by an offset)."""
    other = sorted(f for f in frames if f and base is not None and f != base.body)
    if other and base is not None:
        log.warning(
            "%s: the odometry is of frame %s; the model's free joint moves body %r: read "
            "as that body's pose and twist",
            path,
            _names(other),
            untrusted.excerpt(base.body, 60),
        )


def _odometry(path: Path, topic: str, msg: Any, base: Base) -> tuple[np.ndarray, np.ndarray]:
    """A ``nav_msgs/Odometry`` message as MuJoCo's free joint holds the base's state
    (:data:`~.params.BASE_Q`, :data:`~.params.BASE_V`). The pose is the base frame's in
    the world (the message's ``header.frame_id``, an ``odom`` or ``map`` frame with z up
    as REP 105 has it, taken as the model's world); the twist is in the base's own frame
    (``child_frame_id``, as the message defines it), so its linear part is turned into the
    world as the free joint holds it, and the angular part is kept."""
    pose, twist = msg.pose.pose, msg.twist.twist
    quat = np.array(
        [pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z]
    )
    norm = float(np.linalg.norm(quat))
    if not math.isfinite(norm) or not 0.5 < norm < 1.5:
        raise InputError(
            f"{topic}: an Odometry orientation that is not a unit quaternion "
            f"(|q| = {norm:.3g})",
            file=path,
        )
    quat /= norm
    linear = _rotate(quat, np.array([twist.linear.x, twist.linear.y, twist.linear.z]))
    q = np.array([pose.position.x, pose.position.y, pose.position.z, *quat])
    v = np.array([*linear, twist.angular.x, twist.angular.y, twist.angular.z])
    return q, v


def _rotate(quat: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """``vec`` turned by the unit quaternion ``quat`` (w, x, y, z)."""
    w, u = quat[0], quat[1:]
    return vec + 2.0 * w * np.cross(u, vec) + 2.0 * np.cross(u, np.cross(u, vec))


def resample(
    found: Log, joints: list[str], actuators: list[str], dt: float, floating: Base | None = None
) -> Trajectory:
    """``found`` on a grid of step ``dt`` (the model's timestep), columns in the model's
    order; :class:`InputError` when it does not describe this model: a joint or actuator
    the log lacks, or no column of the model at all (a log of another robot). ``base``: the
    model's floating base, whose state the log must hold too (``q.<base>.x`` ..
    ``v.<base>.wz``, :data:`~.params.BASE_Q` and :data:`~.params.BASE_V`)."""
    base = floating.joint if floating else None
    path = found.path
    base_q = [f"{base}.{c}" for c in BASE_Q] if base else []
    base_v = [f"{base}.{c}" for c in BASE_V] if base else []
    named = set(found.q) | set(found.v) | set(found.u)
    ours = set(joints) | set(actuators) | set(base_q) | set(base_v)
    if not named & ours:
        raise InputError(
            "log names none of the model's joints or actuators (a log of another robot?): "
            f"log has {_names(sorted(named))}; model has {_names(joints)}",
            file=path,
        )
    unknown = sorted(set(found.q) - set(joints) - set(base_q)) + sorted(
        set(found.u) - set(actuators)
    )
    if unknown:
        log.warning(
            "%s: columns of no joint or actuator of the model ignored: %s", path, _names(unknown)
        )
    lacking = [f"q.{j}" for j in joints if j not in found.q]
    lacking += [f"u.{a}" for a in actuators if a not in found.u]
    if lacking:
        raise InputError(
            f"log lacks {_names(lacking)}: every joint's position and every actuator's "
            "command must be logged to replay it",
            file=path,
        )
    lacking = [f"q.{c}" for c in base_q if c not in found.q]
    lacking += [f"v.{c}" for c in base_v if c not in found.v]
    if lacking:
        raise InputError(
            f"log lacks {_names(lacking)}: the model's base is free (joint "
            f"'{untrusted.excerpt(base or '', 60)}'), and its state (position, orientation "
            "and velocity, as q.<base>.x .. v.<base>.wz) must be logged to replay it; a "
            "bag gives it as one nav_msgs/Odometry topic (see docs/calibrate.md)",
            file=path,
        )
    n = int(math.floor((found.end - found.start) / dt + 1e-9)) + 1
    if n < 3:
        raise InputError(f"log is shorter than three model timesteps ({dt:g} s)", file=path)
    grid = found.start + dt * np.arange(n)
    sampled = _sampled(
        grid,
        [found.q[c][0] for c in [*joints, *base_q]]
        + [found.v[c][0] for c in [*joints, *base_v] if c in found.v],
        dt,
    )
    q = np.column_stack([np.interp(grid, *found.q[j]) for j in joints])
    vs = []
    for j, name in enumerate(joints):
        if name in found.v:
            vs.append(np.interp(grid, *found.v[name]))
        else:
            log.warning("%s: no v.%s: velocity taken from the positions' differences", path, name)
            vs.append(np.gradient(q[:, j], dt))
    u = (
        np.column_stack([_hold(grid, *found.u[a]) for a in actuators])
        if actuators
        else np.zeros((n, 0))
    )
    if not base:
        return Trajectory(str(path), dt, q, np.column_stack(vs), u, sampled=sampled)
    pose = np.column_stack([np.interp(grid, *found.q[c]) for c in base_q])
    norm = np.linalg.norm(pose[:, 3:], axis=1)
    if np.any(norm < 0.5) or np.any(norm > 1.5):
        raise InputError(
            f"columns q.{base_q[3]} .. q.{base_q[6]} are not a unit quaternion (w, x, y, z)",
            file=path,
        )
    pose[:, 3:] /= norm[:, None]  # interpolated between samples: back onto the unit sphere
    twist = np.column_stack([np.interp(grid, *found.v[c]) for c in base_v])
    return Trajectory(str(path), dt, q, np.column_stack(vs), u, pose, twist, sampled)


def _sampled(grid: np.ndarray, times: list[np.ndarray], dt: float) -> np.ndarray:
    """Whether each grid time is within a quarter of ``dt`` of a sample of every signal
    (each signal's sorted times, two at least: `_columns` refuses fewer)."""
    ok = np.ones(len(grid), dtype=bool)
    for t in times:
        i = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
        gap = np.minimum(np.abs(t[i] - grid), np.abs(t[i - 1] - grid))
        ok &= gap <= 0.25 * dt
    return ok


def _hold(grid: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Zero-order hold: at each grid time the last sample at or before it (the first sample
    before the log's first)."""
    i = np.searchsorted(t, grid + 1e-12, side="right") - 1
    return x[np.clip(i, 0, len(x) - 1)]


def _names(names: list[str], most: int = 8) -> str:
    shown = ", ".join(untrusted.excerpt(n, 40) for n in names[:most])
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")
