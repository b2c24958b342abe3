"""Issue 33's own robot: the iMETRO robot (rail, lift, UR arm and gripper), as
make-facility converts it into ``components/``, calibrated from a log of a perturbed copy
of itself (its arm's damping tripled), with sensor noise: ``urdf2mjcf calibrate`` from the
nominal model recovers each damping within 2 % and the held-out tracking error falls at
least 5x."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import mujoco
import pytest
from lxml import etree

from tests.calibrate import arm
from tests.security.attack import run
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]
PERTURBED = ("shoulder_lift_joint", "elbow_joint", "wrist_1_joint")
FIXED = ("rail", "lift", "lift_middle", "shoulder_pan_joint", "wrist_2_joint", "wrist_3_joint")


@pytest.fixture(scope="module")
def robot(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("imetro") / "imetro"
    build_facility(load_recipe(ROOT / "recipes" / "imetro.yaml"), out, root=ROOT)
    return out / "components" / "imetro_robot" / "imetro_robot.xml"


def test_the_imetro_robot_recovers_its_arms_damping(robot, tmp_path):
    m = mujoco.MjModel.from_xml_path(str(robot))
    nominal = {j: float(m.dof_damping[m.jnt_dofadr[m.joint(j).id]]) for j in PERTURBED}
    assert all(v > 0 for v in nominal.values())
    truth = {j: 3.0 * v for j, v in nominal.items()}
    real = tmp_path / "real"
    shutil.copytree(robot.parent, real)
    tree = etree.parse(str(robot))
    for el in tree.iter("joint"):
        if el.get("name") in truth:
            el.set("damping", repr(truth[el.get("name")]))
    (real / robot.name).write_bytes(etree.tostring(tree))
    log = arm.record(real / robot.name, tmp_path / "log.csv", seconds=8.0, amplitude=0.2)
    params = tmp_path / "params.yaml"
    fixed = [*FIXED, "finger_1_joint", "finger_2_joint"]
    params.write_text("joints:\n" + "".join(f"  {j}: {{damping: false}}\n" for j in fixed))
    res = run(
        "urdf2mjcf", "calibrate", str(robot), str(log), "-o", "cal", "--free", "damping",
        "--params", str(params), cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    found = {p["name"]: p["after"] for p in report["parameters"]}
    assert set(found) == {f"{j}.damping" for j in PERTURBED}
    for j, value in truth.items():
        assert found[f"{j}.damping"] == pytest.approx(value, rel=0.02), j
    assert report["held_out_improvement"] >= 5.0
