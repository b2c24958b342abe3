"""Converted models behave as the description says, checked in simulation
and against analytic formulas."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

import urdf2mjcf
from urdf2mjcf.transforms import quat_to_matrix, rpy_to_matrix

GOLDEN_INPUTS = Path(__file__).parent / "data" / "golden"


def _convert(name: str, out_dir: Path, **kw) -> tuple[Path, urdf2mjcf.Report]:
    out = out_dir / f"{name}.xml"
    report = urdf2mjcf.convert(GOLDEN_INPUTS / f"{name}.urdf", out, use_environment=False, **kw)
    return out, report


def _world_inertia(m: mujoco.MjModel, body: int) -> np.ndarray:
    r = quat_to_matrix(tuple(m.body_iquat[body]))
    return r @ np.diag(m.body_inertia[body]) @ r.T


def test_mimic_follower_tracks_leader_with_multiplier_and_offset(tmp_path):
    out, _ = _convert("mimic", tmp_path)
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    leader, follower = m.joint("leader"), m.joint("follower")
    assert d.qpos[follower.qposadr[0]] == pytest.approx(0.1), "home keyframe satisfies the mimic"
    worst = 0.0
    for i in range(int(3.0 / m.opt.timestep)):
        t = i * m.opt.timestep
        d.qfrc_applied[leader.dofadr[0]] = 0.02 * math.sin(2 * math.pi * 0.5 * t)
        mujoco.mj_step(m, d)
        ql, qf = d.qpos[leader.qposadr[0]], d.qpos[follower.qposadr[0]]
        if t > 0.2:
            worst = max(worst, abs(qf - (-2.0 * ql + 0.1)))
    assert abs(d.qpos[leader.qposadr[0]]) > 0.05, "the leader really moved"
    assert worst < 5e-3


def test_bodies_estimated_from_density_have_analytic_mass_and_inertia(tmp_path):
    out, report = _convert("estimated", tmp_path)
    assert {n.element for n in report.estimated} == {
        "link 'box_link'",
        "link 'cylinder_link'",
        "link 'sphere_link'",
    }
    m = mujoco.MjModel.from_xml_path(str(out))
    rho = 1000.0

    # Box 0.2 x 0.1 x 0.4 at (0.1, 0, 0), yawed 0.5 rad.
    a, b, c = 0.2, 0.1, 0.4
    mass = rho * a * b * c
    body = m.body("box_link").id
    assert m.body_mass[body] == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(m.body_ipos[body], [0.1, 0, 0], atol=1e-12)
    r = rpy_to_matrix((0, 0, 0.5))
    local = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * mass / 12
    np.testing.assert_allclose(_world_inertia(m, body), r @ local @ r.T, rtol=1e-9, atol=1e-12)

    # Cylinder r=0.05, h=0.3 at (0, 0, -0.15), rolled 0.2 rad.
    rad, h = 0.05, 0.3
    mass = rho * math.pi * rad * rad * h
    body = m.body("cylinder_link").id
    assert m.body_mass[body] == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(m.body_ipos[body], [0, 0, -0.15], atol=1e-12)
    r = rpy_to_matrix((0.2, 0, 0))
    ixx = mass * (3 * rad * rad + h * h) / 12
    local = np.diag([ixx, ixx, mass * rad * rad / 2])
    np.testing.assert_allclose(_world_inertia(m, body), r @ local @ r.T, rtol=1e-9, atol=1e-12)

    # Sphere r=0.07 from the visual (no collision element).
    rad = 0.07
    mass = rho * 4 / 3 * math.pi * rad**3
    body = m.body("sphere_link").id
    assert m.body_mass[body] == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(m.body_inertia[body], [0.4 * mass * rad * rad] * 3, rtol=1e-9)


def test_density_option_scales_estimated_mass(tmp_path):
    out, _ = _convert("estimated", tmp_path, density=500.0, link_density={"sphere_link": 2000.0})
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.body_mass[m.body("box_link").id] == pytest.approx(500 * 0.2 * 0.1 * 0.4)
    assert m.body_mass[m.body("sphere_link").id] == pytest.approx(2000 * 4 / 3 * math.pi * 0.07**3)


@pytest.mark.parametrize("case", ["joints", "dae_material", "nonconvex"])
def test_converting_twice_gives_byte_identical_output(case, tmp_path):
    _, r1 = _convert(case, tmp_path / "a")
    _, r2 = _convert(case, tmp_path / "b")
    files1 = {
        p.relative_to(tmp_path / "a"): p.read_bytes()
        for p in (tmp_path / "a").rglob("*")
        if p.is_file()
    }
    files2 = {
        p.relative_to(tmp_path / "b"): p.read_bytes()
        for p in (tmp_path / "b").rglob("*")
        if p.is_file()
    }
    assert files1 == files2


def test_second_conversion_does_no_decomposition_work(tmp_path):
    cache = tmp_path / "cache"
    _, first = _convert("nonconvex", tmp_path / "a", cache_dir=cache)
    assert first.decomposed, "the U bracket is decomposed the first time"
    _, second = _convert("nonconvex", tmp_path / "b", cache_dir=cache)
    assert not second.decomposed
    assert len(second.cached) == len(first.decomposed)


def test_nonconvex_mesh_becomes_several_convex_collision_geoms(tmp_path):
    out, _ = _convert("nonconvex", tmp_path)
    m = mujoco.MjModel.from_xml_path(str(out))
    bracket = m.body("bracket").id
    collision = [g for g in range(m.ngeom) if m.geom_bodyid[g] == bracket and m.geom_group[g] == 3]
    assert len(collision) >= 2
    paddle = [
        g
        for g in range(m.ngeom)
        if m.geom_bodyid[g] == m.body("paddle").id and m.geom_group[g] == 3
    ]
    assert len(paddle) == 1, "a box mesh is near-convex: one hull"


def test_every_joint_type_maps_to_mujoco_joints(tmp_path):
    out, _ = _convert("joints", tmp_path)
    m = mujoco.MjModel.from_xml_path(str(out))
    jt = mujoco.mjtJoint
    assert m.jnt_type[m.joint("hinge").id] == jt.mjJNT_HINGE and m.jnt_limited[m.joint("hinge").id]
    np.testing.assert_allclose(m.jnt_range[m.joint("hinge").id], [-1.5, 1.5])
    assert m.dof_damping[m.joint("hinge").dofadr[0]] == 0.7
    assert m.dof_frictionloss[m.joint("hinge").dofadr[0]] == 0.2
    np.testing.assert_allclose(m.jnt_actfrcrange[m.joint("hinge").id], [-30, 30])
    assert (
        m.jnt_type[m.joint("spin").id] == jt.mjJNT_HINGE and not m.jnt_limited[m.joint("spin").id]
    )
    assert m.jnt_type[m.joint("slider").id] == jt.mjJNT_SLIDE
    assert [m.jnt_type[m.joint(f"float_{s}").id] for s in "xyz"] == [jt.mjJNT_SLIDE] * 3
    assert m.jnt_type[m.joint("float_rot").id] == jt.mjJNT_BALL
    assert [m.jnt_type[m.joint(f"table_{s}").id] for s in ("x", "y", "rot")] == [
        jt.mjJNT_SLIDE,
        jt.mjJNT_SLIDE,
        jt.mjJNT_HINGE,
    ]
    assert m.body("tool").id > 0, "fixed links are kept as bodies"
    assert m.nkey == 1 and m.key(0).name == "home"


def test_fuse_fixed_merges_fixed_links_and_leaves_a_site(tmp_path):
    out, _ = _convert("joints", tmp_path, fuse_fixed=True)
    m = mujoco.MjModel.from_xml_path(str(out))
    with pytest.raises(KeyError):
        m.body("tool")
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    site = m.site("tool").id
    out2, _ = _convert("joints", tmp_path / "unfused")
    m2 = mujoco.MjModel.from_xml_path(str(out2))
    d2 = mujoco.MjData(m2)
    mujoco.mj_kinematics(m2, d2)
    np.testing.assert_allclose(d.site_xpos[site], d2.xpos[m2.body("tool").id], atol=1e-12)
    np.testing.assert_allclose(d.site_xmat[site], d2.xmat[m2.body("tool").id], atol=1e-12)


def test_floating_base_option_adds_a_free_joint(tmp_path):
    out, _ = _convert("joints", tmp_path, floating_base=True)
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE and m.jnt_bodyid[0] == m.body("base").id


def test_output_folder_is_relocatable(tmp_path):
    out, report = _convert("dae_material", tmp_path / "a")
    moved = tmp_path / "moved"
    (tmp_path / "a").rename(moved)
    m = mujoco.MjModel.from_xml_path(str(moved / "scene.xml"))
    assert m.nmesh >= 1 and m.ngeom >= 2
    assert all(str(p).startswith(str(tmp_path / "a")) for p in report.files)


def test_dae_material_becomes_a_mujoco_material(tmp_path):
    out, _ = _convert("dae_material", tmp_path)
    m = mujoco.MjModel.from_xml_path(str(out))
    base = m.body("base").id
    visual = [g for g in range(m.ngeom) if m.geom_bodyid[g] == base and m.geom_group[g] == 2]
    mesh_geoms = [g for g in visual if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
    assert len(mesh_geoms) >= 1
    colours = {
        tuple(np.round(m.mat_rgba[m.geom_matid[g]], 3)) for g in mesh_geoms if m.geom_matid[g] >= 0
    }
    assert colours, "mesh parts carry their Collada materials"
    assert all(c[:3] != (0.5, 0.5, 0.5) for c in colours)
    sphere = [g for g in visual if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE][0]
    np.testing.assert_allclose(m.mat_rgba[m.geom_matid[sphere]], [0.1, 0.8, 0.2, 1], rtol=1e-6)


def test_height_field_from_the_mujoco_extension_loads_through_scene_include(tmp_path):
    from PIL import Image

    Image.fromarray(np.arange(64, dtype=np.uint8).reshape(8, 8) * 4).save(tmp_path / "terrain.png")
    src = tmp_path / "ground.urdf"
    src.write_text(
        """<robot name="ground">
  <link name="world"/>
  <mujoco>
    <asset><hfield name="terrain" file="terrain.png" size="2 2 0.3 0.1"/></asset>
    <worldbody><geom name="terrain" type="hfield" hfield="terrain"/></worldbody>
  </mujoco>
</robot>"""
    )
    out = tmp_path / "out" / "ground.xml"
    urdf2mjcf.convert(src, out, use_environment=False)
    m = mujoco.MjModel.from_xml_path(str(out.parent / "scene.xml"))
    assert m.nhfield == 1 and m.hfield_nrow[0] == 8
