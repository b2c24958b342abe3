"""URDF 1.0, 1.1 and 1.2 as urdfdom 6 reads them, checked against urdfdom itself
(pinocchio 4 reads URDF through urdfdom 6): what it refuses is one error line, what
it reads converts, and the frames, inertials and collision shapes of 1.1 files
(``quat_xyzw`` in every kind of origin, capsules) agree with pinocchio's to 1e-9."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from tests.corpus import _stderr_lines, compare_with_pinocchio
from tests.security.attack import assert_one_error, run

INERTIA = '<inertia ixx="0.02" iyy="0.03" izz="0.04" ixy="0.001" ixz="0" iyz="0.002"/>'


def _urdf(version: str | None, body: str) -> str:
    v = f' version="{version}"' if version is not None else ""
    return f'<?xml version="1.0"?>\n<robot name="v"{v}>\n{body}\n</robot>\n'


def _arm(origin: str, version: str | None = "1.1", limit_extra: str = "") -> str:
    """Two moving links, ``origin`` (attributes of every <origin>) on each joint,
    inertial, visual and collision."""
    link = (
        '<link name="{n}"><inertial><origin xyz="0.01 0.02 0.03" {o}/><mass value="1.5"/>'
        + INERTIA
        + '</inertial><visual><origin xyz="0 0 0.1" {o}/><geometry><box size="0.1 0.2 0.3"/>'
        '</geometry></visual><collision><origin xyz="0.05 0 0.1" {o}/><geometry>'
        '<capsule radius="0.04" length="0.2"/></geometry></collision></link>'
    )
    joint = (
        '<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
        '<origin xyz="0.1 0.2 0.3" {o}/><axis xyz="0 1 0"/>'
        '<limit lower="-1" upper="1" effort="10" velocity="2"{e}/></joint>'
    )
    body = (
        '<link name="base"><inertial><mass value="3"/>'
        + INERTIA
        + "</inertial></link>"
        + link.format(n="upper", o=origin)
        + link.format(n="lower", o=origin)
        + joint.format(n="j1", p="base", c="upper", o=origin, e=limit_extra)
        + joint.format(n="j2", p="upper", c="lower", o=origin, e=limit_extra)
    )
    return _urdf(version, body)


def _urdfdom_refuses(text: str) -> str | None:
    """urdfdom's first error for ``text``, None when it reads it."""
    with _stderr_lines() as lines:
        try:
            pin.buildModelFromXML(text)
            return None
        except Exception as exc:  # noqa: BLE001 - pinocchio raises ValueError
            first = str(exc)
    errors = [ln.split("Error:", 1)[1].strip() for ln in lines if "Error:" in ln]
    return errors[0] if errors else first


def _convert(tmp_path: Path, text: str, *args: str):
    src = tmp_path / "robot.urdf"
    src.write_text(text)
    res = run(
        "urdf2mjcf", str(src), "-o", "out/robot.xml", "--report", "r.json", *args, cwd=tmp_path
    )
    return src, res


REFUSED = {
    "both-rpy-and-quat": (
        _urdf(
            "1.1",
            '<link name="a"/><link name="b"/><joint name="j" type="fixed">'
            '<parent link="a"/><child link="b"/><origin rpy="0 0 1" quat_xyzw="0 0 0 1"/>'
            "</joint>",
        ),
        ("joint 'j'", "both rpy and quat_xyzw"),
    ),
    "version-1.3": (_urdf("1.3", '<link name="a"/>'), ("robot", "version '1.3'", "1.0, 1.1, 1.2")),
    "version-2.0": (_urdf("2.0", '<link name="a"/>'), ("robot", "version '2.0'")),
    "version-0.9": (_urdf("0.9", '<link name="a"/>'), ("robot", "version '0.9'")),
    "version-1": (_urdf("1", '<link name="a"/>'), ("robot", "MAJOR.MINOR")),
    "version-1.1.1": (_urdf("1.1.1", '<link name="a"/>'), ("robot", "MAJOR.MINOR")),
    "version-1.a": (_urdf("1.a", '<link name="a"/>'), ("robot", "version '1.a'")),
    "version-trailing-space": (_urdf("1.1 ", '<link name="a"/>'), ("robot", "version")),
    "version-negative": (_urdf("-1.1", '<link name="a"/>'), ("robot", "negative")),
    "version-empty-field": (_urdf(".1", '<link name="a"/>'), ("robot", "empty field")),
    "no-links": (_urdf(None, ""), ("robot", "has no <link>")),
    "no-links-only-a-joint": (
        _urdf(None, '<joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint>'),
        ("robot", "has no <link>"),
    ),
    "comma-in-rpy": (
        _urdf(
            None,
            '<link name="a"/><link name="b"/><joint name="j" type="fixed">'
            '<parent link="a"/><child link="b"/><origin rpy="0,0,1"/></joint>',
        ),
        ("joint 'j'", "rpy='0,0,1'"),
    ),
    "negative-acceleration": (
        _arm('rpy="0 0 0"', "1.2", ' acceleration="-2"'),
        ("joint 'j1'", "acceleration='-2'", "negative"),
    ),
    "quat-of-3-numbers": (
        _urdf(
            "1.1",
            '<link name="a"/><link name="b"/><joint name="j" type="fixed">'
            '<parent link="a"/><child link="b"/><origin quat_xyzw="0 0 1"/></joint>',
        ),
        ("joint 'j'", "quat_xyzw", "needs 4 numbers"),
    ),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_what_urdfdom_refuses_is_one_error_line(case, tmp_path):
    text, needles = REFUSED[case]
    assert _urdfdom_refuses(text) is not None  # the spec's reference refuses it too
    src, res = _convert(tmp_path, text)
    assert_one_error(res, src.name, *needles)
    assert not (tmp_path / "out").exists()  # nothing written
    # nothing of urdfdom's own printing ("at line 243 in .../urdf_parser/src/model.cpp")
    assert "at line" not in res.stderr and "urdf_parser" not in res.stderr


@pytest.mark.parametrize("version", ["1.0", "1.1", "1.2", "+1.1", "01.02", " 1.1", "1.-0"])
def test_every_version_urdfdom_reads_converts(version, tmp_path):
    text = _urdf(
        version, '<link name="a"><inertial><mass value="1"/>' + INERTIA + "</inertial></link>"
    )
    assert _urdfdom_refuses(text) is None
    _, res = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr


def _world_frames(pm, q):
    pd = pm.createData()
    pin.framesForwardKinematics(pm, pd, q)
    return pd


QUATS = {
    "general": "0.1 -0.3 0.5 0.8",  # not unit: urdfdom normalises it
    "pitch-90-exactly": "0 0.7071067811865476 0 0.7071067811865476",
    "pitch-near-90": "0.0000001 0.70710678 0 0.70710678",  # within 1e-7 of gimbal lock
    "half-turn-about-x": "1 0 0 0",
    "negative-w": "0.2 0.3 -0.1 -0.9",
}


@pytest.mark.parametrize("name", sorted(QUATS))
def test_quat_xyzw_in_every_origin_agrees_with_urdfdom(name, tmp_path):
    text = _arm(f'quat_xyzw="{QUATS[name]}"')
    assert _urdfdom_refuses(text) is None
    src, res = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    assert "warning" not in res.stderr, res.stderr
    out = tmp_path / "out" / "robot.xml"
    # frames and gravity torques (the inertial's position) at random configurations
    cmp = compare_with_pinocchio(src, out, {})
    assert cmp.max_frame_pos_err < 1e-9 and cmp.max_frame_rot_err < 1e-9, cmp
    assert cmp.max_gravity_rel_err < 1e-9, cmp
    # the inertials' rotation: each body's inertia tensor in its link frame
    pm = pin.buildModelFromXML(text)
    m = mujoco.MjModel.from_xml_path(str(out))
    for j in range(1, pm.njoints):
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, _child(text, pm.names[j]))
        ours, theirs = _body_inertia(m, body), pm.inertias[j].inertia
        assert np.abs(ours - theirs).max() < 1e-12, (name, pm.names[j])
    # collision capsules: placed where urdfdom places them (pinocchio's geometry model)
    _same_collision_capsules(pm, text, m)
    # the certificate is urdfdom's, passed, and yourdfpy (completed with URDF 1.1) agrees
    cert = json.loads((tmp_path / "r.json").read_text())["certificate"]
    assert cert["computed"] and cert["reference"]["implementation"] == "urdfdom", cert.get("why")
    assert cert["references"]["agreement"]["agree"], cert["references"]
    own = [
        f for f in cert["failures"] if f.split(".")[0] in ("frames", "joints", "mass", "dynamics")
    ]
    assert not own, own


def _child(text: str, joint: str) -> str:
    from lxml import etree

    root = etree.fromstring(text.encode())
    return root.find(f"joint[@name='{joint}']").find("child").get("link")


def _body_inertia(m, body: int) -> np.ndarray:
    """The body's inertia tensor about its centre of mass, in the body's frame."""
    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, m.body_iquat[body])
    r3 = r.reshape(3, 3)
    return r3 @ np.diag(m.body_inertia[body]) @ r3.T


def _same_collision_capsules(pm, text: str, m) -> None:
    gm = pin.buildGeomFromUrdfString(pm, text, pin.GeometryType.COLLISION)
    pd = _world_frames(pm, pin.neutral(pm))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    capsules = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE]
    assert len(capsules) == len(gm.geometryObjects) == 2
    for obj in gm.geometryObjects:
        world = pd.oMi[obj.parentJoint] * obj.placement
        best = min(
            capsules,
            key=lambda g: float(np.linalg.norm(d.geom_xpos[g] - world.translation)),
        )
        assert np.linalg.norm(d.geom_xpos[best] - world.translation) < 1e-9
        # a capsule's axis (z) is the one direction that matters
        axis = d.geom_xmat[best].reshape(3, 3)[:, 2]
        assert abs(abs(float(axis @ world.rotation[:, 2])) - 1) < 1e-12
        assert m.geom_size[best][0] == pytest.approx(obj.geometry.radius, abs=1e-15)
        assert m.geom_size[best][1] == pytest.approx(obj.geometry.halfLength, abs=1e-15)


def test_quat_xyzw_in_a_1_0_file_is_ignored_with_a_warning_as_urdfdom_ignores_it(tmp_path):
    text = _arm('quat_xyzw="0 0 0.7071067811865476 0.7071067811865476"', version=None)
    assert _urdfdom_refuses(text) is None
    src, res = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    warned = [
        ln
        for ln in res.stderr.splitlines()
        if ln.startswith("warning:") and "quat_xyzw is URDF 1.1" in ln
    ]
    assert len(warned) == 8, res.stderr  # 2 joints, 2 x (inertial, visual, collision)
    assert all("URDF 1.1" in w and "version 1.0" in w and "ignored" in w for w in warned)
    assert any("joint 'j1' <origin>" in w for w in warned)
    cmp = compare_with_pinocchio(src, tmp_path / "out" / "robot.xml", {})
    assert cmp.max_frame_pos_err < 1e-9 and cmp.max_frame_rot_err < 1e-9, cmp


def test_1_2_motion_limits_are_kept_for_the_report_and_said_not_enforced(tmp_path):
    text = _arm('rpy="0.1 0.2 0.3"', "1.2", ' acceleration="2.5" jerk="40"')
    assert _urdfdom_refuses(text) is None
    src, res = _convert(tmp_path, text, "-v")
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    # urdfdom's default deceleration is the acceleration
    want = {"acceleration": 2.5, "deceleration": 2.5, "jerk": 40.0}
    assert report["motion_limits"] == {"j1": want, "j2": want}
    notes = [
        n for n in report["notes"] if n["element"] == "joint 'j1'" and "URDF 1.2" in n["message"]
    ]
    assert len(notes) == 1 and "MuJoCo does not enforce them" in notes[0]["message"]
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "robot.xml"))
    assert m.jnt_range[m.joint("j1").id].tolist() == [-1.0, 1.0]  # the position limits


def test_1_2_limits_in_an_older_file_are_ignored_with_a_warning(tmp_path):
    text = _arm('rpy="0 0 0"', "1.1", ' acceleration="2" deceleration="3" jerk="5"')
    assert _urdfdom_refuses(text) is None
    _, res = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["motion_limits"] == {}
    warned = [
        ln for ln in res.stderr.splitlines() if ln.startswith("warning:") and "URDF 1.2" in ln
    ]
    assert len(warned) == 2 and "acceleration, deceleration, jerk are URDF 1.2" in warned[0], warned


def test_1_2_revolute_without_both_position_limits_converts_with_a_warning(tmp_path):
    text = _urdf(
        "1.2",
        '<link name="a"/><link name="b"><inertial><mass value="1"/>'
        + INERTIA
        + '</inertial></link><joint name="j" type="revolute"><parent link="a"/>'
        '<child link="b"/><limit upper="1" effort="1" velocity="1"/></joint>',
    )
    assert "lower and upper" in _urdfdom_refuses(text)
    _, res = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    assert "URDF 1.2 needs both lower and upper" in res.stderr
    (tmp_path / "strict").mkdir()
    _, res = _convert(tmp_path / "strict", text, "--strict")
    assert_one_error(res, "joint 'j'", "lower and upper")


def test_a_capsule_in_a_1_0_file_is_kept_with_a_warning(tmp_path):
    text = _arm('rpy="0 0 0"', version=None)
    # urdfdom drops a 1.0 file's capsule (the collision element)
    pm = pin.buildModelFromXML(text)
    with _stderr_lines():
        gm = pin.buildGeomFromUrdfString(pm, text, pin.GeometryType.COLLISION)
    assert gm.ngeoms == 0
    _, res = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    warned = [ln for ln in res.stderr.splitlines() if "<capsule> is URDF 1.1" in ln]
    assert len(warned) == 2, res.stderr
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "robot.xml"))
    assert sum(m.geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE) == 2


def test_a_zero_quaternion_is_no_rotation_as_urdfdom_reads_it(tmp_path):
    text = _arm('quat_xyzw="0 0 0 0"')
    assert _urdfdom_refuses(text) is None
    src, res = _convert(tmp_path, text)
    assert res.returncode == 0, res.stderr
    assert "is zero; read as no rotation" in res.stderr
    cmp = compare_with_pinocchio(src, tmp_path / "out" / "robot.xml", {})
    assert cmp.max_frame_pos_err < 1e-12 and cmp.max_frame_rot_err < 1e-12, cmp
    assert math.isfinite(cmp.max_gravity_rel_err)
