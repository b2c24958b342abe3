"""The MIRA3D pair's deliver task (``rover-drive BUNDLE --task deliver``): one run on the
Moon checked against MuJoCo itself (the grains' body masses and where they lie, the
collector's contact forces against its mass times gravity, the printed beads against the
planned square computed here from the printer's pose), one run of the command on the
floor (its report), and the error line for a bundle without the pair."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from urdf2mjcf.runner.rover import rover_drive_command
from urdf2mjcf.runner.rover.deliver import run_deliver
from urdf2mjcf.runner.rover.printhead import AHEAD, SIDE
from urdf2mjcf.runner.rover.sim import RoverSim

ROOT = Path(__file__).resolve().parents[2]
TASK_KEYS = {
    "name",
    "success",
    "collected_kg",
    "delivered_kg",
    "spilled_kg",
    "printed_path_m",
    "path_error_m",
}


@pytest.fixture(scope="module")
def moon_run(shipped_bundle):
    """The deliver task once on the Moon pair bundle: (sim after the run, result, model
    masses of the grains, the collector's mass)."""
    sim = RoverSim(shipped_bundle("mira3d-pair"))
    m = sim.m
    grains = [
        m.body(f"regolith_{k}").id
        for k in range(m.nbody)
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"regolith_{k}") >= 0
    ]
    res, reports = run_deliver(sim, seed=3, log=lambda _: None)
    return sim, res, reports, grains


def _in_hopper(sim: RoverSim, body: int, rover: str) -> bool:
    """Whether ``body`` sits above ``rover``'s control box (0.5 x 0.5 m, top 0.73 m above
    the base), read here from MuJoCo's poses."""
    m, d = sim.m, sim.d
    box = m.body(f"{rover}_control_box_link").id
    base = m.body(f"{rover}_base_link").id
    rot = d.xmat[base].reshape(3, 3)
    local = (d.xpos[body] - d.xpos[box]) @ rot
    return bool(abs(local[0]) <= 0.3 and abs(local[1]) <= 0.3 and 0.15 < local[2] < 0.45)


def test_the_load_goes_from_the_pile_to_the_printer_and_the_balance_closes(moon_run):
    sim, res, _, grains = moon_run
    m = sim.m
    pile = float(sum(m.body_mass[g] for g in grains))
    assert pile == pytest.approx(12.0)
    assert res.success, res.summary()
    assert res.collected_kg == pytest.approx(pile, rel=1e-9)
    at_printer = sum(m.body_mass[g] for g in grains if _in_hopper(sim, g, "printer"))
    at_collector = sum(m.body_mass[g] for g in grains if _in_hopper(sim, g, "collector"))
    assert res.delivered_kg == pytest.approx(at_printer, rel=1e-9)
    assert res.carried_kg == pytest.approx(at_collector, abs=1e-9)
    total = res.delivered_kg + res.spilled_kg + res.carried_kg
    assert abs(res.collected_kg - total) <= 0.01 * res.collected_kg
    # the grains are held by the printer's welds and by nothing else
    for k, g in enumerate(grains):
        on = {
            r: bool(sim.d.eq_active[m.equality(f"regolith_{k}_{r}").id])
            for r in ("collector", "printer")
        }
        assert on == {"collector": False, "printer": True}, g
    assert res.rock_contacts == 0


def test_the_collectors_wheels_carry_the_load(moon_run):
    sim, res, _, _ = moon_run
    m = sim.m
    g = -float(m.opt.gravity[2])
    root = m.body("collector_base_link").id
    own = float(sum(m.body_mass[i] for i in range(m.nbody) if m.body_rootid[i] == root))
    # standing braked, the ground carries the rover, then the rover and its load
    assert res.wheel_load_empty_n == pytest.approx(own * g, rel=0.01)
    assert res.wheel_load_loaded_n - res.wheel_load_empty_n == pytest.approx(
        res.collected_kg * g, rel=0.03
    )


def test_the_printed_layer_follows_the_planned_square(moon_run):
    sim, res, reports, _ = moon_run
    m, d = sim.m, sim.d
    beads = [
        m.body(f"bead_{k}").mocapid[0]
        for k in range(m.nbody)
        if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"bead_{k}") >= 0
    ]
    xyz = d.mocap_pos[beads]
    placed = xyz[xyz[:, 2] > -50]  # the others stay parked 100 m down
    assert len(placed) > 0.9 * len(beads)
    assert np.all(np.abs(placed[:, 2] - 0.015) < 1e-9)  # on the ground, radius 15 mm
    printed = float(np.sum(np.linalg.norm(np.diff(placed[:, :2], axis=0), axis=1)))
    assert res.printed_path_m == pytest.approx(printed, rel=1e-9)
    # the planned square, from the printer's true pose when it began to print
    start = next(r for r in reports if r["phase"] == "hand-over")["true"]
    end = next(r for r in reports if r["phase"] == "print")["true"]
    assert math.hypot(end["x"] - start["x"], end["y"] - start["y"]) < 0.03  # it stood braked
    yaw = math.radians(start["yaw"])
    centre = np.array([start["x"], start["y"]]) + AHEAD * np.array([math.cos(yaw), math.sin(yaw)])
    local = placed[:, :2] - centre
    c, s = math.cos(yaw), math.sin(yaw)
    u = local @ np.array([c, s])
    v = local @ np.array([-s, c])
    # distance to the square's outline: |max(|u|, |v|) - side / 2| outside the corners' rounding
    off = np.abs(np.maximum(np.abs(u), np.abs(v)) - SIDE / 2)
    assert float(off.mean()) == pytest.approx(res.path_error_m, abs=2e-3)
    assert off.max() < 0.02
    assert printed == pytest.approx(4 * SIDE, rel=0.05)
    assert res.planned_path_m == pytest.approx(4 * SIDE, rel=1e-9)


def test_deliver_on_the_floor_writes_its_report(shipped_bundle, tmp_path):
    bundle = shipped_bundle("mira3d-pair-floor")
    report = tmp_path / "deliver.json"
    res = CliRunner().invoke(
        rover_drive_command, [str(bundle), "--task", "deliver", "--report", str(report)]
    )
    assert res.exit_code == 0, res.output
    data = json.loads(report.read_text())
    assert TASK_KEYS <= set(data["task"])
    assert data["task"]["name"] == "deliver" and data["task"]["success"] is True
    assert {"scene", "tasks", "warnings"} <= set(data)
    assert data["warnings"] == {}
    phases = [t["phase"] for t in data["tasks"]]
    assert phases[:3] == ["to the pile", "scoop", "to the printer"]
    assert "deliver: success" in res.output


def test_deliver_needs_the_pair(shipped_bundle):
    bundle = shipped_bundle("mira3d-floor")
    exe = Path(sys.executable).parent / "rover-drive"
    res = subprocess.run(
        [str(exe), str(bundle), "--task", "deliver"], capture_output=True, text=True
    )
    assert res.returncode == 2
    assert res.stdout == ""
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert str(bundle / "facility.json") in lines[0] and "collector" in lines[0]


def test_the_deliver_world_is_off_unless_a_pair_recipe_sets_it():
    world = (ROOT / "facility/worlds/mira3d_world/urdf/mira3d_world.urdf.xacro").read_text()
    assert re.search(r'<xacro:arg name="deliver" default="false"/>', world)
    setting = {
        p.name: yaml.safe_load(p.read_text()).get("flags", {}).get("deliver", False)
        for p in (ROOT / "recipes").glob("mira3d-*.yaml")
    }
    assert {n for n, on in setting.items() if on} == {"mira3d-pair.yaml", "mira3d-pair-floor.yaml"}
