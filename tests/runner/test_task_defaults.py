"""Each rover task parameter's default is declared once, in the task kinds' registry
(runner/task_kinds.py), which the task dataclasses and the plan's keys read: so a task built from a
plan that leaves a key out is the task built with no argument (a turn's top rate was
0.5 rad/s in the dataclass and 30 deg/s in the plan and the CLI); the command line's
defaults are checked in test_task_kinds.py."""

from __future__ import annotations

import math
from dataclasses import fields

import pytest

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
