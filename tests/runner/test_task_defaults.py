"""Each rover task parameter's default is declared once, on its task's dataclass: the
plan's keys, the docs' table and ``rover-drive``'s options take it from there, so a
task built from a plan that leaves a key out is the task built with no argument (a
turn's top rate was 0.5 rad/s in the dataclass and 30 deg/s in the plan and the CLI)."""

from __future__ import annotations

import ast
import math
from dataclasses import fields
from pathlib import Path

import pytest

from urdf2mjcf.runner.rover import cli, tasks
from urdf2mjcf.runner.rover.tasks import TASKS, ArmWave, Hold, Straight, Turn

REQUIRED = {"straight": {"distance": 2.0}, "turn": {"angle_deg": 90.0}}
BARE = {
    "straight": Straight(2.0),
    "turn": Turn(math.radians(90.0)),
    "hold": Hold(),
    "arm_wave": ArmWave(),
}


@pytest.mark.parametrize("kind", list(TASKS))
def test_a_plan_that_leaves_every_key_out_builds_the_bare_task(kind):
    assert TASKS[kind].build({"kind": kind, **REQUIRED.get(kind, {})}) == BARE[kind]


def test_every_key_default_is_its_dataclass_default():
    dataclasses = {"straight": Straight, "turn": Turn, "hold": Hold, "arm_wave": ArmWave}
    units = {"rate_deg": ("rate", math.radians)}
    for kind, task in TASKS.items():
        defaults = {f.name: f.default for f in fields(dataclasses[kind])}
        for key, k in task.keys.items():
            if k.default is None:
                continue  # required
            field, to_si = units.get(key, (key, lambda x: x))
            assert to_si(k.default) == pytest.approx(defaults[field]), (kind, key)


def test_the_commands_defaults_are_the_registrys_and_not_written_again():
    params = {p.name: p for p in cli.rover_drive_command.params}
    assert params["speed"].default == TASKS["straight"].keys["speed"].default
    assert params["rate"].default == TASKS["turn"].keys["rate_deg"].default == tasks.TURN_RATE_DEG
    # no literal default beside the declaration: the options name the registry's
    source = ast.parse(Path(cli.__file__).read_text())
    literal = {
        kw.value.value
        for call in ast.walk(source)
        if isinstance(call, ast.Call) and getattr(call.func, "attr", "") == "option"
        for arg in call.args[:1]
        if isinstance(arg, ast.Constant) and arg.value in ("--speed", "--rate")
        for kw in call.keywords
        if kw.arg == "default" and isinstance(kw.value, ast.Constant)
    }
    assert not literal, literal
