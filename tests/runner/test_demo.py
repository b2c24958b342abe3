"""The whole logistics demo on the default facility (the real layout, the paper's
published waypoints), the published waypoints reached in simulation, and facilities
broken on purpose that make it fail at the right step, saying why."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.runner.cli import facility_demo_command
from urdf2mjcf.runner.demo import Demo, load_waypoints
from urdf2mjcf.runner.load import load

ROOT = Path(__file__).resolve().parents[2]
WAYPOINTS = ROOT / "recipes" / "demo" / "imetro.yaml"
# facility-facts.md section 4: the published joint waypoints (arm: pan, lift, elbow, w1-3)
PUBLISHED_ARM = {
    "demo_home": (3.1927, -2.3913, -1.7760, -0.4700, -1.6177, -1.6134),
    "init": (2.5656, -3.0020, -0.9599, -0.6982, -1.5184, -1.0297),
    "approach_bench_seat": (2.443, -2.670, -1.571, -0.419, -1.500, -0.925),
    "stow": (1.5010, -0.3316, -2.2515, -3.6477, -1.5533, 1.5708),
}
PRE_DROP = ((-1.006, 0.811, 1.580), (0.725, 0.688, 0.032, -0.004))  # tool0: xyz, quat xyzw


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


def test_the_demo_file_carries_the_published_values_unchanged():
    steps = {s["name"]: s for s in load_waypoints(WAYPOINTS)["steps"]}
    for name, arm in PUBLISHED_ARM.items():
        given = steps[name].get("arm") or steps[name]["q"][2:]
        assert tuple(given) == arm, name
    assert steps["init"]["q"][:2] == [0, 0]
    lid = steps["open_lid"]
    assert (lid["steps"], lid["step_deg"], lid["hold_orientation"]) == (8, 11.5, True)
    assert steps["back_out"]["tool"] == [0, 0, -0.4]
    assert [steps[n]["set"] for n in ("rail_to_0.5", "rail_to_1.2", "lift_stage_up")] == [
        {"rail": 0.5}, {"rail": 1.2}, {"lift": 0.68}
    ]
    assert steps["rail_to_0.3"]["set"] == {"rail": 0.3} and steps["rail_to_0"]["set"] == {"rail": 0}
    assert steps["lift_0.2"]["world"] == [0, 0, 0.2]
    pre = steps["pre_drop"]
    assert pre["site"] == "tool" and tuple(pre["position"]) == PRE_DROP[0]
    assert tuple(pre["orientation_xyzw"]) == PRE_DROP[1]
    assert steps["back_off"]["tool"] == [0, 0, -0.05]


class _Recording(Demo):
    """The demo, noting how close each published joint waypoint is reached (after the
    step and 0.5 s more of holding) and tool0's pose after pre_drop."""

    reached: dict
    tool: tuple

    def run_step(self, step: dict) -> None:
        super().run_step(step)
        name = step["name"]
        if name in PUBLISHED_ARM:
            self.ctl.wait(0.5)
            q = self.d.qpos[self.r.qpos]
            self.reached[name] = (q[2:].copy(), self.ctl.target[2:].copy())
        if name == "pre_drop":
            s = self.r.sites["tool"]
            self.tool = (self.d.site_xpos[s].copy(), self.d.site_xmat[s].reshape(3, 3).copy())


@pytest.fixture(scope="module")
def recorded(facility):
    fac = load(facility)
    demo = _Recording(fac, load_waypoints(WAYPOINTS), log=lambda *_: None)
    demo.reached = {}
    try:
        result = demo.run()
    finally:
        demo.close()
    return demo, result


@pytest.mark.slow
def test_the_published_demo_succeeds_and_reaches_the_published_waypoints(recorded):
    demo, result = recorded
    assert result.ok, (result.failed_step, result.message)
    for name, arm in PUBLISHED_ARM.items():
        q, target = demo.reached[name]
        np.testing.assert_allclose(target, arm, atol=1e-12, err_msg=name)
        assert np.abs(q - np.array(arm)).max() < 1e-3, f"{name}: {np.abs(q - arm).max():.2e} rad"
    # tool0 at pre_drop: within 1 cm (and 1 deg) of the published world pose
    p, r = demo.tool
    assert np.linalg.norm(p - np.array(PRE_DROP[0])) < 0.01
    want = Rotation.from_quat(PRE_DROP[1]).as_matrix()
    assert Rotation.from_matrix(r.T @ want).magnitude() < np.radians(1)


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
    # joint moves are planned: planner, planning time and path length in the report
    planned = {s["name"]: s["plan"] for s in data["steps"] if s.get("plan")}
    assert {"init", "approach_bench_seat", "stow", "rail_to_0.3", "home"} <= set(planned)
    for plan in planned.values():
        assert plan["planner"] in ("straight", "RRTstar")
        assert plan["planning_time_s"] >= 0 and plan["path_length"] >= 0
    steps = {s["name"]: s for s in data["steps"]}
    assert any("trainer_lid" in c for c in steps["open_lid"]["contacts"])
    assert any("ctb" in c and "finger" in c for c in steps["close"]["contacts"])
    assert data["verdict"]["tilt_deg"] < 10 and data["verdict"]["speed"] < 0.01
    assert abs(data["handle"]["position"][0] - 0.8) < 0.01  # seen where the bag lies
    assert (frames / "find_handle_wrist.png").is_file() and (frames / "final.png").is_file()


@pytest.mark.slow
def test_the_compact_layouts_demo_succeeds(tmp_path):
    out = tmp_path / "imetro-compact"
    recipe = load_recipe(ROOT / "recipes" / "imetro-compact.yaml")
    build_facility(recipe, out, root=ROOT, components=False)
    res = _run(out, spec=load_waypoints(ROOT / "recipes" / "demo" / "imetro-compact.yaml"))
    assert res.ok, (res.failed_step, res.message)


@pytest.mark.slow
def test_ctb_out_of_the_wrist_cameras_view_fails_at_find_handle(facility):
    def move_ctb(fac):
        j = fac.joint("ctb_joint")
        fac.data.qpos[fac.model.jnt_qposadr[j]] = (
            2.0  # 1.2 m down the rail from where it is looked for
        )

    res = _run(facility, move_ctb)
    assert not res.ok and res.failed_step == "find_handle"
    assert "not in the wrist camera's view" in res.message


@pytest.mark.slow
def test_a_bin_too_small_fails_the_success_check(facility):
    spec = load_waypoints(WAYPOINTS)
    spec["stowage"]["inside"] = [0.6462, 0.45, 0.3475]  # shorter than the 0.50 m bag
    res = _run(facility, spec=spec)
    assert all(s.ok for s in res.steps)
    assert not res.ok and res.failed_step == "success check"
    assert "outside the stowage volume of 'trainer_seat_bin'" in res.message


@pytest.mark.slow
def test_carrying_the_bag_along_the_floor_is_refused_by_the_planner(facility):
    spec = load_waypoints(WAYPOINTS)
    low = ("lift_0.2", "sideways", "lift_stage_up")  # the bag would be dragged over the floor
    spec["steps"] = [s for s in spec["steps"] if s["name"] not in low]

    res = _run(facility, spec=spec)
    assert not res.ok and res.failed_step == "rail_to_0.3"
    assert "no collision-free joint move" in res.message
    assert "'floor'" in res.message and "'ctb'" in res.message
    assert np.isfinite(res.sim_time)
