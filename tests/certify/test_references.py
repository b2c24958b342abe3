"""Who the certificate believes: urdfdom (through pinocchio) for the frames where it
reads the description, yourdfpy for the parts and where urdfdom cannot read it;
where they disagree (yourdfpy's mimic after a planar joint) the certificate says
which it believes and why, and passes a model that is right. Nothing urdfdom prints
reaches our stderr."""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import pinocchio as pin
import pytest

from tests.corpus import compare_with_pinocchio
from tests.security.attack import assert_one_error, run
from urdf2mjcf.certify.reference import urdfdom_quiet

INERTIA = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'


def _link(name: str, mass: float = 1.0) -> str:
    return (
        f'<link name="{name}"><inertial><mass value="{mass}"/>{INERTIA}</inertial>'
        '<collision><geometry><box size="0.05 0.05 0.05"/></geometry></collision></link>'
    )


# A mobile base on a planar joint, a telescoping lift and a two-finger gripper whose
# second finger mimics the first: yourdfpy 0.0.60 reads the mimic's leader from the
# slot of its configuration that, after the planar joint, holds another joint.
PLANAR_GRIPPER = (
    '<robot name="mobile">'
    + '<link name="odom"/>'
    + _link("base", 20)
    + _link("lift")
    + _link("finger_l", 0.1)
    + _link("finger_r", 0.1)
    + '<joint name="base_planar" type="planar"><parent link="odom"/><child link="base"/>'
    '<axis xyz="0 0 1"/></joint>'
    '<joint name="lift_joint" type="prismatic"><parent link="base"/><child link="lift"/>'
    '<origin xyz="0.2 0 0.5"/><axis xyz="0 0 1"/>'
    '<limit lower="0" upper="1.2" effort="100" velocity="0.5"/></joint>'
    '<joint name="finger_l_joint" type="prismatic"><parent link="lift"/>'
    '<child link="finger_l"/><origin xyz="0.1 0.05 0"/><axis xyz="0 1 0"/>'
    '<limit lower="0" upper="0.04" effort="10" velocity="0.1"/></joint>'
    '<joint name="finger_r_joint" type="prismatic"><parent link="lift"/>'
    '<child link="finger_r"/><origin xyz="0.1 -0.05 0"/><axis xyz="0 -1 0"/>'
    '<limit lower="0" upper="0.04" effort="10" velocity="0.1"/>'
    '<mimic joint="finger_l_joint" multiplier="1" offset="0"/></joint>'
    "</robot>"
)


def _convert(tmp_path: Path, text: str, *args: str):
    src = tmp_path / "robot.urdf"
    src.write_text(text)
    res = run(
        "urdf2mjcf", str(src), "-o", "out/robot.xml", "--report", "r.json", *args, cwd=tmp_path
    )
    report = json.loads((tmp_path / "r.json").read_text()) if res.returncode == 0 else None
    return src, res, report


def test_a_planar_base_with_a_mimic_gripper_is_certified_by_urdfdom(tmp_path):
    src, res, report = _convert(tmp_path, PLANAR_GRIPPER, "--verify")
    assert res.returncode == 0, res.stderr
    cert = report["certificate"]
    assert cert["passed"], cert["failures"]
    assert cert["reference"]["implementation"] == "urdfdom"
    agreement = cert["references"]["agreement"]
    # yourdfpy's frames are wrong here, by what the lift moves; urdfdom is believed
    assert agreement["compared"] and not agreement["agree"], agreement
    assert agreement["link"] == "finger_r" and agreement["max_position_difference_m"] > 0.01
    assert agreement["believed"].startswith("urdfdom ")
    why = agreement["why"]
    assert "mimic joint 'finger_r_joint'" in why and "'finger_l_joint'" in why, why
    assert "planar joint 'base_planar'" in why, why
    # the summary says it once, and passes
    last = res.stdout.strip().splitlines()[-1]
    assert last.startswith("certificate: passed") and "urdfdom 6" in last, res.stdout
    assert last.count("believed") == 1
    # independently: pinocchio's frames and gravity torques, the mimic coupled as written
    cmp = compare_with_pinocchio(
        src, tmp_path / "out" / "robot.xml", {"finger_r_joint": ("finger_l_joint", 1.0, 0.0)}
    )
    assert cmp.max_frame_pos_err < 1e-9 and cmp.max_frame_rot_err < 1e-9, cmp


def test_references_that_agree_say_so(tmp_path):
    text = PLANAR_GRIPPER.replace("planar", "fixed").replace(
        '<axis xyz="0 0 1"/></joint>', "</joint>", 1
    )
    _, res, report = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    agreement = report["certificate"]["references"]["agreement"]
    assert agreement["compared"] and agreement["agree"], agreement
    assert "believed" not in res.stdout


def test_a_file_urdfdom_refuses_is_certified_by_yourdfpy_and_urdfdom_says_nothing(tmp_path):
    # an axis of 4 numbers in one joint's origin: urdfdom refuses "0 0 0 0" as rpy;
    # we and yourdfpy read the first three
    text = PLANAR_GRIPPER.replace(
        '<origin xyz="0.2 0 0.5"/>', '<origin xyz="0.2 0 0.5" rpy="0 0 0 0"/>'
    )
    with pytest.raises(ValueError):
        with urdfdom_quiet():
            pin.buildModelFromXML(text)
    _, res, report = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    cert = report["certificate"]
    assert cert["computed"] and cert["reference"]["implementation"] == "yourdfpy", cert
    why_not = cert["references"]["urdfdom_why_not"]
    assert why_not.startswith("urdfdom cannot read it: Parser found 4 elements"), why_not
    assert "at line" not in res.stderr and "urdf_parser" not in res.stderr, res.stderr
    assert "Error:" not in res.stderr, res.stderr


def test_a_1_1_capsule_file_is_certified_not_left_uncomputed(tmp_path):
    text = PLANAR_GRIPPER.replace("<robot ", '<robot version="1.1" ').replace(
        '<box size="0.05 0.05 0.05"/>', '<capsule radius="0.02" length="0.05"/>'
    )
    _, res, report = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    cert = report["certificate"]
    assert cert["computed"], cert.get("why")
    assert cert["reference"]["implementation"] == "urdfdom"
    assert "not computed" not in res.stdout + res.stderr


def test_a_file_no_reference_reads_says_so_once(tmp_path):
    # an axis of four numbers: we read the first three (with a warning); urdfdom refuses
    # the axis and yourdfpy keeps all four
    text = PLANAR_GRIPPER.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 1 0 0"/>')
    _, res, report = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    out = res.stdout + res.stderr
    assert out.count("not computed") == 1, out
    line = next(ln for ln in out.splitlines() if "not computed" in ln)
    assert line.startswith("certificate: not computed: no reference reads it (urdfdom: "), line
    assert "yourdfpy: joint 'finger_l_joint': an axis of 4 numbers" in line, line
    assert "nothing checked the model" in line
    assert "at line" not in res.stderr and "urdf_parser" not in res.stderr
    assert report["certificate"]["computed"] is False
    # --verify refuses it
    (tmp_path / "v").mkdir()
    src = tmp_path / "v" / "robot.urdf"
    src.write_text(text)
    res = run("urdf2mjcf", str(src), "-o", "out/robot.xml", "--verify", cwd=tmp_path / "v")
    assert res.returncode == 1 and "no reference reads it" in res.stderr, res.stderr


def test_verify_of_a_description_no_reference_reads_is_one_error(tmp_path):
    _, res, _ = _convert(tmp_path, PLANAR_GRIPPER)
    assert res.returncode == 0, res.stderr
    bad = tmp_path / "bad.urdf"
    bad.write_text(
        PLANAR_GRIPPER.replace("<robot ", '<robot version="1.1" ').replace(
            '<origin xyz="0.2 0 0.5"/>', '<origin xyz="0.2 0 0.5" rpy="0 0 0" quat_xyzw="0 0 0 1"/>'
        )
    )
    res = run("urdf2mjcf", "verify", str(bad), "out/robot.xml", cwd=tmp_path)
    line = assert_one_error(res, "bad.urdf", "no reference reads it", "Both rpy and quat_xyzw")
    assert "at line" not in res.stderr and "urdf_parser" not in res.stderr, line


def test_urdfdom_is_held_back_but_another_threads_stderr_is_not(capfd):
    started, release = threading.Event(), threading.Event()

    def other() -> None:
        started.wait()
        os.write(2, b"another thread's line\n")
        release.set()

    t = threading.Thread(target=other)
    t.start()
    with urdfdom_quiet() as lines:
        started.set()
        release.wait(10)
        with pytest.raises(ValueError):
            pin.buildModelFromXML('<robot name="r"></robot>')
    t.join()
    err = capfd.readouterr().err
    assert "another thread's line" in err
    assert "No link elements" not in err and "at line" not in err
    assert any("No link elements found" in ln for ln in lines), lines
