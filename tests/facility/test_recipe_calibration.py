"""A component's ``calibration`` key in a recipe: its file applied to that component's
conversion, as ``urdf2mjcf SOURCE --calibration FILE`` does; a bad one refused."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
import yaml

from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]
DAMPING = 7.25  # N m s/rad: not a value the robot's description or actuator file gives


def _recipe(tmp_path: Path, calibration: object, *, attach: bool = True) -> Path:
    """recipes/imetro.yaml with its component table inline, the robot calibrated."""
    data = yaml.safe_load((ROOT / "recipes" / "imetro.yaml").read_text())
    table = yaml.safe_load((ROOT / "recipes" / "components" / "imetro.yaml").read_text())
    table["robot"]["calibration"] = calibration
    if not attach:
        del table["robot"]["attach"]
    data["components"] = table
    path = tmp_path / "recipe.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _joint(imetro_bundle: Path) -> str:
    manifest = json.loads((imetro_bundle / "facility.json").read_text())
    return manifest["components"]["robot"]["roles"]["joints"][3]  # an arm joint


def _damping(scene: Path, joint: str) -> float:
    m = mujoco.MjModel.from_xml_path(str(scene))
    return float(m.dof_damping[m.jnt_dofadr[m.joint(joint).id]])


def test_the_recipes_calibration_sets_the_built_scenes_joint_damping(imetro_bundle, tmp_path):
    joint = _joint(imetro_bundle)
    assert _damping(imetro_bundle / "scene.xml", joint) != DAMPING
    (tmp_path / "calib.yaml").write_text(f"joints:\n  {joint}: {{damping: {DAMPING}}}\n")
    recipe = load_recipe(_recipe(tmp_path, "calib.yaml"), root=ROOT)
    built = build_facility(recipe, tmp_path / "out", root=ROOT, components=False)
    assert _damping(built.scene, joint) == DAMPING  # read back by MuJoCo from the files
    # the bundle's recipe keeps the key (a rebuild from it calibrates the same)
    copy = yaml.safe_load((tmp_path / "out" / "recipe.yaml").read_text())
    assert copy["components"]["robot"]["calibration"] == "calib.yaml"


def test_a_missing_calibration_file_is_an_error_naming_the_recipe_and_key(tmp_path):
    path = _recipe(tmp_path, "nowhere.yaml")
    with pytest.raises(InputError) as err:
        build_facility(load_recipe(path, root=ROOT), tmp_path / "out", root=ROOT, components=False)
    assert str(err.value).startswith(f"{path}: components.robot.calibration: "), err.value
    assert "'nowhere.yaml' does not exist" in str(err.value)
    assert not (tmp_path / "out").exists()


def test_calibration_without_attach_is_refused_as_the_recipe_is_read(tmp_path):
    (tmp_path / "calib.yaml").write_text("joints: {}\n")
    path = _recipe(tmp_path, "calib.yaml", attach=False)
    with pytest.raises(InputError) as err:
        load_recipe(path, root=ROOT)
    assert "components.robot.calibration" in str(err.value) and "attach" in str(err.value)


def test_a_bad_calibration_file_is_one_error_line_exit_2(tmp_path):
    (tmp_path / "calib.yaml").write_text("joints:\n  rail: {damping: -1}\n")
    out = tmp_path / "out"
    code = "from urdf2mjcf.cli import make_facility_main; make_facility_main()"
    args = [str(_recipe(tmp_path, "calib.yaml")), "-o", str(out), "--root", str(ROOT)]
    proc = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=ROOT, timeout=300
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    assert "recipe.yaml: components.robot.calibration: calibration file 'calib.yaml'" in lines[0]
    assert not out.exists()
