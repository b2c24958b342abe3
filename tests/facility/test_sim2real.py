"""The iMETRO paper's sim-to-real failure causes as recipe flags (its Table II;
facility/worlds/imetro_world/urdf/sim2real.xacro, docs/facility.md): each builds,
adds what it says, and behaves. Off by default: the default recipe has none."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest

from urdf2mjcf.errors import ConversionError
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import apply_sets, load_recipe, parse_recipe
from urdf2mjcf.schema import load

ROOT = Path(__file__).resolve().parents[2]
FLAGS = {"cable_housing": False, "floor_beams": False, "strap_stiffness": 0}
BEAM_TOP = 0.10
G = 9.81


def _recipe(name: str, sets: dict[str, str]) -> Any:
    """A shipped recipe with the sim-to-real flags declared (as recipes/imetro.yaml
    declares them) and ``sets`` applied."""
    data, src = load(ROOT / "recipes" / name, "recipe")
    data["flags"] = {**FLAGS, **data["flags"]}
    return parse_recipe(apply_sets(data, sets, src), src, ROOT)


def _build(recipe: Any, out: Path) -> tuple[mujoco.MjModel, mujoco.MjData, dict]:
    report = build_facility(recipe, out, root=ROOT)
    m = mujoco.MjModel.from_xml_path(str(report.scene))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return m, d, json.loads((report.output / "facility.json").read_text())


def test_default_recipe_declares_the_flags_off():
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
    assert {k: recipe.flags[k] for k in FLAGS} == FLAGS


def test_floor_beams_raise_the_floor_under_the_ctb(tmp_path):
    ctb = "{xyz: [1.2, 0.8, 0.105], yaw: 1.5707963267948966}"
    recipe = _recipe("imetro-no-robot.yaml", {"floor_beams": "true", "placements.ctb": ctb})
    m, d, manifest = _build(recipe, tmp_path / "beams")
    beams = m.body("floor_beams").id
    tops = [
        d.geom_xpos[g][2] + m.geom_size[g][2] for g in range(m.ngeom) if m.geom_bodyid[g] == beams
    ]
    assert tops and np.allclose(tops, BEAM_TOP)
    for _ in range(1000):  # 2 s: the bag settles on the beams, not on the floor
        mujoco.mj_step(m, d)
    bag = m.body("ctb").id
    assert d.xpos[bag][2] == pytest.approx(BEAM_TOP, abs=2e-3)
    touching = {
        m.body(m.geom_bodyid[g]).name for c in d.contact[: d.ncon] for g in c.geom if g >= 0
    }
    assert "floor_beams" in touching and "floor" not in touching, touching
    assert manifest["flags"]["floor_beams"] is True


def test_floor_beams_with_the_ctb_on_the_floor_is_an_error(tmp_path):
    recipe = _recipe("imetro-no-robot.yaml", {"floor_beams": "true"})
    with pytest.raises(ConversionError, match="floor_beams: the CTB stands on the beams"):
        build_facility(recipe, tmp_path / "bad", root=ROOT)


@pytest.mark.parametrize("stiffness", [900.0, 3000.0])
def test_stretchy_strap_stretches_by_hookes_law(tmp_path, stiffness):
    """A steady pull up on the strap of half the bag's weight (the bag stays down): the
    strap joint stretches F / k, the configured compliance (lifted by its strap, the
    whole bag's weight stretches it m_bag g / k)."""
    recipe = _recipe("imetro-no-robot.yaml", {"strap_stiffness": str(stiffness)})
    m, d, manifest = _build(recipe, tmp_path / "strap")
    joint = m.joint("ctb_strap_joint")
    assert m.jnt_stiffness[joint.id] == pytest.approx(stiffness)
    assert "ctb_strap_joint" in manifest["components"]["ctb"]["joints"]
    strap, bag = m.body("ctb_strap").id, m.body("ctb").id
    for _ in range(500):  # the bag settles on the floor first
        mujoco.mj_step(m, d)
    pull = 0.5 * m.body_mass[bag] * G
    bag_z = d.xpos[bag][2]
    stretch = []
    for _ in range(1500):  # 3 s
        d.xfrc_applied[strap, 2] = pull + m.body_mass[strap] * G  # the strap's own weight too
        mujoco.mj_step(m, d)
        stretch.append(d.qpos[joint.qposadr[0]])
    assert d.xpos[bag][2] == pytest.approx(bag_z, abs=1e-3), "the bag stays down"
    assert np.mean(stretch[-250:]) == pytest.approx(pull / stiffness, rel=0.02)
    assert np.ptp(stretch[-250:]) < 0.02 * pull / stiffness, "and it has settled"


def test_rigid_strap_by_default(tmp_path):
    m, _, manifest = _build(_recipe("imetro-no-robot.yaml", {}), tmp_path / "rigid")
    assert manifest["components"]["ctb"]["joints"] == ["ctb_joint"]
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "ctb_strap") < 0


def test_cable_housing_rides_on_the_wrist_camera_and_collides_as_the_robot(tmp_path):
    m, d, _ = _build(_recipe("imetro.yaml", {"cable_housing": "true"}), tmp_path / "housing")
    housing = m.body("cable_housing").id
    assert m.body(m.body_parentid[housing]).name == "wrist_camera_link"
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == housing and m.geom_contype[g]]
    assert len(geoms) == 2
    assert all((m.geom_contype[g], m.geom_conaffinity[g]) == (1, 1) for g in geoms)
    # no contact at home: the robot stands as it does without it
    assert not [
        c for c in d.contact[: d.ncon] if housing in (m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2])
    ]
    # it moves with the wrist
    before = d.xpos[housing].copy()
    d.qpos[m.joint("wrist_2_joint").qposadr[0]] += 0.5
    mujoco.mj_forward(m, d)
    assert np.linalg.norm(d.xpos[housing] - before) > 0.02
