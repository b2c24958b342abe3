"""How far a rover's odometry drifts from the truth: the figures of one task (position
and heading error it added, per metre driven), each rover's paths (true, wheel
odometry, wheel + IMU) and their plot (``rover-drive --plot``)."""

from __future__ import annotations

import math
import os
import struct
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from ...errors import OutputError
from ...output import check_output_file, read_own
from .odometry import true_pose, wrap_angle
from .roles import Rover
from .state import SimState

GENERATOR = "rover-drive"
"""The PNG ``Software`` text of our plots: a plot saying so is ours to replace."""
MIN_PATH = 0.01
"""m: a task whose true path is shorter has no figures per metre (None)."""
MIN_TURN = 1.0
"""deg: a task that turned less has no heading error per degree turned (None)."""
SAMPLE_EVERY = 0.05
"""s simulated between two points of a path."""
_PNG = b"\x89PNG\r\n\x1a\n"


def _per(value: float, amount: float, least: float) -> float | None:
    return value / amount if amount >= least else None


class DriftStart:
    """Where the odometry and the truth stood when a task began: the task's drift is what
    its own motion added, as if the odometry had been set to the truth at its start."""

    def __init__(self, sim: SimState, rover: Rover):
        odo = sim.odometry[rover.name]
        pose = true_pose(sim.m, sim.d, rover)
        self.odo = (odo.x, odo.y, odo.yaw, odo.turned)
        self.fused = odo.fused.copy()
        self.true = (pose.x, pose.y, pose.yaw)
        self.xyz = sim.d.xpos[rover.base].copy()

    def figures(self, sim: SimState, rover: Rover, path: float, turned: float) -> dict[str, Any]:
        """The drift added since the start, ``path`` (m) and ``turned`` (rad, unwrapped)
        being the true base's path length and turn over the task."""
        odo = sim.odometry[rover.name]
        pose = true_pose(sim.m, sim.d, rover)
        # each displacement in its own start frame: an earlier heading error is not counted
        moved_odo = _local(odo.x - self.odo[0], odo.y - self.odo[1], self.odo[2])
        moved_true = _local(pose.x - self.true[0], pose.y - self.true[1], self.true[2])
        position = float(np.linalg.norm(moved_odo - moved_true))
        # unwrapped: a wheel count of 464 deg for a 90 deg turn is 374 deg off, not 14
        heading = math.degrees((odo.turned - self.odo[3]) - turned)
        fused = float(
            np.linalg.norm((odo.fused - self.fused) - (sim.d.xpos[rover.base] - self.xyz))
        )
        turned_deg = math.degrees(turned)
        return {
            "path_m": path,
            "turned_deg": turned_deg,
            "position_m": position,
            "position_per_m": _per(position, path, MIN_PATH),
            "heading_deg": heading,
            "heading_per_m_deg": _per(abs(heading), path, MIN_PATH),
            "heading_per_deg_turned": _per(abs(heading), abs(turned_deg), MIN_TURN),
            "fused_position_m": fused,
            "fused_position_per_m": _per(fused, path, MIN_PATH),
        }


def _local(dx: float, dy: float, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * dx + s * dy, -s * dx + c * dy])


def drift_line(rover: str, task: str, drift: Mapping[str, Any]) -> str:
    """One line of a task's drift for the printed summary."""
    per_m = drift["position_per_m"]
    per_turn = drift["heading_per_deg_turned"]
    head = (
        f" ({per_turn:.2f} deg per deg turned)"
        if per_turn is not None  # a turn: per metre would say little
        else f" ({drift['heading_per_m_deg']:.3f} deg/m)"
        if drift["heading_per_m_deg"] is not None
        else ""
    )
    return (
        f"{rover}: {task} drift over {drift['path_m']:.3f} m driven, "
        f"{drift['turned_deg']:.1f} deg turned: position {drift['position_m']:.3f} m"
        + (f" ({100 * per_m:.2f} % of the path)" if per_m is not None else "")
        + f", heading {drift['heading_deg']:+.2f} deg"
        + head
        + f"; wheel + IMU {drift['fused_position_m']:.3f} m"
    )


class PathLog:
    """Each rover's true, wheel-odometry and wheel + IMU positions in the plane, and the
    wheels' heading error (deg, unwrapped), every ``SAMPLE_EVERY`` s of simulated time;
    ``step`` goes into ``RoverSim.on_step``."""

    def __init__(self, sim: SimState, rovers: Mapping[str, Rover]):
        self.sim, self.rovers = sim, dict(rovers)
        self.every = max(1, int(round(SAMPLE_EVERY / float(sim.m.opt.timestep))))
        self.steps = 0
        self.paths: dict[str, dict[str, list[tuple[float, float]]]] = {
            n: {"true": [], "odometry": [], "fused": [], "heading": []} for n in self.rovers
        }
        self.t0 = float(sim.d.time)
        # the true turn, unwrapped sample to sample, and the wheels' at the start
        self._yaw = {n: true_pose(sim.m, sim.d, r).yaw for n, r in self.rovers.items()}
        self._turned = dict.fromkeys(self.rovers, 0.0)
        self._odo0 = {n: sim.odometry[n].turned for n in self.rovers}
        self.sample()

    def step(self) -> None:
        self.steps += 1
        if self.steps % self.every == 0:
            self.sample()

    def sample(self) -> None:
        for name, r in self.rovers.items():
            odo, p = self.sim.odometry[name], self.sim.d.xpos[r.base]
            rows = self.paths[name]
            rows["true"].append((float(p[0]), float(p[1])))
            rows["odometry"].append((odo.x, odo.y))
            rows["fused"].append((float(odo.fused[0]), float(odo.fused[1])))
            yaw = true_pose(self.sim.m, self.sim.d, r).yaw
            self._turned[name] += wrap_angle(yaw - self._yaw[name])
            self._yaw[name] = yaw
            error = odo.turned - self._odo0[name] - self._turned[name]
            rows["heading"].append((float(self.sim.d.time) - self.t0, math.degrees(error)))

    def finish(self) -> None:
        """The last point, where the run ended between two samples."""
        if self.steps % self.every:
            self.sample()


def _software(f: BinaryIO) -> str | None:
    if f.read(8) != _PNG:
        return None
    for _ in range(64):  # a few header chunks; never the whole file
        head = f.read(8)
        if len(head) < 8:
            return None
        size, kind = struct.unpack(">I4s", head)
        if kind == b"IDAT" or size > 65536:
            return None
        body = f.read(size + 4)[:size]
        if kind == b"tEXt" and b"\0" in body:
            key, _, value = body.partition(b"\0")
            if key == b"Software":
                return value.decode("latin-1")
    return None


def plotted_by(path: Path) -> str | None:
    """The ``Software`` text of a PNG file before its image data; None for anything
    else (a symlink, a FIFO or a device: never opened; not a PNG, unreadable)."""
    return read_own(path, _software)


def check_plot(plot: Path, overwrite: bool, report: Path | None = None) -> None:
    """Before the drive: matplotlib is there, ``plot`` ends in .png, is not the report,
    and an existing file there is a plot of ours (or ``overwrite``)."""
    from ...extras import require

    require("sim", "rover-drive --plot", ["matplotlib"])
    if plot.suffix.lower() != ".png":
        raise OutputError("a plot must end in .png", file=plot, element="--plot")
    if plot.is_dir():
        raise OutputError("is a folder; give the .png file to write", file=plot)
    for parent in plot.parents:  # the nearest existing folder above it must be one
        if os.path.lexists(parent):
            if not parent.is_dir():
                raise OutputError(
                    f"cannot write here: {parent} is not a folder", file=plot, element="--plot"
                )
            break
    if report is not None and os.path.abspath(report) == os.path.abspath(plot):
        raise OutputError("is the --report file too; give the plot its own", file=plot)
    ours = lambda f: _software(f) == GENERATOR  # noqa: E731
    check_output_file(plot, overwrite, ours, f"is not a plot of {GENERATOR}", "--plot")


_COLOURS = ("#1565c0", "#c62828", "#2e7d32", "#6a1b9a", "#ef6c00", "#00838f")


def write_plot(log: PathLog, tasks: Sequence[Mapping[str, Any]], path: Path) -> None:
    """A PNG of every rover's true path against its odometry (seen from above), the drift
    of each task in the legend; written to ``path`` (a reserved temporary file)."""
    import matplotlib

    matplotlib.use("Agg")  # headless; before pyplot is imported
    import matplotlib.pyplot as plt

    log.finish()
    fig, (ax, err) = plt.subplots(1, 2, figsize=(12.0, 5.5), dpi=100)
    head = err.twinx()
    try:
        for k, (name, rows) in enumerate(log.paths.items()):
            colour = _COLOURS[k % len(_COLOURS)]
            label = f"{name}: " if len(log.paths) > 1 else ""
            for key, style, what in (
                ("true", "-", "true path"),
                ("odometry", "--", "wheel odometry"),
                ("fused", ":", "wheel + IMU"),
            ):
                xy = np.array(rows[key])
                ax.plot(xy[:, 0], xy[:, 1], style, color=colour, lw=1.6, label=label + what)
                ax.plot(xy[-1, 0], xy[-1, 1], "o" if key == "true" else "x", color=colour)
            ax.plot(*rows["true"][0], "s", color=colour, label=label + "start")
            true = np.array(rows["true"])
            t = np.array(rows["heading"])[:, 0]
            for key, style, what in (
                ("odometry", "--", "wheel odometry"),
                ("fused", ":", "wheel + IMU"),
            ):
                gap = np.linalg.norm(np.array(rows[key]) - true, axis=1)
                err.plot(t, gap, style, color=colour, lw=1.6, label=f"{label}{what}, position")
            head.plot(
                t,
                np.array(rows["heading"])[:, 1],
                "-",
                color=colour,
                alpha=0.45,
                lw=1.2,
                label=f"{label}wheel odometry, heading",
            )
        lines = [
            f"{t['rover']} {t['task']}: {t['drift']['position_m']:.3f} m, "
            f"{t['drift']['heading_deg']:+.1f} deg over {t['drift']['path_m']:.2f} m"
            for t in tasks
            if "drift" in t
        ]
        ax.set_title("odometry drift" + ("\n" + "\n".join(lines) if lines else ""), fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(fontsize="small", loc="best")
        err.set_xlabel("time since the odometry started (s)")
        err.set_ylabel("position error in the plane (m)")
        head.set_ylabel("heading error, wheel odometry (deg)")
        err.grid(True, lw=0.4, alpha=0.5)
        err.set_title("odometry against the truth", fontsize=9)
        handles = err.get_legend_handles_labels()
        more = head.get_legend_handles_labels()
        err.legend(handles[0] + more[0], handles[1] + more[1], fontsize="small", loc="upper left")
        fig.tight_layout()
        # our mark, and no version: the same drive gives the same bytes
        fig.savefig(path, format="png", metadata={"Software": GENERATOR})
    finally:
        plt.close(fig)
