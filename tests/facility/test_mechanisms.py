"""Mechanisms hold and release (issue 12): every latch facility.json lists holds its
joint shut with the lock at its "locked" value (a push of 8 N m, or 50 N on a slide,
moves it less than 2 deg / 5 mm in 1 s) and lets it open with the lock at its
"released" value (the same push opens it more than 20 deg / 5 cm, or, for a door too
heavy and damped to get that far in 1 s however free it is, at least 90 % of what the
analytic free door does). Checked in a built facility (the mockups without the robot,
with hatch 4040 placed too), so the facility's collision classes are the ones tested:
the catches and bolts must touch their strikes there."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe

from .mechanism_checks import free_swing, hold, push_latched

ROOT = Path(__file__).resolve().parents[2]
RECIPE = ROOT / "recipes" / "imetro-no-robot.yaml"
SETS = {"hatch_4040": "true", "placements.hatch_4040": "{xyz: [-1.4, -1.2, 0], yaw: 0}"}
TORQUE, FORCE = 8.0, 50.0  # N m on a hinge, N on a slide
HELD = {mujoco.mjtJoint.mjJNT_HINGE: math.radians(2), mujoco.mjtJoint.mjJNT_SLIDE: 0.005}
OPEN = {mujoco.mjtJoint.mjJNT_HINGE: math.radians(20), mujoco.mjtJoint.mjJNT_SLIDE: 0.05}


@pytest.fixture(scope="module")
def facility(tmp_path_factory) -> tuple[mujoco.MjModel, list[dict]]:
    import json

    recipe = load_recipe(RECIPE, SETS, root=ROOT)
    out = build_facility(recipe, tmp_path_factory.mktemp("mechanisms") / "f", root=ROOT)
    manifest = json.loads((out.output / "facility.json").read_text())
    return mujoco.MjModel.from_xml_path(str(out.scene)), manifest["mechanisms"]


def _fresh(m: mujoco.MjModel) -> mujoco.MjData:
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return d


def _push(m: mujoco.MjModel, joint: str) -> float:
    return TORQUE if m.jnt_type[m.joint(joint).id] == mujoco.mjtJoint.mjJNT_HINGE else FORCE


def test_every_latched_mockup_is_listed(facility):
    m, mechanisms = facility
    held = {x["holds"] for x in mechanisms}
    doors = {f"trainer_door_{s}_joint" for s in ("left_rear", "left_front", "right_rear", "right_front")}
    assert doors | {"hatch_4060_door_joint", "hatch_4040_door_joint", "express_rack_merlin_door_joint"} <= held
    for x in mechanisms:
        assert set(x) == {"name", "component", "holds", "lock", "locked", "released"}
        for key in ("holds", "lock"):
            assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, x[key]) >= 0, x


def test_every_mechanism_holds_when_locked(facility):
    m, mechanisms = facility
    moved = {}
    for x in mechanisms:
        trace = push_latched(m, _fresh(m), x["holds"], x["lock"], x["locked"], _push(m, x["holds"]))
        moved[x["name"]] = float(np.abs(trace).max())
    kind = {x["name"]: int(m.jnt_type[m.joint(x["holds"]).id]) for x in mechanisms}
    failed = {n: v for n, v in moved.items() if v >= HELD[kind[n]]}
    assert not failed, f"moved with the lock locked (rad or m): {failed}; all: {moved}"


def test_every_mechanism_opens_when_released(facility):
    m, mechanisms = facility
    opened, wanted = {}, {}
    for x in mechanisms:
        d = _fresh(m)
        push = _push(m, x["holds"])
        trace = push_latched(m, d, x["holds"], x["lock"], x["released"], push)
        opened[x["name"]] = float(trace[-1])
        kind = int(m.jnt_type[m.joint(x["holds"]).id])
        # the reference: the same joint with nothing in its way, from rest, for 1 s
        wanted[x["name"]] = min(OPEN[kind], 0.9 * free_swing(m, _fresh(m), x["holds"], push, 1.0))
    failed = {n: (opened[n], wanted[n]) for n in opened if opened[n] <= wanted[n]}
    assert not failed, f"(opened, wanted) with the lock released: {failed}"
    # the 20 deg of the issue, wherever the door's own dynamics allow it
    assert sum(v >= math.radians(20) for v in opened.values()) >= len(opened) - 2, opened


def test_hatch_wheel_draws_the_bolt(facility):
    """Turning the outer crank wheel by its joint moves the bolt (a full turn: 35 mm
    back) and the inner wheel with it, in the facility."""
    m, _ = facility
    for p in ("hatch_4060_", "hatch_4040_"):
        d = _fresh(m)
        bolt = m.joint(p + "latch_joint").qposadr[0]
        inner = m.joint(p + "inner_wheel_joint").qposadr[0]
        seen = []
        for k in range(1000):  # a full turn in 2 s, then held
            target = min(1.0, k / 500) * 2 * math.pi
            hold(m, d, p + "outer_wheel_joint", target)
            mujoco.mj_step(m, d)
            if k % 100 == 99:
                seen.append((target, d.qpos[bolt], d.qpos[inner]))
        # while turning at pi rad/s the coupling lags a little; once held, it is exact
        for target, b, i in seen:
            assert b == pytest.approx(0.035 * target / (2 * math.pi), abs=1e-3), (p, seen)
            assert i == pytest.approx(target, abs=0.1), (p, seen)
        assert seen[-1][1] == pytest.approx(0.035, abs=1e-4), (p, seen)
        assert seen[-1][2] == pytest.approx(2 * math.pi, abs=0.01), (p, seen)


def test_a_mechanism_naming_a_missing_joint_is_an_error(tmp_path):
    """The declaration is checked against the compiled model: file, key and line."""
    table = (ROOT / "recipes" / "components" / "imetro.yaml").read_text()
    bad = tmp_path / "mechanisms.yaml"
    bad.write_text("# bad\ndoor_latch: {holds: door_joint, lock: no_such_joint, locked: 0, released: 1}\n")
    (tmp_path / "imetro.yaml").write_text(
        table.replace("facility/mockups/hatch/config/mechanisms.yaml", str(bad))
    )
    recipe_text = RECIPE.read_text().replace("components/imetro.yaml", str(tmp_path / "imetro.yaml"))
    (tmp_path / "recipe.yaml").write_text(recipe_text)
    recipe = load_recipe(tmp_path / "recipe.yaml", {"express_rack": "false"}, root=ROOT)
    with pytest.raises(InputError) as err:
        build_facility(recipe, tmp_path / "out", root=ROOT)
    text = str(err.value)
    assert str(bad) in text and "door_latch.lock" in text and "line 2" in text, text
    assert "hatch_4060_no_such_joint" in text, text
