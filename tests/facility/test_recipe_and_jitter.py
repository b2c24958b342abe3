"""Recipes parse strictly, --set edits them, and jitter is reproducible."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import xacro_args
from urdf2mjcf.facility.jitter import jittered
from urdf2mjcf.facility.recipe import Pose2D, load_recipe

ROOT = Path(__file__).resolve().parents[2]
RECIPES = sorted((ROOT / "recipes").glob("*.yaml"))


@pytest.mark.parametrize("path", RECIPES, ids=[p.stem for p in RECIPES])
def test_every_shipped_recipe_parses_and_names_an_existing_xacro(path):
    recipe = load_recipe(path)
    assert (ROOT / recipe.xacro).is_file()
    if recipe.actuator_config:
        assert (ROOT / recipe.actuator_config).is_file()


def test_set_changes_flags_and_dotted_fields(tmp_path):
    recipe = load_recipe(
        ROOT / "recipes" / "imetro.yaml",
        {"hatch_4040": "true", "jitter.ctb_yaw": "0.5", "placements.trainer.yaw": "3.0"},
    )
    assert recipe.flags["hatch_4040"] is True
    assert recipe.jitter["ctb_yaw"] == 0.5
    assert recipe.placements["trainer"].yaw == 3.0


@pytest.mark.parametrize(
    "text, element",
    [
        ("name: x\nxacro: a.xacro\nflavour: 1\n", "flavour"),
        ("name: x\nxacro: a.xacro\nplacements: {t: {xyz: [1, 2]}}\n", "placements.t.xyz"),
        ("name: x\nxacro: a.xacro\njitter: {ctb_position: -1}\n", "jitter.ctb_position"),
        ("name: x\nxacro: a.xacro\nsimulation: {timestep: fast}\n", "simulation.timestep"),
        ("xacro: a.xacro\n", "name"),
        ("name: [unclosed\n", None),
    ],
)
def test_bad_recipe_is_an_input_error_naming_file_and_key(tmp_path, text, element):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as info:
        load_recipe(path)
    assert "bad.yaml" in str(info.value)
    if element:
        assert element in str(info.value)


POSES = {"trainer": Pose2D((1.0, 2.0, 0.0), 0.5), "hatch": Pose2D((-1.0, 0.0, 0.0), 0.0)}
CTB = Pose2D((0.8, 0.8, 0.13), math.pi / 2)
RANGES = {"position": 0.02, "yaw": 0.0175, "ctb_position": 0.05, "ctb_yaw": 0.2618}


def test_no_seed_keeps_nominal_poses():
    placements, ctb, offsets = jittered(POSES, CTB, RANGES, None)
    assert placements == POSES and ctb == CTB and offsets == {}


def test_same_seed_same_poses_and_offsets_within_ranges():
    a = jittered(POSES, CTB, RANGES, 7)
    b = jittered(POSES, CTB, RANGES, 7)
    assert a == b
    placements, ctb, offsets = a
    for name, delta in offsets.items():
        pos = RANGES["ctb_position" if name == "ctb" else "position"]
        yaw = RANGES["ctb_yaw" if name == "ctb" else "yaw"]
        assert abs(delta["dx"]) <= pos and abs(delta["dy"]) <= pos and abs(delta["dyaw"]) <= yaw
    assert ctb.xyz[2] == CTB.xyz[2], "heights are not jittered"


def test_different_seeds_move_poses_and_one_range_does_not_shift_another():
    p1, c1, _ = jittered(POSES, CTB, RANGES, 1)
    p2, c2, _ = jittered(POSES, CTB, RANGES, 2)
    assert c1 != c2 and p1 != p2
    # Turning off mockup jitter leaves the CTB's draw unchanged.
    _, c_only, _ = jittered(POSES, CTB, {**RANGES, "position": 0.0, "yaw": 0.0}, 1)
    assert c_only == c1


def test_xacro_args_carry_flags_poses_and_simulation_options():
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
    args = xacro_args(recipe, dict(recipe.placements), recipe.ctb)
    assert args["hatch_4060"] == "true" and args["robot"] == "imetro"
    assert float(args["trainer_yaw"]) == recipe.placements["trainer"].yaw
    assert float(args["ctb_z"]) == recipe.ctb.xyz[2]
    assert args["timestep"] == "0.002"
