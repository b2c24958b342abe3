"""A run shown live in the browser viewer (``--view``): the viewer serves the run's
model and its states while it runs, and the run is the run without ``--view``; and
``make-facility --view`` serves the facility it built.

What the viewer sends the browser is read as the browser reads it: ``GET /model`` (an
MJB MuJoCo loads) and the ``/state`` WebSocket, whose payloads carry the simulation
state as float64 bytes."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from tests.test_view import TIMEOUT, Lines, at, served_model
from urdf2mjcf.view.live import LiveView

ROOT = Path(__file__).resolve().parents[1]
PENDULUM = """<mujoco>
  <worldbody>
    <body name="bob" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
    </body>
  </worldbody>
</mujoco>
"""


def _command(name: str) -> list[str]:
    return [sys.executable, "-c", f"from urdf2mjcf.cli import {name}; {name}()"]


def _served(url: str, tmp: Path, nbody: int) -> mujoco.MjModel:
    """The served model once the viewer serves the one it was given (a moment after)."""
    deadline = time.monotonic() + TIMEOUT
    while True:
        m = served_model(url, tmp)
        if m.nbody == nbody or time.monotonic() > deadline:
            return m
        time.sleep(0.2)


def _states(url: str, until: Any, limit: float = TIMEOUT) -> list[bytes]:
    """The state payloads the viewer sends a browser, until ``until()`` or the viewer
    closes the connection."""
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    got: list[bytes] = []
    deadline = time.monotonic() + limit
    with connect(at(url, "state?sid=test").replace("http://", "ws://"), max_size=None) as ws:
        while time.monotonic() < deadline and not until(got):
            try:
                msg = ws.recv(timeout=1)
            except TimeoutError:
                continue
            except ConnectionClosed:
                break
            if isinstance(msg, bytes):
                got.append(msg)
                ws.send("state_ack")  # as the page does: the viewer keeps a few in flight
    return got


def test_the_live_view_serves_the_runs_state_and_leaves_the_run_alone(tmp_path):
    m = mujoco.MjModel.from_xml_string(PENDULUM)
    d, alone = mujoco.MjData(m), mujoco.MjData(m)
    d.qpos[0] = alone.qpos[0] = 0.3
    with LiveView(m, d, pace=1000.0, browser=False) as view:
        assert view.studio.url is not None
        served = _served(view.studio.url, tmp_path, m.nbody)
        assert (served.nq, served.nbody, served.ngeom) == (m.nq, m.nbody, m.ngeom)
        for _ in range(200):
            mujoco.mj_step(m, d)
            view.step()
            mujoco.mj_step(m, alone)
        time.sleep(0.1)  # a frame is due: the last state is offered
        view.step()
        now = d.qpos.tobytes() + d.qvel.tobytes()
        when = np.float64(d.time).tobytes()
        states = _states(view.studio.url, lambda got: any(now in s for s in got), 30)
        assert any(now in s and when in s for s in states), "the run's state was not served"
    # the view only reads: the run is the run without it, bit for bit
    assert d.qpos.tobytes() == alone.qpos.tobytes() and d.time == alone.time


@pytest.fixture(scope="module")
def mira(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-floor")


DRIVE = ["--distance", "0.6", "--settle", "0.5"]


def test_rover_drive_view_shows_the_drive_and_changes_nothing(mira, tmp_path):
    plain = subprocess.run(
        [*_command("rover_drive_main"), str(mira), *DRIVE, "--report", str(tmp_path / "a.json")],
        capture_output=True,
        timeout=TIMEOUT,
    )
    assert plain.returncode == 0, plain.stderr
    viewed = subprocess.Popen(
        [*_command("rover_drive_main"), str(mira), *DRIVE, "--report", str(tmp_path / "b.json")]
        + ["--view", "--pace", "0.5"],  # slower than real time: seconds to watch it
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    err = Lines(viewed.stderr)  # type: ignore[arg-type]
    url = err.wait_for("viewing ").split(" at ")[1].split(" ")[0]
    scene = mujoco.MjModel.from_xml_path(str(mira / "scene.xml"))
    served = _served(url, tmp_path, scene.nbody)
    assert (served.nq, served.nbody, served.ngeom) == (scene.nq, scene.nbody, scene.ngeom)
    states = _states(url, lambda got: False)  # until the run ends and the viewer closes
    out = viewed.stdout.read()  # type: ignore[union-attr]
    assert viewed.wait(TIMEOUT) == 0
    # frames while it ran: many, and the rover moved between them
    assert len(states) >= 5 and len(set(states)) >= 5
    # the same run: the report and what it printed, byte for byte
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()
    assert out == plain.stdout


_TIMING = ("wall_time", "real_time_factor", "planning_time_s")
"""What differs between any two runs of the demo: how long the machine took."""


def _without_timing(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _without_timing(v) for k, v in value.items() if k not in _TIMING}
    if isinstance(value, list):
        return [_without_timing(v) for v in value]
    return value


def test_facility_demo_view_changes_nothing_but_the_time_it_takes(imetro_bundle, tmp_path):
    built = imetro_bundle
    command = [*_command("facility_demo_main"), str(built), "--report"]
    plain = subprocess.run([*command, str(tmp_path / "a.json")], capture_output=True)
    assert plain.returncode == 0, plain.stderr
    viewed = subprocess.Popen(
        [*command, str(tmp_path / "b.json"), "--view", "--pace", "1000"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    err = Lines(viewed.stderr)  # type: ignore[arg-type]
    url = err.wait_for("viewing facility-demo ").split(" at ")[1].split(" ")[0]
    states = _states(url, lambda got: False, 2 * TIMEOUT)  # until the run ends
    viewed.stdout.read()  # type: ignore[union-attr]
    assert viewed.wait(TIMEOUT) == 0
    assert len(states) >= 5 and len(set(states)) >= 5
    reports = [json.loads((tmp_path / f"{n}.json").read_text()) for n in "ab"]
    assert reports[0]["ok"] is True
    assert _without_timing(reports[0]) == _without_timing(reports[1])


def test_make_facility_view_serves_the_facility_until_sigterm(tmp_path):
    out = tmp_path / "built"
    proc = subprocess.Popen(
        [*_command("make_facility_main"), str(ROOT / "recipes" / "mira3d-floor.yaml")]
        + ["-o", str(out), "--no-components", "--view"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        lines = Lines(proc.stdout)  # type: ignore[arg-type]
        url = lines.wait_for("viewing ").split(" at ")[1].split(" ")[0]
        scene = mujoco.MjModel.from_xml_path(str(out / "scene.xml"))
        served = _served(url, tmp_path, scene.nbody)
        assert (served.nq, served.nbody, served.ngeom) == (scene.nq, scene.nbody, scene.ngeom)
    finally:
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(TIMEOUT)
    assert code == 0
