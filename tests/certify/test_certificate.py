"""The certificate's figures against figures this test computes itself with pinocchio
(urdfdom's reading of the description) and MuJoCo, on robots from several collections,
and on models altered by hand, where the figures are far from zero."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from lxml import etree

import urdf2mjcf
from tests.corpus import (
    example_robot_data_share,
    example_robot_data_urdfs,
    patched_urdf,
    wild_collections,
)
from urdf2mjcf import api
from urdf2mjcf.certify import SAMPLES, CertificateFailed, certify
from urdf2mjcf.certify.reference import load
from urdf2mjcf.certify.tolerances import Tolerances, markdown_table
from urdf2mjcf.passes import xacro

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo_arm.urdf.xacro"
GOLDEN = ROOT / "tests" / "data" / "golden"
OURS = ("frames", "joints", "mass", "dynamics")
"""The certificate's own sections (collision and lint figures are tested beside)."""


def _erd(name: str) -> Path:
    return next(p for p in example_robot_data_urdfs() if p.name == name)


ROBOTIQ = "grippers/robotiq_2f_85/urdf/robotiq_2f_85.urdf"  # airo-models: mimic joints


def _wild(name: str) -> tuple[Path, dict, list[Path]]:
    for c in wild_collections():
        for u in c.urdfs:
            if c.name(u) == name:
                return u, {}, list(c.package_paths)
    raise LookupError(name)


def _robots() -> list:
    erd = [example_robot_data_share()]
    return [
        pytest.param(DEMO, {"args": {"use_gripper": "true"}}, [], id="demo_arm-gripper-mimic"),
        pytest.param(
            DEMO, {"args": {"use_gripper": "true"}, "fuse_fixed": True}, [], id="demo_arm-fused"
        ),
        pytest.param(GOLDEN / "joints.urdf", {}, [], id="floating-planar-continuous"),
        pytest.param(GOLDEN / "estimated.urdf", {}, [], id="estimated"),
        pytest.param(
            _erd("double_pendulum_continuous.urdf"),
            {"floating_base": True},
            erd,
            id="erd-double_pendulum_continuous-free",
        ),
        pytest.param(_erd("ur5_robot.urdf"), {}, erd, id="erd-ur5", marks=pytest.mark.slow),
        pytest.param(*_wild(ROBOTIQ), id="wild-robotiq_2f_85-mimic"),
    ]


def _convert(source: Path, out: Path, options: dict, package_paths: list[Path]):
    return urdf2mjcf.convert(
        source, out, package_paths=package_paths, use_environment=False, **options
    )


def _pinocchio(urdf: Path, free_root: bool):
    """pinocchio's model of ``urdf`` (xacro expanded by our pass: the same text
    yourdfpy reads; urdfdom parses it)."""
    if free_root:
        return pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    return pin.buildModelFromUrdf(str(urdf))


def _expanded(source: Path, out_dir: Path, options: dict, package_paths: list[Path]) -> Path:
    opts = api.make_options(
        args=options.get("args"), package_paths=package_paths, use_environment=False
    )
    doc = xacro.run(source, opts.xacro)
    path = out_dir / "expanded.urdf"
    path.write_bytes(doc.xml)
    return path


def _body_frames_error(pm, m) -> tuple[float, float]:
    """Worst (position, rotation) error of every pinocchio link frame against the MuJoCo
    body or site of its name, at pinocchio's neutral and MuJoCo's qpos0, in the root
    link's frame."""
    pd = pm.createData()
    q = pin.neutral(pm)
    pin.framesForwardKinematics(pm, pd, q)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    bodies = [pm.frames[f] for f in range(pm.nframes) if pm.frames[f].type == pin.FrameType.BODY]
    root = bodies[0].name
    r_id = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, root)
    r0, p0 = d.xmat[r_id].reshape(3, 3), d.xpos[r_id]
    root_pin = pd.oMf[pm.getFrameId(root, pin.FrameType.BODY)]
    worst = [0.0, 0.0]
    for frame in bodies:
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, frame.name)
        if b >= 0:
            x, r = d.xpos[b], d.xmat[b].reshape(3, 3)
        else:
            s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, frame.name)
            x, r = d.site_xpos[s], d.site_xmat[s].reshape(3, 3)
        placement = root_pin.actInv(pd.oMf[pm.getFrameId(frame.name, pin.FrameType.BODY)])
        worst[0] = max(worst[0], float(np.linalg.norm(r0.T @ (x - p0) - placement.translation)))
        rel = (r0.T @ r).T @ placement.rotation
        worst[1] = max(worst[1], math.acos(max(-1.0, min(1.0, (np.trace(rel) - 1) / 2))))
    return worst[0], worst[1]


def _mass_matrix_error(pm, m) -> float:
    """max |M_mujoco - M_pinocchio| / max |M_pinocchio| over the one-dof joints at
    neutral, armature taken off MuJoCo's diagonal."""
    pd = pm.createData()
    q = pin.neutral(pm)
    mp = pin.crba(pm, pd, q)
    mp = np.triu(mp) + np.triu(mp, 1).T
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    full -= np.diag(m.dof_armature)
    pin_idx, mj_idx = [], []
    for j in range(1, pm.njoints):
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, pm.names[j])
        if pm.joints[j].nv == 1 and jid >= 0:
            pin_idx.append(pm.joints[j].idx_v)
            mj_idx.append(m.jnt_dofadr[jid])
    a = full[np.ix_(mj_idx, mj_idx)]
    b = mp[np.ix_(pin_idx, pin_idx)]
    return float(np.abs(a - b).max() / np.abs(b).max())


@pytest.mark.parametrize(("source", "options", "package_paths"), _robots())
def test_certificate_of_a_conversion_agrees_with_pinocchio(
    source, options, package_paths, tmp_path
):
    out = tmp_path / "robot.xml"
    report = _convert(source, out, options, package_paths)
    cert = report.certificate
    assert cert is not None and cert.computed, cert and cert.why_not
    ours = [f for f in cert.failures if f.split(".")[0].split(" ")[0] in OURS]
    assert not ours, ours
    data = report.to_dict()["certificate"]
    # pinocchio installed: urdfdom's frames are the reference, and yourdfpy agrees
    assert data["reference"]["implementation"] == "urdfdom"
    assert data["references"]["agreement"]["agree"], data["references"]
    assert data["frames"]["max_position_error_m"] < 1e-12
    assert data["frames"]["max_rotation_error_rad"] < 1e-12
    assert data["frames"]["configurations"] == 1 + SAMPLES

    # Independently: pinocchio reads the description (our repairs and estimates patched
    # in, as the certificate says it takes them) and MuJoCo the written files.
    expanded = _expanded(source, tmp_path, options, package_paths)
    reference = patched_urdf(expanded, report.model, tmp_path / "reference.urdf")
    free = bool(options.get("floating_base"))
    pm = _pinocchio(reference, free)
    m = mujoco.MjModel.from_xml_path(str(out))
    assert free == (mujoco.mjtJoint.mjJNT_FREE in m.jnt_type)  # a root named world: no free joint
    total = sum(pm.inertias[i].mass for i in range(pm.njoints))
    assert data["mass"]["urdf_kg"] + data["mass"]["added_kg"] == pytest.approx(total, rel=1e-12)
    assert data["mass"]["mjcf_kg"] == pytest.approx(float(m.body_mass.sum()), rel=1e-12)
    # links welded to the world: pinocchio's universe; MuJoCo's world body (no mass) when
    # --fuse-fixed merges them into it
    welded = data["mass"]["welded_kg"]
    in_world = pm.inertias[0] if options.get("fuse_fixed") else pin.Inertia.Zero()
    assert welded == pytest.approx(in_world.mass, rel=1e-12)
    if data["mass"]["added_kg"]:
        assert any(c["kind"] in ("estimated", "repaired") for c in data["changes"])
    pd = pm.createData()
    pin.forwardKinematics(pm, pd, pin.neutral(pm))
    # each joint's inertia at its placement (pin.centerOfMass disagrees with this sum on
    # pinocchio 4.1 where a world link roots the tree)
    moment = sum(
        pm.inertias[i].mass * pd.oMi[i].act(pm.inertias[i].lever) for i in range(pm.njoints)
    )
    com_pin = (moment - in_world.mass * in_world.lever) / (total - welded)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    first = next(f for f in pm.frames if f.type == pin.FrameType.BODY).name
    root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, first)
    com_mj = d.subtree_com[root] - d.xpos[root]
    assert np.linalg.norm(com_mj - com_pin) < 1e-9
    assert data["mass"]["com_error_m"] < 1e-9
    pos, rot = _body_frames_error(pm, m)
    assert pos < 1e-9 and rot < 1e-6  # acos: half the digits
    dyn = data["dynamics"]
    assert dyn["computed"], dyn
    assert dyn["mass_matrix_relative_error"] < 1e-9
    assert dyn["gravity_relative_error"] < 1e-9
    if not free and dyn["dofs"]:
        assert _mass_matrix_error(pm, m) < 1e-9


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """demo_arm with its gripper, converted; its expanded URDF; yourdfpy's reading."""
    folder = tmp_path_factory.mktemp("demo")
    out = folder / "robot.xml"
    report = _convert(DEMO, out, {"args": {"use_gripper": "true"}}, [])
    expanded = _expanded(DEMO, folder, {"args": {"use_gripper": "true"}}, [])
    opts = api.make_options(args={"use_gripper": "true"}, use_environment=False)
    return report, out, expanded, load(xacro.run(DEMO, opts.xacro))


def _altered(xml: Path, xpath: str, attr: str, change) -> mujoco.MjModel:
    tree = etree.parse(str(xml))
    (el,) = tree.xpath(xpath)
    el.set(attr, change(el.get(attr)))
    return mujoco.MjModel.from_xml_string(etree.tostring(tree, encoding="unicode"))


def test_a_shifted_body_is_measured_as_pinocchio_measures_it(demo):
    report, out, expanded, ref = demo
    m = _altered(out, "//body[@name='forearm']", "pos", lambda v: "0.001 0 0.35")
    cert = certify(ref, m, samples=0)  # home only: the configuration pinocchio uses here
    pos, _ = _body_frames_error(pin.buildModelFromUrdf(str(expanded)), m)
    assert pos == pytest.approx(1e-3, rel=1e-9)
    assert cert.sections["frames"]["max_position_error_m"] == pytest.approx(pos, rel=1e-9)
    assert any(
        "joint 'forearm_joint'" in f and f.startswith("joints.anchor") for f in cert.failures
    )
    assert not cert.passed


def test_a_doubled_mass_is_measured_as_pinocchio_measures_it(demo):
    report, out, expanded, ref = demo
    m = _altered(out, "//body[@name='forearm']/inertial", "mass", lambda v: repr(2 * float(v)))
    cert = certify(ref, m, samples=0)
    pm = pin.buildModelFromUrdf(str(expanded))
    total = sum(pm.inertias[i].mass for i in range(pm.njoints))
    mass = cert.sections["mass"]
    assert mass["urdf_kg"] == pytest.approx(total, rel=1e-12)
    assert mass["mjcf_kg"] == pytest.approx(total + 1.0, rel=1e-12)  # forearm: 1 kg
    assert mass["mismatches"][0]["body"] == "forearm"
    dyn = cert.sections["dynamics"]
    assert dyn["mass_matrix_relative_error"] == pytest.approx(_mass_matrix_error(pm, m), rel=1e-9)
    assert dyn["mass_matrix_relative_error"] > 0.01
    assert any(f.startswith("mass.body 'forearm'") for f in cert.failures)


def test_a_flipped_axis_and_a_changed_coupling_are_named(demo):
    report, out, expanded, ref = demo
    m = _altered(out, "//joint[@name='upper_arm_joint']", "axis", lambda v: "0 -1 0")
    cert = certify(ref, m, samples=2)
    axis = [x for x in cert.sections["joints"]["mismatches"] if x["figure"] == "axis"]
    assert [x["joint"] for x in axis] == ["upper_arm_joint"]
    assert axis[0]["value"] == pytest.approx(math.pi)
    assert cert.sections["frames"]["max_rotation_error_rad"] > 0.1
    m = _altered(out, "//equality/joint", "polycoef", lambda v: "0 -1 0 0 0")
    cert = certify(ref, m, samples=0)
    assert [f for f in cert.failures if f.startswith("joints.")] == [
        "joints.mimic: joint 'finger_right_joint': coupling -1 x + 0, description 1 x + 0 > 1e-09"
    ]


def test_verify_through_the_api_writes_nothing_when_the_certificate_fails(demo, tmp_path):
    report, *_ = demo
    rotation = report.certificate.sections["frames"]["max_rotation_error_rad"]
    assert rotation > 0  # rounding: a tolerance of 0 cannot be met
    out = tmp_path / "out" / "robot.xml"
    with pytest.raises(CertificateFailed) as caught:
        urdf2mjcf.convert(
            DEMO,
            out,
            args={"use_gripper": "true"},
            use_environment=False,
            verify=True,
            tolerances=Tolerances(frame_rotation_rad=0.0),
        )
    assert caught.value.certificate.failures[0].startswith("frames.max_rotation_error_rad")
    assert not (tmp_path / "out").exists()
    ok = urdf2mjcf.convert(DEMO, out, use_environment=False, verify=True)
    assert ok.certificate.passed and out.is_file()


def test_without_validation_there_is_no_certificate_unless_verify_asks(tmp_path):
    r = urdf2mjcf.convert(DEMO, tmp_path / "a" / "robot.xml", validate_model=False)
    assert r.certificate is None
    assert r.to_dict()["certificate"]["computed"] is False
    r = urdf2mjcf.convert(DEMO, tmp_path / "b" / "robot.xml", validate_model=False, verify=True)
    assert r.certificate.passed


def test_tolerances_are_checked_and_documented():
    with pytest.raises(ValueError):
        Tolerances(frame_position_m=-1.0)
    with pytest.raises(ValueError):
        Tolerances(com_m=float("nan"))
    assert Tolerances().with_values([("com_m", 0.5)]).com_m == 0.5
    doc = (ROOT / "docs" / "cli.md").read_text()
    assert markdown_table() in doc, "docs/cli.md: paste tolerances.markdown_table()"
    from urdf2mjcf.certify import DYNAMICS_SAMPLES

    flat = " ".join(doc.split())
    assert f"at {SAMPLES} random configurations (`--samples`)" in flat
    assert f"at home and {DYNAMICS_SAMPLES} random configurations" in flat
