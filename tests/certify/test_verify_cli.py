"""`urdf2mjcf verify` and `urdf2mjcf --verify` as a user runs them: a model altered by
hand fails naming what changed (exit 1), an unaltered one passes (exit 0), bad input is
one error line (exit 2), and --verify writes nothing when its certificate fails."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from lxml import etree

from tests.security.attack import assert_one_error, run

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo_arm.urdf.xacro"
NONCONVEX = ROOT / "tests" / "data" / "golden" / "nonconvex.urdf"
GRIPPER = "use_gripper:=true"


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> Path:
    """demo_arm with its gripper (a mimic joint), converted with a JSON report."""
    folder = tmp_path_factory.mktemp("demo")
    res = run(
        "urdf2mjcf",
        str(DEMO),
        GRIPPER,
        "-o",
        "out/robot.xml",
        "--report",
        "r.json",
        "-v",
        cwd=folder,
    )
    assert res.returncode == 0, res.stderr
    return folder


def _alter(src: Path, dest: Path, xpath: str, attr: str, value: str) -> Path:
    tree = etree.parse(str(src))
    (el,) = tree.xpath(xpath)
    el.set(attr, value)
    dest.parent.mkdir(parents=True, exist_ok=True)
    tree.write(str(dest))
    return dest


def test_the_report_carries_the_certificate(demo):
    cert = json.loads((demo / "r.json").read_text())["certificate"]
    for key in (
        "reference", "frames", "joints", "mass", "dynamics", "collision", "checks", "changes",
        "passed", "failures",
    ):  # fmt: skip
        assert key in cert, key
    # pinocchio is installed (the test extra): urdfdom's frames are the reference, yourdfpy
    # reads the parts, and the two agree on this robot
    assert cert["reference"]["implementation"] == "urdfdom" and cert["reference"]["version"]
    refs = cert["references"]
    assert refs["frames"].startswith("urdfdom ") and refs["parts"].startswith("yourdfpy ")
    assert refs["agreement"]["compared"] and refs["agreement"]["agree"]
    assert set(cert["frames"]) >= {
        "max_position_error_m",
        "max_rotation_error_rad",
        "configurations",
    }
    assert set(cert["mass"]) >= {"urdf_kg", "mjcf_kg", "com_error_m"}
    assert cert["mass"]["urdf_kg"] == pytest.approx(9.9)  # 5 + 2 + 1.5 + 1 + 0.3 + 2 x 0.05
    assert cert["passed"] is True and cert["failures"] == []


def test_the_conversion_prints_its_certificate(demo, tmp_path):
    res = run("urdf2mjcf", str(DEMO), "-o", "o/robot.xml", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    last = res.stdout.strip().splitlines()[-1]
    assert last.startswith("certificate: passed (frames "), res.stdout
    res = run("urdf2mjcf", str(DEMO), "-o", "v/robot.xml", "-v", cwd=tmp_path)
    assert "certificate against urdfdom" in res.stderr and "  frames     ok" in res.stderr
    assert "urdfdom and yourdfpy agree" in res.stderr


def test_an_unaltered_model_passes(demo):
    res = run(
        "urdf2mjcf", "verify", str(DEMO), "out/robot.xml", GRIPPER, "--report", "v.json", cwd=demo
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("certificate: passed"), res.stdout
    assert json.loads((demo / "v.json").read_text())["certificate"]["passed"] is True


ALTERATIONS = [
    pytest.param(
        "//body[@name='forearm']", "pos", "0.001 0 0.35",
        ["failed: frames.max_position_error_m: 0.001 m", "failed: joints.anchor: joint 'forearm_joint'"],
        id="body-shifted-1mm",
    ),
    pytest.param(
        "//joint[@name='upper_arm_joint']", "axis", "0 -1 0",
        ["failed: joints.axis: joint 'upper_arm_joint': axis off by 3.14 rad"],
        id="axis-flipped",
    ),
    pytest.param(
        "//body[@name='forearm']/inertial", "mass", "2.0",
        ["failed: mass.body 'forearm': 2 kg, description 1 kg"],
        id="mass-doubled",
    ),
    pytest.param(
        "//joint[@name='forearm_joint']", "range", "-2.5 2.4",
        ["failed: joints.limits: joint 'forearm_joint'"],
        id="limit-changed",
    ),
    pytest.param(
        "//equality/joint", "polycoef", "0 0.5 0 0 0",
        ["failed: joints.mimic: joint 'finger_right_joint'"],
        id="mimic-changed",
    ),
]  # fmt: skip


@pytest.mark.parametrize(("xpath", "attr", "value", "needles"), ALTERATIONS)
def test_an_altered_model_fails_naming_what_changed(demo, tmp_path, xpath, attr, value, needles):
    model = _alter(demo / "out" / "robot.xml", tmp_path / "robot.xml", xpath, attr, value)
    res = run("urdf2mjcf", "verify", str(DEMO), str(model), GRIPPER, cwd=tmp_path)
    assert res.returncode == 1, res.stderr
    for needle in needles:
        assert needle in res.stderr, (needle, res.stderr)
    assert res.stderr.strip().splitlines()[-1].startswith("certificate: FAILED: ")
    assert not any(ln.startswith("error:") for ln in res.stderr.splitlines())


def test_a_collision_mesh_swapped_for_a_box_fails(tmp_path):
    res = run("urdf2mjcf", str(NONCONVEX), "-o", "out/robot.xml", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    out = tmp_path / "out" / "robot.xml"
    res = run("urdf2mjcf", "verify", str(NONCONVEX), str(out), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    tree = etree.parse(str(out))
    (geom,) = tree.xpath("//geom[@name='paddle_collision']")
    del geom.attrib["mesh"]
    geom.set("type", "box")
    geom.set("size", "0.3 0.3 0.3")
    tree.write(str(out))
    res = run("urdf2mjcf", "verify", str(NONCONVEX), str(out), cwd=tmp_path)
    assert res.returncode == 1, res.stderr
    failed = [ln for ln in res.stderr.splitlines() if ln.startswith("failed: collision")]
    assert failed and all("paddle" in ln for ln in failed), res.stderr


def test_a_name_map_matches_a_model_that_names_things_differently(demo, tmp_path):
    tree = etree.parse(str(demo / "out" / "robot.xml"))
    (body,) = tree.xpath("//body[@name='forearm']")
    body.set("name", "arm3")
    (joint,) = tree.xpath("//joint[@name='forearm_joint']")
    joint.set("name", "j3")
    for el in tree.xpath("//*[@joint='forearm_joint']"):
        el.set("joint", "j3")
    tree.write(str(tmp_path / "robot.xml"))
    res = run("urdf2mjcf", "verify", str(DEMO), "robot.xml", GRIPPER, cwd=tmp_path)
    assert res.returncode == 1
    assert "failed: frames.missing_links: 1 > 0 (no body or site for link 'forearm')" in res.stderr
    assert "failed: joints.missing: joint 'forearm_joint'" in res.stderr
    (tmp_path / "names.yaml").write_text("links: {forearm: arm3}\njoints: {forearm_joint: j3}\n")
    res = run(
        "urdf2mjcf", "verify", str(DEMO), "robot.xml", GRIPPER, "--name-map", "names.yaml",
        cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr


def test_verify_on_a_conversion_writes_only_what_passes(demo, tmp_path):
    report = json.loads((demo / "r.json").read_text())["certificate"]
    assert report["frames"]["max_rotation_error_rad"] > 0  # a tolerance of 0 cannot be met
    res = run("urdf2mjcf", str(DEMO), GRIPPER, "-o", "ok/robot.xml", "--verify", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "ok" / "robot.xml").is_file() and (tmp_path / "ok" / "scene.xml").is_file()
    res = run(
        "urdf2mjcf", str(DEMO), GRIPPER, "-o", "bad/robot.xml", "--verify",
        "--tolerance", "frame_rotation_rad=0", "--report", "bad.json", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 1, res.stderr
    assert "failed: frames.max_rotation_error_rad:" in res.stderr
    assert res.stderr.strip().splitlines()[-1].endswith("; nothing written")
    assert not (tmp_path / "bad").exists() and not (tmp_path / "bad.json").exists()
    assert "Traceback" not in res.stderr
    assert not any(ln.startswith("error:") for ln in res.stderr.splitlines())


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["missing.xml"], ["model not found"]),
        (["garbage.xml"], ["not well-formed XML", "tag mismatch"]),
        (["robot.xml", "--tolerance", "nope=1"], ["unknown tolerance 'nope'"]),
        (["robot.xml", "--tolerance", "com_m=nan"], ["--tolerance", "not finite"]),
        (["robot.xml", "--tolerance", "com_m"], ["--tolerance", "NAME=NUMBER"]),
        (["robot.xml", "--name-map", "bad.yaml"], ["--name-map", "'links' must map names"]),
        (["other.xml"], ["no body or site for any link of 'demo_arm' but its root"]),
    ],
    ids=["missing", "not-mjcf", "unknown-tolerance", "nan", "no-value", "bad-name-map", "other"],
)
def test_bad_input_is_one_error_line(demo, tmp_path, args, needles):
    shutil.copy(demo / "out" / "robot.xml", tmp_path / "robot.xml")
    (tmp_path / "garbage.xml").write_text("<mujoco><worldbody><body><oops/></body></mujoco>")
    (tmp_path / "other.xml").write_text("<mujoco><worldbody/></mujoco>")
    (tmp_path / "bad.yaml").write_text("links: [a, b]\n")
    res = run("urdf2mjcf", "verify", str(DEMO), *args, cwd=tmp_path)
    assert_one_error(res, *needles)
