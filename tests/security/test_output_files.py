"""What a run does at its output files (issue 34, item 3), through the real commands:
no output path is opened to decide whether it is ours (a FIFO at ``--report``,
``--record`` or ``--plot`` is refused at once, never waited on); a recording killed
by SIGKILL leaves its temporary file, which the next run writing beside it removes;
a report that fails as it is written leaves no ``-o`` folder the run created.
"""

from __future__ import annotations

import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from urdf2mjcf.envs import build as env_build

from .attack import ENTRY, ROOT, assert_one_error, run

TIMEOUT = 60
URDF = (
    '<robot name="r"><link name="base"/><link name="arm"><inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>'
    '<limit lower="-1" upper="1" effort="10" velocity="1"/></joint></robot>\n'
)


@pytest.fixture(scope="session")
def floor(_session_cache: Path) -> Path:
    """The MIRA3D floor bundle, built once per session (as tests/runner builds it)."""
    return env_build.facility_folder("mira3d-floor", root=ROOT)[0]


@pytest.mark.parametrize(
    ("option", "name"), [("--report", "out.json"), ("--record", "out.mcap"), ("--plot", "out.png")]
)
def test_a_fifo_at_an_output_of_rover_drive_is_refused_at_once(floor, tmp_path, option, name):
    fifo = tmp_path / name
    os.mkfifo(fifo)
    # a reader would block on open until someone writes: the time limit is the test
    res = run("rover-drive", str(floor), option, str(fifo), cwd=tmp_path, timeout=TIMEOUT)
    assert_one_error(res, name, "is a FIFO", "never opened")
    assert [p.name for p in tmp_path.iterdir()] == [name]


@pytest.mark.parametrize(("option", "name"), [("--report", "out.json"), ("--record", "out.mcap")])
def test_a_fifo_at_an_output_of_facility_demo_is_refused_at_once(
    imetro_bundle, tmp_path, option, name
):
    fifo = tmp_path / name
    os.mkfifo(fifo)
    res = run("facility-demo", str(imetro_bundle), option, str(fifo), cwd=tmp_path, timeout=TIMEOUT)
    assert_one_error(res, name, "is a FIFO")
    assert [p.name for p in tmp_path.iterdir()] == [name]


def test_a_fifo_at_the_report_of_a_conversion_is_refused_at_once(tmp_path):
    (tmp_path / "r.urdf").write_text(URDF)
    os.mkfifo(tmp_path / "r.json")
    res = run(
        "urdf2mjcf",
        str(tmp_path / "r.urdf"),
        "-o",
        str(tmp_path / "out" / "r.xml"),
        "--report",
        str(tmp_path / "r.json"),
        "--overwrite",
        cwd=tmp_path,
        timeout=TIMEOUT,
    )
    assert_one_error(res, "r.json", "is a FIFO")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json", "r.urdf"]


def _temp_files(folder: Path, name: str) -> list[Path]:
    pattern = re.compile(re.escape(f".{name}.") + r"\d+\.[0-9a-f]{12}\.tmp")
    return [p for p in folder.iterdir() if pattern.fullmatch(p.name)]


def test_a_killed_recording_leaves_a_temp_file_the_next_run_removes(floor, tmp_path):
    record = tmp_path / "drive.mcap"
    code = f"from urdf2mjcf.cli import {ENTRY['rover-drive']}; {ENTRY['rover-drive']}()"
    args = [sys.executable, "-c", code, str(floor), "--record", str(record)]
    proc = subprocess.Popen(
        [*args, "--distance", "50", "--speed", "0.5"],  # about 100 s simulated: killed first
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        cwd=tmp_path,
    )
    try:
        deadline = time.monotonic() + TIMEOUT
        while not _temp_files(tmp_path, record.name) and time.monotonic() < deadline:
            assert proc.poll() is None, "the run ended before it was killed"
            time.sleep(0.05)
        time.sleep(0.5)  # into the run, the recording being written
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    (left,) = _temp_files(tmp_path, record.name)
    assert not record.exists()
    again = subprocess.run(
        [*args, "--distance", "0.1"], capture_output=True, text=True, cwd=tmp_path, timeout=300
    )
    assert again.returncode == 0, again.stderr[-2000:]
    assert record.is_file() and record.stat().st_size > 0
    assert not left.exists(), "the next run left the killed run's temporary file"
    assert _temp_files(tmp_path, record.name) == []


def _small_files(limit: int):
    def limited() -> None:
        # writes past `limit` bytes fail (EFBIG) as on a full disk, instead of killing us
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return limited


def test_a_report_that_fails_as_it_is_written_leaves_no_output_folder(tmp_path):
    (tmp_path / "r.urdf").write_text(URDF)
    code = f"from urdf2mjcf.cli import {ENTRY['urdf2mjcf']}; {ENTRY['urdf2mjcf']}()"
    # the model's files (under 1 KB each) fit; the report (about 4 KB) does not
    res = subprocess.run(
        [sys.executable, "-c", code, "r.urdf", "-o", "new/deep/r.xml", "--report", "r.json"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=TIMEOUT,
        preexec_fn=_small_files(2000),
    )
    assert res.returncode == 2, res.stderr[-2000:]
    errors = [x for x in res.stderr.splitlines() if x.startswith("error: ")]
    assert errors == ["error: r.json: cannot write: File too large"], res.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.urdf"]
