"""The odometry drift of a MIRA3D drive (``rover-drive --report/--plot``): the report's
drift figures against the true base pose read from MuJoCo, the report's keys, the plot
(a PNG, ours to replace, never a user's file) and bad ``--plot`` paths."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from urdf2mjcf.runner.rover import RoverSim, Straight, Turn, rover_drive_command
from urdf2mjcf.runner.rover.drift import plotted_by

DRIFT_KEYS = {
    "path_m",
    "turned_deg",
    "position_m",
    "position_per_m",
    "heading_deg",
    "heading_per_m_deg",
    "heading_per_deg_turned",
    "fused_position_m",
    "fused_position_per_m",
}


@pytest.fixture(scope="module")
def floor(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-floor")


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), w * w + x * x - y * y - z * z)


def _local(d: np.ndarray, yaw: float) -> np.ndarray:
    """A planar displacement in a frame turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def test_drift_figures_match_the_true_pose_read_from_mujoco(floor):
    sim = RoverSim(floor)
    base = sim.rover().base
    sim.settle(1.0)
    poses = []  # the base's true (x, y, z, yaw) after every step, straight from MuJoCo

    def record(s: RoverSim) -> None:
        poses.append((*s.d.xpos[base], _yaw(s.d.xquat[base])))

    record(sim)
    straight = sim.run({"rover": Straight(4.0, speed=0.5)}, on_step=record)["rover"]
    split = len(poses)
    turn = sim.run({"rover": Turn(math.radians(45), rate=math.radians(30))}, on_step=record)[
        "rover"
    ]
    p = np.array(poses)
    assert np.allclose(p[-1, :3], sim.d.xpos[base]), "the report is the state at the end"
    for report, part in ((straight, p[:split]), (turn, p[split - 1 :])):
        d = report.drift
        assert set(d) == DRIFT_KEYS
        path = float(np.sum(np.linalg.norm(np.diff(part[:, :3], axis=0), axis=1)))
        turned = math.degrees(float(np.sum(np.angle(np.exp(1j * np.diff(part[:, 3]))))))
        assert d["path_m"] == pytest.approx(path, rel=1e-9, abs=1e-9)
        assert d["turned_deg"] == pytest.approx(turned, abs=1e-6)
    # the straight drive began where the odometry started (the true pose after the
    # settle): its drift is the gap between the odometry and the truth at its end
    d = straight.drift
    gap = math.hypot(
        straight.odometry["x"] - p[split - 1, 0], straight.odometry["y"] - p[split - 1, 1]
    )
    assert d["position_m"] == pytest.approx(gap, abs=1e-9)
    assert d["position_per_m"] == pytest.approx(gap / d["path_m"], rel=1e-9)
    heading = straight.odometry["turn"] - d["turned_deg"]
    assert d["heading_deg"] == pytest.approx(heading, abs=1e-6)
    assert d["heading_per_m_deg"] == pytest.approx(abs(heading) / d["path_m"], rel=1e-6)
    fused = np.array([straight.fused[k] for k in "xyz"])
    assert d["fused_position_m"] == pytest.approx(
        float(np.linalg.norm(fused - p[split - 1, :3])), abs=1e-9
    )
    assert d["heading_per_deg_turned"] is None, "it did not turn"
    # the turn: what it added, each displacement in its own start frame
    t = turn.drift
    odo0 = np.array([straight.odometry["x"], straight.odometry["y"]])
    odo1 = np.array([turn.odometry["x"], turn.odometry["y"]])
    moved_odo = _local(odo1 - odo0, math.radians(straight.odometry["yaw"]))
    moved_true = _local(p[-1, :2] - p[split - 1, :2], p[split - 1, 3])
    assert t["position_m"] == pytest.approx(float(np.linalg.norm(moved_odo - moved_true)), abs=1e-9)
    assert t["heading_deg"] == pytest.approx(turn.odometry["turn"] - t["turned_deg"], abs=1e-6)
    assert t["heading_per_deg_turned"] == pytest.approx(
        abs(t["heading_deg"]) / abs(t["turned_deg"]), rel=1e-9
    )
    # what the figures say: straight, the wheels are within 1 % of the truth; turning in
    # place, a skid-steer rover's wheels count far more turn than it makes
    assert d["position_per_m"] < 0.01 and abs(d["heading_deg"]) < 1.0
    assert t["turned_deg"] == pytest.approx(45.0, abs=2.0)
    assert t["heading_deg"] > 0.5 * t["turned_deg"]


def _drive(floor: Path, *extra: str):
    return CliRunner().invoke(
        rover_drive_command,
        [str(floor), "--distance", "1", "--turn", "20", "--rate", "40", "--settle", "0.5", *extra],
    )


def test_report_and_plot_of_a_drive(floor, tmp_path):
    report, plot = tmp_path / "r.json", tmp_path / "drift.png"
    result = _drive(floor, "--report", str(report), "--plot", str(plot))
    assert result.exit_code == 0, result.output
    assert "rover: straight drift over" in result.output
    assert "rover: turn drift over" in result.output
    tasks = json.loads(report.read_text())["tasks"]
    assert [t["task"] for t in tasks] == ["straight", "turn"]
    for t in tasks:
        assert set(t["drift"]) == DRIFT_KEYS
        assert t["drift"]["path_m"] == pytest.approx(t["true_path"])
    assert tasks[0]["drift"]["position_m"] == pytest.approx(tasks[0]["odometry_position_error"])
    with Image.open(plot) as image:
        assert image.format == "PNG" and image.size[0] > 600 and image.size[1] > 300
    assert plotted_by(plot) == "rover-drive"
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")], "no temp left"
    # our own plot is ours to replace; the same drive draws the same bytes
    first = plot.read_bytes()
    again = _drive(floor, "--plot", str(plot))
    assert again.exit_code == 0, again.output
    assert plot.read_bytes() == first


def _run(*args: str, cwd: Path, block: str = "") -> subprocess.CompletedProcess:
    code = f"import sys; {block}from urdf2mjcf.cli import rover_drive_main; rover_drive_main()"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd, timeout=300
    )


def _one_error(proc: subprocess.CompletedProcess, *needles: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


def test_plot_never_replaces_a_users_file_and_bad_paths_are_one_error(floor, tmp_path):
    mine = tmp_path / "holiday.png"
    Image.new("RGB", (4, 4), "red").save(mine)
    before = mine.read_bytes()
    (tmp_path / "folder.png").mkdir()
    (tmp_path / "a_file").write_text("not a folder\n")
    cases = [
        (["--plot", "holiday.png"], ("holiday.png", "not a plot of rover-drive", "--overwrite")),
        (["--plot", "drift.svg"], ("drift.svg", "--plot", "must end in .png")),
        (["--plot", "folder.png"], ("folder.png", "--plot", "is a directory")),
        (["--plot", "a_file/drift.png"], ("a_file/drift.png", "cannot write here")),
        (["--plot", "r.png", "--report", "r.png"], ("r.png",)),
    ]
    for args, needles in cases:
        _one_error(_run(str(floor), "--distance", "0.2", *args, cwd=tmp_path), *needles)
    # without matplotlib (the sim extra): one line naming the extra, before any work
    proc = _run(
        str(floor), "--plot", "new.png", cwd=tmp_path, block="sys.modules['matplotlib'] = None; "
    )
    _one_error(proc, "rover-drive --plot needs the sim extra", "matplotlib")
    assert mine.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "folder.png", "holiday.png"]
