"""Recipes parse strictly, --set edits them, and jitter is reproducible."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import xacro_args
from urdf2mjcf.facility.jitter import jittered
from urdf2mjcf.facility.pose import Pose2D
from urdf2mjcf.facility.recipe import load_recipe

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
        {"hatch_4040": "true", "jitter.ctb.yaw": "0.5", "placements.trainer.yaw": "3.0"},
    )
    assert recipe.flags["hatch_4040"] is True
    assert recipe.jitter_ranges("ctb") == {"position": 0.05, "yaw": 0.5}
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


POSES = {
    "arm": Pose2D((0.0, 0.0, 0.0), 0.0),
    "trainer": Pose2D((1.0, 2.0, 0.0), 0.5),
    "hatch": Pose2D((-1.0, 0.0, 0.0), 0.0),
    "ctb": Pose2D((0.8, 0.8, 0.13), math.pi / 2),
}
MOCKUP = {"position": 0.02, "yaw": 0.0175}
RANGES = {"arm": None, "trainer": MOCKUP, "hatch": MOCKUP, "ctb": {"position": 0.05, "yaw": 0.2618}}
FREE = {"ctb"}


def test_no_seed_keeps_nominal_poses():
    placements, offsets = jittered(POSES, RANGES, FREE, None)
    assert placements == POSES and offsets == {}


def test_same_seed_same_poses_and_offsets_within_ranges():
    a = jittered(POSES, RANGES, FREE, 7)
    b = jittered(POSES, RANGES, FREE, 7)
    assert a == b
    placements, offsets = a
    assert set(offsets) == {"trainer", "hatch", "ctb"}, "a component without ranges never moves"
    assert placements["arm"] == POSES["arm"]
    for name, delta in offsets.items():
        pos, yaw = RANGES[name]["position"], RANGES[name]["yaw"]
        assert abs(delta["dx"]) <= pos and abs(delta["dy"]) <= pos and abs(delta["dyaw"]) <= yaw
    assert placements["ctb"].xyz[2] == POSES["ctb"].xyz[2], "heights are not jittered"


def test_different_seeds_move_poses_and_one_range_does_not_shift_another():
    p1, _ = jittered(POSES, RANGES, FREE, 1)
    p2, _ = jittered(POSES, RANGES, FREE, 2)
    assert p1["ctb"] != p2["ctb"] and p1["trainer"] != p2["trainer"]
    # Turning off mockup jitter leaves the free body's draw unchanged.
    still = {**RANGES, "trainer": {"position": 0.0, "yaw": 0.0}, "hatch": {}}
    p3, _ = jittered(POSES, still, FREE, 1)
    assert p3["ctb"] == p1["ctb"] and p3["trainer"] == POSES["trainer"]
    # A free body is drawn after the fixed ones: removing it leaves theirs unchanged.
    p4, _ = jittered({k: v for k, v in POSES.items() if k != "ctb"}, RANGES, FREE, 1)
    assert p4["trainer"] == p1["trainer"] and p4["hatch"] == p1["hatch"]


def test_xacro_args_carry_flags_poses_and_simulation_options():
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
    args = xacro_args(recipe, dict(recipe.placements))
    assert args["hatch_4060"] == "true" and args["robot"] == "imetro"
    assert float(args["trainer_yaw"]) == recipe.placements["trainer"].yaw
    assert float(args["ctb_z"]) == recipe.placements["ctb"].xyz[2]
    assert args["timestep"] == "0.002"
