"""Rover task plans (``rover-drive BUNDLE --plan FILE``): a plan drives a built MIRA3D
bundle and the base's true pose, read from MuJoCo's data, ends where the plan
commands; the registry builds the very tasks the classes make; every kind of bad
plan is one ``error:`` line naming the file and the element, exit 2, nothing
written; the docs' keys table is the registry's."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf2mjcf.command_runner import run_command
from urdf2mjcf.envs import build as env_build
from urdf2mjcf.runner.rover import (
    ArmWave,
    Hold,
    RoverSim,
    Straight,
    Turn,
    plan_file,
    rover_drive_command,
)
from urdf2mjcf.runner.rover.plan_file import (
    PLAN_SECONDS_MAX,
    TASKS_MAX,
    check_plan,
    check_shape,
    read_plan,
)
from urdf2mjcf.runner.rover.tasks import DRIVES, TASKS, keys_table

ROOT = Path(__file__).resolve().parents[2]
PLAN = """\
tasks:
  - {kind: straight, distance: 1.0, speed: 0.5}
  - {kind: turn, angle_deg: -45, rate_deg: 40}
  - {kind: hold, duration: 0.3}
  - {kind: straight, distance: -0.5}
arm: {kind: arm_wave, joint: 0, amplitude: 0.3, period: 2.0}
"""
SETTLE = 0.5


@pytest.fixture(scope="session")
def floor(_session_cache: Path) -> Path:
    """The MIRA3D floor bundle, built once per session in the cache the runner's and the
    environments' tests build it in (whichever runs first builds it)."""
    return env_build.facility_folder("mira3d-floor", root=ROOT)[0]


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), w * w + x * x - y * y - z * z)


def test_the_registry_builds_what_the_classes_make():
    assert TASKS["straight"].build({"kind": "straight", "distance": 2}) == Straight(2.0)
    assert TASKS["straight"].build(
        {"kind": "straight", "distance": -3.5, "speed": 0.25, "hold_heading": False}
    ) == Straight(-3.5, speed=0.25, hold_heading=False)
    assert TASKS["turn"].build({"kind": "turn", "angle_deg": 90, "rate_deg": 45}) == Turn(
        math.pi / 2, rate=math.pi / 4
    )
    assert TASKS["hold"].build({"kind": "hold", "duration": 0.5}) == Hold(0.5)
    assert TASKS["arm_wave"].build({"kind": "arm_wave"}) == ArmWave()
    assert list(DRIVES) == ["straight", "turn", "hold"] and TASKS["arm_wave"].arm


def test_a_plan_drives_the_rover_where_it_commands(floor, tmp_path):
    path = tmp_path / "plan.yaml"
    path.write_text(PLAN)
    plan = read_plan(path)
    sim = RoverSim(floor)
    rover = sim.rover()
    chosen = check_plan(plan, sim.rovers)
    assert chosen == ["rover"]
    sim.settle(SETTLE)
    home = float(sim.d.qpos[rover.arm_qpos[0]])
    truth: list[tuple[float, float, float, float]] = []  # x, y, yaw, arm joint 0 per step

    def record() -> None:
        d = sim.d
        base = rover.base
        truth.append((*d.xpos[base][:2], _yaw(d.xquat[base]), d.qpos[rover.arm_qpos[0]]))

    sim.on_step.append(record)
    record()
    ends = [0]
    for spec in plan.tasks:
        DRIVES[spec["kind"]].run(sim, spec, chosen, plan.arm)
        ends.append(len(truth) - 1)
    t = np.array(truth)
    pose = [t[i, :3] for i in ends]
    heading = [float(np.sum(np.angle(np.exp(1j * np.diff(t[: i + 1, 2]))))) for i in ends]

    def moved(k: int) -> tuple[float, float]:
        """Task k's displacement along and across the heading it started with."""
        dx, dy = pose[k + 1][:2] - pose[k][:2]
        c, s = math.cos(pose[k][2]), math.sin(pose[k][2])
        return c * dx + s * dy, -s * dx + c * dy

    def turned(k: int) -> float:
        return math.degrees(heading[k + 1] - heading[k])

    along, across = moved(0)
    assert along == pytest.approx(1.0, rel=0.05) and abs(across) < 0.1 and abs(turned(0)) < 2.0
    assert turned(1) == pytest.approx(-45.0, abs=2.0), "turned right by the IMU"
    assert np.hypot(*moved(2)) < 0.01 and abs(turned(2)) < 1.0, "held still"
    along, across = moved(3)
    assert along == pytest.approx(-0.5, rel=0.05) and abs(across) < 0.1 and abs(turned(3)) < 2.0
    # the arm swung its shoulder pan during the tasks (0.3 rad), and goes back home after
    swing = np.abs(t[:, 3] - home)
    assert 0.2 < swing.max() < 0.35
    sim.settle(1.0)
    assert abs(sim.d.qpos[rover.arm_qpos[0]] - home) < 0.01

    # the command runs the same plan the same way: its report's truth is this run's
    report = tmp_path / "r.json"
    args = [str(floor), "--plan", str(path), "--settle", str(SETTLE), "--report", str(report)]
    with pytest.raises(SystemExit) as done:
        run_command(rover_drive_command, args, prog_name="rover-drive")
    assert done.value.code == 0
    tasks = json.loads(report.read_text())["tasks"]
    assert [r["task"] for r in tasks] == ["straight", "turn", "hold", "straight"]
    assert [r["commanded"] for r in tasks] == [1.0, -45.0, 0.0, -0.5]
    for r, i in zip(tasks, ends[1:], strict=True):
        assert r["true"]["x"] == pytest.approx(t[i, 0], abs=1e-9)
        assert r["true"]["y"] == pytest.approx(t[i, 1], abs=1e-9)
        assert math.radians(r["true"]["yaw"]) == pytest.approx(t[i, 2], abs=1e-9)


def _plan(body: str) -> str:
    return "tasks:\n" + body


BAD = [
    (_plan("  - {kind: teleport}\n"), "tasks[0].kind", "unknown kind 'teleport'; valid: "),
    (_plan("  - {kind: arm_wave}\n"), "tasks[0].kind", "is an arm motion"),
    ("tasks: []\n", "tasks", "needs a non-empty list of tasks"),
    (
        _plan("  - {kind: hold}\n  - {kind: straight, distance: 1, sped: 2}\n"),
        "tasks[1].sped",
        "unknown key; valid: kind, distance, speed, accel, hold_heading",
    ),
    (_plan("  - {kind: turn}\n"), "tasks[0].angle_deg", "is required"),
    (_plan("  - {distance: 1}\n"), "tasks[0].kind", "is required"),
    (_plan("  - {kind: straight, distance: ten}\n"), "tasks[0].distance", "is not a number"),
    (_plan("  - {kind: turn, angle_deg: 9, imu: 1}\n"), "tasks[0].imu", "is not true or false"),
    (
        _plan("  - {kind: hold}\n  - {kind: hold}\n  - {kind: straight, distance: 1.0e+9}\n"),
        "tasks[2].distance",
        "out of range (from -1000 to 1000)",
    ),
    (_plan("  - {kind: straight, distance: 1, speed: 0}\n"), "tasks[0].speed", "out of range"),
    (_plan("  - {kind: straight, distance: .nan}\n"), "tasks[0].distance", "is not finite"),
    (_plan("  - {kind: hold, duration: 1000}\n"), "tasks[0].duration", "out of range"),
    (_plan("  - {kind: hold}\narm: {kind: arm_wave, joint: -1}\n"), "arm.joint", "whole number"),
    (_plan("  - {kind: hold}\narm: {kind: hold}\n"), "arm.kind", "is a drive task"),
    (_plan("  - {kind: hold}\nspeed: 3\n"), "speed", "unknown key; valid: rovers, tasks, arm"),
    ("- {kind: hold}\n", "plan", "is a mapping"),
    ("tasks: [\n", "line 2", "not valid YAML"),
    (
        _plan("  - {kind: hold}\n" * (TASKS_MAX + 1)),
        "tasks",
        f"has {TASKS_MAX + 1} tasks; at most {TASKS_MAX}",
    ),
    ("rovers: rover\n" + _plan("  - {kind: hold}\n"), "rovers", "needs a non-empty list"),
    ("rovers: [rover, rover]\n" + _plan("  - {kind: hold}\n"), "rovers[1]", "named twice"),
    # the issue's: 1,000 holds of 100 s; the least time of drives and turns counts too
    (
        _plan("  - {kind: hold, duration: 100}\n" * TASKS_MAX),
        "tasks[6]",
        f"brings the plan's time to at least 700 s; a plan may run at most "
        f"{PLAN_SECONDS_MAX:g} s simulated",
    ),
    (
        _plan(
            "  - {kind: straight, distance: 1000, speed: 2}\n  - {kind: turn, angle_deg: 3600}\n"
        ),
        "tasks[1]",
        "brings the plan's time to at least 620 s",
    ),
    # against the bundle: its rovers, their arm joints
    ("rovers: [rover, collector]\n" + _plan("  - {kind: hold}\n"), "rovers[1]", "no rover"),
    (
        _plan("  - {kind: hold}\n  - {kind: hold}\narm: {kind: arm_wave, joint: 6}\n"),
        "arm.joint",
        "6 is not an arm joint of rover 'rover' (joints 0 .. 5)",
    ),
]


def test_bad_plans_are_one_error_naming_the_file_and_element(floor, tmp_path, capsys):
    report = tmp_path / "r.json"
    for i, (text, element, message) in enumerate(BAD):
        plan = tmp_path / f"plan{i}.yaml"
        plan.write_text(text)
        with pytest.raises(SystemExit) as done:
            args = [str(floor), "--plan", str(plan), "--report", str(report)]
            run_command(rover_drive_command, args, prog_name="rover-drive")
        out, err = capsys.readouterr()
        assert done.value.code == 2 and out == "", (text, out, err)
        assert err.count("\n") == 1, err
        assert err.startswith(f"error: {plan}: {element}"), (err, element)
        assert message in err, (message, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        f"plan{i}.yaml" for i in range(len(BAD))
    )


def test_plan_goes_with_no_task_option_and_reads_only_a_regular_file(floor, tmp_path, capsys):
    plan = tmp_path / "plan.yaml"
    plan.write_text("rovers: [rover]\n" + _plan("  - {kind: hold}\n"))
    os.mkfifo(tmp_path / "fifo.yaml")
    cases = [
        (["--plan", str(plan), "--distance", "3"], "--distance does not go with --plan"),
        (["--plan", str(plan), "--arm"], "--arm does not go with --plan"),
        (["--plan", str(plan), "--task", "deliver"], "--task does not go with --plan"),
        (["--plan", str(plan), "--rover", "rover"], "--rover does not go with a plan that"),
        (["--plan", str(tmp_path / "fifo.yaml")], "fifo.yaml"),
        (["--plan", str(tmp_path / "none.yaml")], "none.yaml"),
    ]
    for args, needle in cases:
        with pytest.raises(SystemExit) as done:
            run_command(rover_drive_command, [str(floor), *args], prog_name="rover-drive")
        out, err = capsys.readouterr()
        assert done.value.code == 2 and out == "", (args, out, err)
        assert err.startswith("error:") and err.count("\n") == 1 and needle in err, (args, err)
    # as a user runs it: one line, exit 2
    code = "from urdf2mjcf.cli import rover_drive_main; rover_drive_main()"
    plan.write_text(_plan("  - {kind: straight, distance: 1, speed: 99}\n"))
    proc = subprocess.run(
        [sys.executable, "-c", code, str(floor), "--plan", str(plan)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2 and proc.stdout == "", proc
    assert (
        proc.stderr
        == f"error: {plan}: tasks[0].speed: 99 is out of range (above 0 to 10) (line 2)\n"
    )


def test_the_docs_list_the_registrys_kinds_and_keys(floor, tmp_path, monkeypatch, capsys):
    text = (ROOT / "docs" / "mira3d.md").read_text()
    section = text.split("## Task plans", 1)[1].split("\n## ", 1)[0]
    assert "\n".join(keys_table()) in section
    kinds = re.findall(r"^\| `(\w+)` \|", section, flags=re.M)
    assert list(dict.fromkeys(kinds)) == list(TASKS)
    (example,) = re.findall(r"```yaml\n(.*?)```", section, flags=re.S)
    plan = check_shape(yaml.safe_load(example), None)
    assert plan.rovers == ("collector",) and [t["kind"] for t in plan.tasks] == list(DRIVES)
    assert plan.arm == {"kind": "arm_wave", "joint": 0, "amplitude": 0.3}
    # the example error is what the command prints
    monkeypatch.chdir(tmp_path)
    Path("plan.yaml").write_text(BAD[8][0])
    with pytest.raises(SystemExit):
        run_command(rover_drive_command, [str(floor), "--plan", "plan.yaml"])
    line = capsys.readouterr().err.strip()
    assert line.startswith("error: plan.yaml: tasks[2].distance") and line in section.splitlines()


def test_a_plan_that_runs_past_its_bound_is_stopped_naming_the_task(
    floor, tmp_path, capsys, monkeypatch
):
    # within the bound at the least (0.6 s at 0.5 m/s) but ramping up and braking takes
    # longer: the run stops when the plan's time is spent, at the task running then
    monkeypatch.setattr(plan_file, "PLAN_SECONDS_MAX", 1.0)
    plan = tmp_path / "plan.yaml"
    plan.write_text(_plan("  - {kind: hold, duration: 0.2}\n  - {kind: straight, distance: 0.3}\n"))
    report = tmp_path / "r.json"
    with pytest.raises(SystemExit) as done:
        args = [str(floor), "--plan", str(plan), "--settle", "0", "--report", str(report)]
        run_command(rover_drive_command, args, prog_name="rover-drive")
    err = capsys.readouterr().err
    assert done.value.code == 2, err
    (line,) = [x for x in err.splitlines() if x.startswith("error: ")]
    assert line.startswith(f"error: {plan}: tasks[1]"), line
    assert "not done when the plan reached its bound of 1 s simulated" in line
    assert not report.exists()


def test_the_docs_give_the_plans_time_bound():
    text = (ROOT / "docs" / "mira3d.md").read_text()
    section = text.split("## Task plans", 1)[1].split("\n## ", 1)[0]
    assert f"at most {PLAN_SECONDS_MAX:g} s of simulated time" in section
