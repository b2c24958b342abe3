"""The whole logistics demo on the default facility, and facilities broken on
purpose that make it fail at the right step, saying why."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.runner.cli import facility_demo_command
from urdf2mjcf.runner.demo import Demo, load_waypoints
from urdf2mjcf.runner.load import load

ROOT = Path(__file__).resolve().parents[2]
WAYPOINTS = ROOT / "recipes" / "demo" / "imetro.yaml"


@pytest.fixture(scope="module")
def facility(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "imetro"
    build_facility(load_recipe(ROOT / "recipes" / "imetro.yaml"), out, root=ROOT, components=False)
    return out


def _run(folder: Path, change=None, spec=None):
    fac = load(folder)
    if change:
        change(fac)
    demo = Demo(fac, spec or load_waypoints(WAYPOINTS), log=lambda *_: None)
    try:
        return demo.run()
    finally:
        demo.close()


@pytest.mark.slow
def test_the_demo_succeeds_on_the_default_facility(facility, tmp_path):
    report = tmp_path / "report.json"
    frames = tmp_path / "frames"
    res = CliRunner().invoke(
        facility_demo_command,
        [str(facility), "--report", str(report), "--frames", str(frames)],
    )
    assert res.exit_code == 0, res.output
    assert "SUCCESS" in res.output and "open_lid" in res.output
    data = json.loads(report.read_text())
    assert data["ok"] and all(s["ok"] for s in data["steps"])
    steps = {s["name"]: s for s in data["steps"]}
    assert any("trainer_lid" in c for c in steps["open_lid"]["contacts"])
    assert any("ctb" in c and "finger" in c for c in steps["close"]["contacts"])
    assert data["verdict"]["tilt_deg"] < 10 and data["verdict"]["speed"] < 0.01
    assert abs(data["handle"]["position"][0] - 1.2) < 0.01  # seen where the bag lies
    assert (frames / "find_handle_wrist.png").is_file() and (frames / "final.png").is_file()


@pytest.mark.slow
def test_ctb_out_of_the_wrist_cameras_view_fails_at_find_handle(facility):
    def move_ctb(fac):
        j = fac.joint("ctb_joint")
        fac.data.qpos[fac.model.jnt_qposadr[j]] = (
            1.9  # 0.7 m down the rail from where it is looked for
        )

    res = _run(facility, move_ctb)
    assert not res.ok and res.failed_step == "find_handle"
    assert "not in the wrist camera's view" in res.message


@pytest.mark.slow
def test_a_bin_too_small_fails_the_success_check(facility):
    spec = load_waypoints(WAYPOINTS)
    spec["stowage"]["inside"] = [0.45, 0.55, 0.32]  # shorter than the 0.50 m bag
    res = _run(facility, spec=spec)
    assert all(s.ok for s in res.steps)
    assert not res.ok and res.failed_step == "success check"
    assert "outside the stowage volume of 'trainer_seat_bin'" in res.message


@pytest.mark.slow
def test_an_obstacle_in_the_carry_path_is_an_unintended_contact(facility):
    spec = load_waypoints(WAYPOINTS)
    spec["steps"] = [s for s in spec["steps"] if s["name"] != "raise_to_carry"]  # carry too low

    res = _run(facility, spec=spec)
    assert not res.ok and res.failed_step == "pre_drop"
    assert "unintended contact" in res.message and "ctb with trainer_bench" in res.message
    assert np.isfinite(res.sim_time)
