"""URDF 1.2 acceleration limits in a bundle's facility.json: read into the robot and
obeyed by the demo's planned moves (MuJoCo does not enforce them)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from urdf2mjcf.runner import demo
from urdf2mjcf.runner.load import LoadError, load
from urdf2mjcf.runner.plan import JointPlanner

LIMITED = 6  # a wrist joint (role index): the demo's own AMAX for it is 3 rad/s^2


def _bundle(imetro_bundle: Path, tmp_path: Path, limits: object) -> Path:
    folder = tmp_path / "bundle"
    shutil.copytree(imetro_bundle, folder)
    path = folder / "facility.json"
    data = json.loads(path.read_text())
    data["components"]["robot"]["motion_limits"] = limits
    path.write_text(json.dumps(data, indent=2))
    return folder


def test_a_stated_acceleration_limit_slows_a_planned_move_and_holds(imetro_bundle, tmp_path):
    plain = load(imetro_bundle).robot
    assert plain.amax == []
    joint = plain.joint_names[LIMITED]
    limits = {joint: {"acceleration": 0.6, "deceleration": 0.4, "jerk": 5.0}}
    fac = load(_bundle(imetro_bundle, tmp_path, limits))
    r = fac.robot
    assert r.amax == [None] * LIMITED + [0.4] + [None] * (len(r.joints) - LIMITED - 1)
    amax = demo.planner_amax(r)
    assert amax[LIMITED] == 0.4 and np.array_equal(
        np.delete(amax, LIMITED), np.delete(demo.AMAX, LIMITED)
    )
    m, start = fac.model, fac.data.qpos.copy()
    goal = start[r.qpos].copy()
    goal[LIMITED] += 0.5  # the wrist turns in place from home: a straight, free path
    vmax = np.full(len(r.joints), 1.0)

    def move(acc: np.ndarray):
        return JointPlanner(m, list(r.joints), vmax, acc, seed=0).plan(start, goal)

    fast, slow = move(np.asarray(demo.AMAX, float)), move(amax)
    assert fast.planner == slow.planner == "straight"
    assert slow.times[-1] > 1.5 * fast.times[-1], (fast.times[-1], slow.times[-1])
    # the joint's acceleration along the retimed path, from its samples alone
    t, q = slow.times, slow.q[:, LIMITED]
    acc = np.diff(np.diff(q) / np.diff(t)) / np.diff(t)[1:]
    assert np.max(np.abs(acc)) <= 0.4 * 1.01, np.max(np.abs(acc))
    assert np.max(np.abs(acc)) > 0.3  # the limit is what binds the move
    np.testing.assert_allclose(q[-1] - q[0], 0.5, atol=1e-9)


@pytest.mark.parametrize(
    ("limits", "element", "says"),
    [
        ({"J": {"acceleration": -1}}, "motion_limits.J.acceleration", "not a positive number"),
        ({"J": {"deceleration": "fast"}}, "motion_limits.J.deceleration", "not a positive"),
        ({"J": {"snap": 1.0}}, "motion_limits.J", "a mapping of acceleration"),
        ([1, 2], "motion_limits", "not a mapping"),
    ],
)
def test_a_bad_motion_limit_is_one_error_naming_the_key(
    imetro_bundle, tmp_path, limits, element, says
):
    joint = load(imetro_bundle).robot.joint_names[LIMITED]
    if isinstance(limits, dict):
        limits = {joint: limits["J"]}
        element = element.replace(".J", f".{joint}")
    folder = _bundle(imetro_bundle, tmp_path, limits)
    with pytest.raises(LoadError) as err:
        load(folder)
    text = str(err.value)
    assert "\n" not in text and says in text, text
    assert text.startswith(f"{folder / 'facility.json'}: components.robot.{element}: "), text
