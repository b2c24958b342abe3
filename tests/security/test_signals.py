"""Signals end everything (issue 19, item 7): SIGTERM or Ctrl-C during facility-demo
--trials stops every worker within 5 s, leaves no process behind (workers, the
multiprocessing resource tracker, decomposition workers) and no temporary folder, and
exits 143 (SIGTERM) or 130 (SIGINT); a second SIGTERM orphans nothing either."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import NoReturn

import pytest

from tests.security.attack import ROOT, run

STOP_WITHIN = 5.0
"""Seconds from the signal to the command's exit, and again to the last process's end."""


@pytest.fixture(scope="module")
def facility(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("signals") / "imetro"
    recipe = str(ROOT / "recipes" / "imetro.yaml")
    res = run(
        "make-facility", recipe, "--root", str(ROOT), "-o", str(out), "--no-components",
        cwd=ROOT, timeout=600, memory=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    return out


def _parents() -> dict[int, int]:
    out = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            out[int(entry)] = int(stat.rsplit(")", 1)[1].split()[1])
    return out


def descendants(pid: int) -> set[int]:
    parents, found, frontier = _parents(), set(), {pid}
    while frontier:
        frontier = {c for c, p in parents.items() if p in frontier} - found
        found |= frontier
    return found


def running(pids: set[int]) -> set[int]:
    """Those of ``pids`` that still run (not zombies waiting to be reaped)."""
    alive = set()
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            alive.add(pid)
    return alive


def start_trials(facility: Path, tmp_path: Path) -> tuple[subprocess.Popen, set[int]]:
    """facility-demo --trials 100000 with two workers, once a trial is under way (its
    temporary folder is made); the processes it runs by then."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    code = (  # SIGUSR1: the stacks of a command that did not stop, for the failure
        "import faulthandler, signal; faulthandler.register(signal.SIGUSR1, all_threads=True)\n"
        # Ctrl-C as a terminal's shell gives it: Python keeps SIGINT ignored when the
        # process that started it ignored it, as a test runner's worker may
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "from urdf2mjcf.cli import facility_demo_main; facility_demo_main()"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(facility), "--trials", "100000", "--workers", "2"],
        cwd=tmp_path,
        env={**os.environ, "TMPDIR": str(tmp)},
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # our own group: a stray process is found, and ended, by it
    )
    deadline = time.monotonic() + 300
    while not list(tmp.glob("imetro-trial-*")):
        if proc.poll() is not None or time.monotonic() > deadline:
            _kill_group(proc)
            pytest.fail(f"no trial started: {proc.communicate()[1][-2000:]}")
        time.sleep(0.1)
    time.sleep(1.0)  # well into the trial: building the facility or running the demo
    return proc, descendants(proc.pid)


def _hung(proc: subprocess.Popen, what: str) -> NoReturn:
    proc.send_signal(signal.SIGUSR1)
    time.sleep(1.0)
    _kill_group(proc)
    pytest.fail(f"the command did not exit within 60 s of {what}:\n{proc.communicate()[1]}")


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def stop(proc: subprocess.Popen, *signals: signal.Signals) -> tuple[int, str, float]:
    start = time.monotonic()
    for i, sig in enumerate(signals):
        if i:
            time.sleep(0.3)
        proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        _hung(proc, "the signal")
    return proc.returncode, err, time.monotonic() - start


def assert_nothing_left(proc: subprocess.Popen, before: set[int], tmp_path: Path) -> None:
    deadline = time.monotonic() + STOP_WITHIN
    left = running(before | descendants(proc.pid))
    while left and time.monotonic() < deadline:
        time.sleep(0.1)
        left = running(left)
    names = {p: Path(f"/proc/{p}/cmdline").read_bytes()[:120] for p in left}
    _kill_group(proc)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not left, names
    assert list((tmp_path / "tmp").iterdir()) == []  # no trial's folder either


def test_sigterm_during_trials_stops_every_worker(facility, tmp_path):
    proc, before = start_trials(facility, tmp_path)
    assert len(running(before)) >= 2, before  # the workers (and the resource tracker)
    code, err, seconds = stop(proc, signal.SIGTERM)
    assert code == 128 + signal.SIGTERM, err
    assert seconds < STOP_WITHIN, seconds
    assert "terminated (SIGTERM)" in err and "Traceback" not in err, err
    assert_nothing_left(proc, before, tmp_path)


def test_a_second_sigterm_orphans_nothing(facility, tmp_path):
    proc, before = start_trials(facility, tmp_path)
    code, err, seconds = stop(proc, signal.SIGTERM, signal.SIGTERM)
    assert code == 128 + signal.SIGTERM, err
    assert seconds < STOP_WITHIN, seconds
    assert_nothing_left(proc, before, tmp_path)


def test_ctrl_c_during_trials_stops_every_worker(facility, tmp_path):
    proc, before = start_trials(facility, tmp_path)
    # A terminal sends Ctrl-C to the whole foreground group: the workers get it too.
    start = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        _hung(proc, "Ctrl-C")
    assert proc.returncode == 128 + signal.SIGINT, err
    assert time.monotonic() - start < STOP_WITHIN
    assert "interrupted" in err and "Traceback" not in err, err
    assert_nothing_left(proc, before, tmp_path)
