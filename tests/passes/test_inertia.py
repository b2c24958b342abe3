"""Inertia pass: analytic oracles for estimates, MuJoCo 4.0 as the oracle for validity."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from scipy.integrate import quad
from scipy.spatial.transform import Rotation

from urdf2mjcf.assets import mesh_asset
from urdf2mjcf.errors import InertiaError
from urdf2mjcf.fmt import fmt_vec
from urdf2mjcf.ir import (
    BodyInertial,
    Box,
    Geom,
    Inertial,
    Joint,
    Link,
    LoadedMesh,
    MeshData,
    MeshRef,
    Model,
    Pose,
    Robot,
    Sphere,
    Visual,
)
from urdf2mjcf.passes.inertia import InertiaConfig, run

SOURCE = Path("/robots/test.urdf")


def robot(*links: Link, joints: tuple[Joint, ...] = ()) -> Robot:
    return Robot(name="r", source=SOURCE, links=links, joints=joints)


def convert(rob: Robot, cfg: InertiaConfig | None = None, **model_fields) -> Model:
    return run(Model(robot=rob, **model_fields), cfg or InertiaConfig())


def single(link: Link, cfg: InertiaConfig | None = None, **model_fields) -> Model:
    return convert(robot(link), cfg, **model_fields)


def full_matrix(fi) -> np.ndarray:
    ixx, iyy, izz, ixy, ixz, iyz = fi
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def collision(name: str, *geoms: Geom) -> dict:
    return {"collision_geoms": {name: geoms}}


def geom(gtype: str, size, pos=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0), mesh=None) -> Geom:
    return Geom("collision", gtype, pos, quat, tuple(size), mesh=mesh)


def urdf_inertial(mass, inertia, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> Inertial:
    return Inertial(Pose(xyz, rpy), mass, inertia)


def notes_of(model: Model, kind: str) -> list[str]:
    return [n.message for n in model.notes if n.kind == kind]


# --- MJCF as the emitter writes it (fullinertia, no mass from geoms) --------------------------


def mjcf(rob: Robot, inertials) -> str:
    def body(name: str, joint: Joint | None) -> str:
        attrs = f'name="{name}"'
        inner = ""
        if joint is not None:
            q = Rotation.from_euler("xyz", joint.origin.rpy).as_quat(scalar_first=True)
            attrs += f' pos="{fmt_vec(joint.origin.xyz)}" quat="{fmt_vec(q)}"'
            kind = {"revolute": "hinge", "continuous": "hinge", "prismatic": "slide"}.get(
                joint.type
            )
            if kind:
                inner += f'<joint type="{kind}" axis="{fmt_vec(joint.axis)}"/>'
            elif joint.type == "floating":
                inner += "<freejoint/>"
        b = inertials[name]
        if b is not None:  # as emit writes it: diaginertia when the tensor is diagonal
            tensor = (
                f'diaginertia="{fmt_vec(b.fullinertia[:3])}"'
                if tuple(b.fullinertia[3:]) == (0, 0, 0)
                else f'fullinertia="{fmt_vec(b.fullinertia)}"'
            )
            inner += f'<inertial pos="{fmt_vec(b.pos)}" mass="{fmt_vec([b.mass])}" {tensor}/>'

        inner += "".join(body(j.child, j) for j in rob.child_joints.get(name, ()))
        return f"<body {attrs}>{inner}</body>"

    return (
        '<mujoco><compiler angle="radian" inertiafromgeom="false"/>'
        f"<worldbody>{body(rob.root, None)}</worldbody></mujoco>"
    )


def mujoco_error(rob: Robot, inertials) -> str | None:
    try:
        mujoco.MjModel.from_xml_string(mjcf(rob, inertials))
    except ValueError as exc:
        return str(exc)
    return None


# --- estimates from primitives ------------------------------------------------------------------


def test_box_estimate_has_analytic_mass_and_inertia():
    m = single(
        Link("b"), InertiaConfig(density=500.0), **collision("b", geom("box", (0.1, 0.2, 0.3)))
    )
    b = m.inertials["b"]
    w, d, h = 0.2, 0.4, 0.6
    mass = 500.0 * w * d * h
    assert b.mass == pytest.approx(mass, rel=1e-12)
    expected = (
        mass / 12 * (d * d + h * h),
        mass / 12 * (w * w + h * h),
        mass / 12 * (w * w + d * d),
        0,
        0,
        0,
    )
    assert b.fullinertia == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert b.pos == (0.0, 0.0, 0.0) and b.source == "estimated"
    assert notes_of(m, "estimated") == [
        f"mass {mass:.6g} kg from collision geometry (box) at density 500 kg/m^3"
    ]


def test_cylinder_estimate_has_analytic_mass_and_inertia():
    r, length = 0.05, 0.3
    b = single(Link("c"), **collision("c", geom("cylinder", (r, length / 2)))).inertials["c"]
    mass = 1000.0 * math.pi * r * r * length
    assert b.mass == pytest.approx(mass, rel=1e-12)
    side = mass * (3 * r * r + length * length) / 12
    assert b.fullinertia == pytest.approx(
        (side, side, mass * r * r / 2, 0, 0, 0), rel=1e-12, abs=1e-15
    )


def test_sphere_estimate_has_analytic_mass_and_inertia():
    r = 0.07
    b = single(Link("s"), **collision("s", geom("sphere", (r,)))).inertials["s"]
    mass = 1000.0 * 4 / 3 * math.pi * r**3
    assert b.mass == pytest.approx(mass, rel=1e-12)
    assert b.fullinertia == pytest.approx(
        (0.4 * mass * r * r,) * 3 + (0, 0, 0), rel=1e-12, abs=1e-15
    )


def test_capsule_estimate_matches_integrating_discs_along_its_axis():
    r, h = 0.04, 0.1  # radius, half length of the cylinder part
    b = single(Link("c"), **collision("c", geom("capsule", (r, h)))).inertials["c"]

    def disc_radius2(z):  # squared radius of the cross-section at height z
        return r * r if abs(z) <= h else max(r * r - (abs(z) - h) ** 2, 0.0)

    def integral(f):
        return 2 * quad(f, 0, h + r, points=[h], epsabs=0, epsrel=1e-13)[0]

    rho = 1000.0
    mass = integral(lambda z: rho * math.pi * disc_radius2(z))
    axial = integral(lambda z: rho * math.pi * disc_radius2(z) ** 2 / 2)
    transverse = integral(lambda z: rho * math.pi * disc_radius2(z) * (disc_radius2(z) / 4 + z * z))
    assert b.mass == pytest.approx(mass, rel=1e-10)
    assert b.fullinertia == pytest.approx(
        (transverse, transverse, axial, 0, 0, 0), rel=1e-10, abs=1e-15
    )


def test_offset_rotated_primitive_has_its_com_and_rotated_tensor():
    rot = Rotation.from_rotvec([0.3, -0.5, 0.9])
    pos = (0.1, -0.2, 0.3)
    g = geom("box", (0.05, 0.1, 0.2), pos=pos, quat=tuple(rot.as_quat(scalar_first=True)))
    b = single(Link("b"), **collision("b", g)).inertials["b"]
    mass = 1000 * 0.1 * 0.2 * 0.4
    local = np.diag(
        [
            mass / 12 * (0.2**2 + 0.4**2),
            mass / 12 * (0.1**2 + 0.4**2),
            mass / 12 * (0.1**2 + 0.2**2),
        ]
    )
    r = rot.as_matrix()
    assert b.pos == pytest.approx(pos, abs=1e-15)
    assert full_matrix(b.fullinertia) == pytest.approx(r @ local @ r.T, abs=1e-15)


def test_two_geoms_combine_by_the_parallel_axis_theorem():
    r, d = 0.05, 0.2
    geoms = (geom("sphere", (r,), pos=(d, 0.0, 0.1)), geom("sphere", (r,), pos=(-d, 0.0, 0.1)))
    b = single(Link("l"), **collision("l", *geoms)).inertials["l"]
    m1 = 1000 * 4 / 3 * math.pi * r**3
    own = 0.4 * m1 * r * r
    assert b.mass == pytest.approx(2 * m1, rel=1e-12)
    assert b.pos == pytest.approx((0.0, 0.0, 0.1), abs=1e-15)
    expected = (2 * own, 2 * (own + m1 * d * d), 2 * (own + m1 * d * d), 0, 0, 0)
    assert b.fullinertia == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_visual_primitives_are_used_when_there_is_no_collision_geometry():
    link = Link("v", visuals=(Visual(Pose((0.0, 0.0, 0.5)), Sphere(0.1)),))
    m = single(link)
    b = m.inertials["v"]
    assert b.mass == pytest.approx(1000 * 4 / 3 * math.pi * 0.001, rel=1e-12)
    assert b.pos == (0.0, 0.0, 0.5)
    assert "visual geometry (sphere)" in notes_of(m, "estimated")[0]


def test_per_link_density_overrides_the_default():
    g = geom("box", (0.1, 0.1, 0.1))
    rob = robot(Link("a"), Link("b"), joints=(Joint("j", "fixed", "a", "b"),))
    cfg = InertiaConfig(density=1000.0, link_density={"b": 2700.0})
    m = convert(rob, cfg, collision_geoms={"a": (g,), "b": (g,)})
    assert m.inertials["a"].mass == pytest.approx(8.0, rel=1e-12)
    assert m.inertials["b"].mass == pytest.approx(8.0 * 2.7, rel=1e-12)
    assert "density 2700 kg/m^3" in notes_of(m, "estimated")[1]


def test_density_must_be_positive():
    with pytest.raises(ValueError, match="positive"):
        InertiaConfig(link_density={"a": 0.0})


def test_link_without_inertial_or_geometry_is_massless():
    m = single(Link("empty"))
    assert m.inertials == {"empty": None} and m.notes == ()


# --- estimates from meshes ----------------------------------------------------------------------

BOX = (0.2, 0.4, 0.6)


def analytic_box(density=1000.0):
    w, d, h = BOX
    mass = density * w * d * h
    return mass, np.array([d * d + h * h, w * w + h * h, w * w + d * d]) * mass / 12


def visual_mesh_model(vertices, faces, origin: Pose | None = None):
    path = Path("/meshes/box.stl")
    mesh = MeshData(np.asarray(vertices, float), np.asarray(faces, np.int64))
    loaded = LoadedMesh(path, (1.0, 1.0, 1.0), (), mesh, "0" * 64)
    link = Link("m", visuals=(Visual(origin or Pose(), MeshRef("package://p/box.stl", path)),))
    return single(link, meshes={(path, (1.0, 1.0, 1.0)): loaded})


def test_collision_mesh_piece_estimate_matches_the_analytic_box():
    box = trimesh.creation.box(BOX)
    asset = mesh_asset("box", MeshData(box.vertices, box.faces))
    g = Geom("collision", "mesh", (0.1, 0.2, 0.3), (1.0, 0.0, 0.0, 0.0), mesh=asset.name)
    b = single(Link("m"), mesh_assets=(asset,), **collision("m", g)).inertials["m"]
    mass, moments = analytic_box()
    assert b.pos == pytest.approx((0.1, 0.2, 0.3), abs=1e-7)
    assert b.mass == pytest.approx(mass, rel=1e-6)  # STL stores float32
    assert b.fullinertia == pytest.approx(tuple(moments) + (0, 0, 0), rel=1e-6, abs=1e-12)


def test_watertight_visual_mesh_estimate_matches_the_analytic_box():
    box = trimesh.creation.box(BOX)
    m = visual_mesh_model(box.vertices, box.faces, Pose((1.0, 2.0, 3.0), (0.0, 0.0, math.pi / 2)))
    b = m.inertials["m"]
    mass, (ixx, iyy, izz) = analytic_box()
    assert b.mass == pytest.approx(mass, rel=1e-12)
    assert b.pos == pytest.approx((1.0, 2.0, 3.0), abs=1e-12)
    assert b.fullinertia == pytest.approx(
        (iyy, ixx, izz, 0, 0, 0), rel=1e-12, abs=1e-12
    )  # yawed 90 deg
    assert [n.kind for n in m.notes] == ["estimated"]


def test_box_mesh_with_a_missing_face_is_estimated_close_to_the_closed_box_with_a_note():
    box = trimesh.creation.box(BOX)
    m = visual_mesh_model(box.vertices, box.faces[2:])  # two triangles = one face gone
    mass, moments = analytic_box()
    b = m.inertials["m"]
    assert b.mass == pytest.approx(mass, rel=1e-6)
    assert np.diag(full_matrix(b.fullinertia)) == pytest.approx(moments, rel=1e-6)
    assert any("not watertight" in n.message for n in m.notes)


def test_box_mesh_with_a_large_hole_falls_back_to_its_convex_hull_with_a_note():
    box = trimesh.creation.box(BOX)
    top_and_side = {i for i, n in enumerate(box.face_normals) if n[2] > 0.5 or n[0] > 0.5}
    m = visual_mesh_model(
        box.vertices, [f for i, f in enumerate(box.faces) if i not in top_and_side]
    )
    assert m.inertials["m"].mass == pytest.approx(analytic_box()[0], rel=1e-9)
    assert len(notes_of(m, "hull")) == 1


def test_flat_geometry_gives_no_mass_and_a_warning():
    link = Link("flat", visuals=(Visual(Pose(), Box((0.1, 0.1, 0.0))),))
    m = single(link)
    assert m.inertials["flat"] is None
    assert notes_of(m, "warning") == ["visual geometry (box) encloses no volume and gives no mass"]


# --- URDF inertials -----------------------------------------------------------------------------


def test_valid_inertial_without_rotation_is_kept_bit_for_bit():
    inertia = (0.011, 1.3e-4, -2.2e-4, 0.0123, 3.1e-5, 0.0071)  # ixx ixy ixz iyy iyz izz
    m = single(Link("l", inertial=urdf_inertial(1.25, inertia, xyz=(0.01, -0.02, 0.3))))
    b = m.inertials["l"]
    assert b.fullinertia == (0.011, 0.0123, 0.0071, 1.3e-4, -2.2e-4, 3.1e-5)
    assert (b.mass, b.pos, b.source) == (1.25, (0.01, -0.02, 0.3), "urdf")
    assert m.notes == ()


def test_valid_rotated_inertial_is_rotated_into_link_axes_and_mujoco_agrees():
    inertia = (0.03, 0.001, -0.002, 0.02, 0.0015, 0.012)
    rpy, xyz = (0.4, -1.1, 2.5), (0.05, 0.02, -0.1)
    rob = robot(
        Link("base"),
        Link("arm", inertial=urdf_inertial(2.5, inertia, xyz, rpy)),
        joints=(Joint("j", "revolute", "base", "arm", axis=(0.0, 0.0, 1.0)),),
    )
    m = convert(rob)
    b = m.inertials["arm"]
    r = Rotation.from_euler("xyz", rpy).as_matrix()  # extrinsic x, y, z = Rz Ry Rx
    i = full_matrix((inertia[0], inertia[3], inertia[5], inertia[1], inertia[2], inertia[4]))
    expected = r @ i @ r.T
    assert full_matrix(b.fullinertia) == pytest.approx(expected, abs=1e-15)
    assert (b.mass, b.pos, b.source) == (2.5, xyz, "urdf") and m.notes == ()

    mj = mujoco.MjModel.from_xml_string(mjcf(rob, m.inertials))
    body = mj.body("arm").id
    assert mj.body_mass[body] == 2.5
    assert mj.body_ipos[body] == pytest.approx(xyz, abs=1e-15)
    q = mj.body_iquat[body]
    rq = Rotation.from_quat(q, scalar_first=True).as_matrix()
    assert rq @ np.diag(mj.body_inertia[body]) @ rq.T == pytest.approx(expected, abs=1e-14)


def test_tensor_that_is_not_positive_definite_is_repaired_keeping_axes():
    # eigenvalues -1, 1, 3 along (1,-1,0)/sqrt2, z, (1,1,0)/sqrt2
    rob = robot(
        Link("base"),
        Link("l", inertial=urdf_inertial(1.0, (1.0, 2.0, 0.0, 1.0, 0.0, 1.0))),
        joints=(Joint("j", "revolute", "base", "l"),),
    )
    m = convert(rob)
    b = m.inertials["l"]
    assert b.source == "repaired"
    axes = np.array([[1, -1, 0], [0, 0, math.sqrt(2)], [1, 1, 0]]) / math.sqrt(2)
    in_axes = axes @ full_matrix(b.fullinertia) @ axes.T
    assert in_axes - np.diag(np.diag(in_axes)) == pytest.approx(np.zeros((3, 3)), abs=1e-12)
    # -1 -> floor 1e-3 * 3; then both smaller raised by (3 - 0.003 - 1) / 2 so that A + B = C
    assert np.diag(in_axes) == pytest.approx([1.0015, 1.9985, 3.0], rel=1e-9)
    (note,) = notes_of(m, "repaired")
    assert "inertia must have positive eigenvalues" in note and "(-1, 1, 3) ->" in note
    assert mujoco_error(rob, m.inertials) is None


def test_tensor_violating_the_triangle_inequality_is_repaired_and_compiles():
    rob = robot(
        Link("base"),
        Link("l", inertial=urdf_inertial(2.0, (0.1, 0.0, 0.0, 0.2, 0.0, 1.0), rpy=(0.3, 0.2, 0.1))),
        joints=(Joint("j", "revolute", "base", "l"),),
    )
    m = convert(rob)
    b = m.inertials["l"]
    moments = np.linalg.eigvalsh(full_matrix(b.fullinertia))
    assert moments == pytest.approx([0.45, 0.55, 1.0], rel=1e-9)  # both raised by 0.35
    assert b.source == "repaired" and "A + B >= C" in notes_of(m, "repaired")[0]
    assert mujoco_error(rob, m.inertials) is None


def test_point_mass_on_a_welded_frame_is_kept_as_given():
    # MuJoCo accepts diaginertia="0 0 0" on a body without joints (a tool frame).
    m = single(Link("tool", inertial=urdf_inertial(2.0, (0.0,) * 6, xyz=(0.0, 0.0, 0.05))))
    b = m.inertials["tool"]
    assert (b.mass, b.pos, b.fullinertia, b.source) == (2.0, (0.0, 0.0, 0.05), (0.0,) * 6, "urdf")
    assert not notes_of(m, "repaired")
    assert mujoco_error(m.robot, m.inertials) is None


def test_point_mass_on_a_link_with_a_joint_is_repaired_into_a_one_centimetre_sphere():
    rob = robot(
        Link("base", inertial=MASSIVE),
        Link("tool", inertial=urdf_inertial(2.0, (0.0,) * 6, xyz=(0.0, 0.0, 0.05))),
        joints=(rev("j", "base", "tool"),),
    )
    as_given = {
        "base": convert(rob).inertials["base"],
        "tool": BodyInertial(2.0, (0.0, 0.0, 0.05), (0.0,) * 6),
    }
    assert "mass and inertia of moving bodies" in mujoco_error(rob, as_given)
    m = convert(rob)
    b = m.inertials["tool"]
    sphere = 0.4 * 2.0 * 0.01**2
    assert b.fullinertia == pytest.approx((sphere,) * 3 + (0, 0, 0), rel=1e-12, abs=1e-18)
    assert (b.mass, b.pos, b.source) == (2.0, (0.0, 0.0, 0.05), "repaired")
    assert notes_of(m, "repaired")[0].endswith("(0, 0, 0) -> (8e-05, 8e-05, 8e-05) kg m^2")
    assert mujoco_error(rob, m.inertials) is None


def test_point_mass_on_a_link_with_geometry_gets_its_geometry_inertia_at_the_declared_mass():
    # gingerurdf.urdf (urdf_files_dataset): 30 kg links with ixx = iyy = izz = 0. A
    # 1 cm sphere's tensor on them diverges in a fifth of a second; the box they are
    # shaped like, at their own mass, does not.
    rob = robot(
        Link("base", inertial=MASSIVE),
        Link("arm", inertial=urdf_inertial(30.0, (0.0,) * 6, xyz=(0.0, 0.0, 0.3))),
        joints=(rev("j", "base", "arm"),),
    )
    m = convert(rob, **collision("arm", geom("box", (0.05, 0.1, 0.3), pos=(0.0, 0.0, 0.3))))
    b = m.inertials["arm"]
    w, d, h = 0.1, 0.2, 0.6
    box = (30.0 / 12 * (d * d + h * h), 30.0 / 12 * (w * w + h * h), 30.0 / 12 * (w * w + d * d))
    assert b.fullinertia == pytest.approx(box + (0, 0, 0), rel=1e-12, abs=1e-15)
    assert (b.mass, b.pos, b.source) == (30.0, (0.0, 0.0, 0.3), "repaired")
    (note,) = notes_of(m, "repaired")
    assert "collision geometry (box) at the declared mass 30 kg" in note
    assert mujoco_error(rob, m.inertials) is None


def test_boundary_tensors_are_repaired_exactly_when_mujoco_rejects_them():
    # Thin plates (A + B = C up to rounding) in random orientations: MuJoCo's own
    # eigen-solver decides, with no tolerance; rpy = 0 so the URDF numbers are what
    # MuJoCo would read.
    rng = np.random.default_rng(7)
    outcomes = set()
    for k in range(40):
        a, b = rng.uniform(0.01, 0.1, 2)
        r = Rotation.random(random_state=k).as_matrix()
        t = r @ np.diag([a, b, a + b]) @ r.T
        inertia = (t[0, 0], t[0, 1], t[0, 2], t[1, 1], t[1, 2], t[2, 2])
        rob = robot(
            Link("base"),
            Link("l", inertial=urdf_inertial(1.0, inertia)),
            joints=(Joint("j", "revolute", "base", "l"),),
        )
        m = convert(rob)
        unrepaired = (t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2])
        mujoco_accepts = (
            mujoco_error(rob, {"base": None, "l": _replace_full(m.inertials["l"], unrepaired)})
            is None
        )
        assert (m.inertials["l"].source == "urdf") == mujoco_accepts
        if mujoco_accepts:
            assert m.inertials["l"].fullinertia == unrepaired
        assert mujoco_error(rob, m.inertials) is None
        outcomes.add(mujoco_accepts)
    assert outcomes == {True, False}  # both cases were exercised


def _replace_full(b, full):
    return dataclasses.replace(b, fullinertia=tuple(float(x) for x in full))


def test_negative_mass_raises_naming_link_and_value():
    with pytest.raises(InertiaError) as err:
        single(Link("wheel", inertial=urdf_inertial(-0.5, (1, 0, 0, 1, 0, 1))))
    assert err.value.element == "link 'wheel' inertial"
    assert err.value.file == str(SOURCE)
    assert "-0.5" in str(err.value) and "negative" in str(err.value)


@pytest.mark.parametrize(
    "inertial",
    [
        urdf_inertial(float("nan"), (1, 0, 0, 1, 0, 1)),
        urdf_inertial(1.0, (1, 0, 0, float("inf"), 0, 1)),
        urdf_inertial(1.0, (1, 0, 0, 1, 0, 1), rpy=(0.0, float("nan"), 0.0)),
    ],
)
def test_non_finite_inertial_raises(inertial):
    with pytest.raises(InertiaError, match="non-finite"):
        single(Link("l", inertial=inertial))


# --- zero mass: repaired exactly where MuJoCo 4.0 rejects the model ----------------------------

MASSIVE = urdf_inertial(1.0, (0.01, 0, 0, 0.01, 0, 0.01))
ZERO = urdf_inertial(0.0, (0, 0, 0, 0, 0, 0))


def rev(name, parent, child):
    return Joint(
        name, "revolute", parent, child, origin=Pose((0.0, 0.0, 0.1)), axis=(0.0, 1.0, 0.0)
    )


def fixed(name, parent, child):
    return Joint(name, "fixed", parent, child, origin=Pose((0.1, 0.0, 0.0)))


ZERO_MASS_CASES = {
    "massless frame links on fixed joints": robot(
        Link("base", inertial=MASSIVE),
        Link("tool0", inertial=ZERO),
        Link("flange"),
        joints=(fixed("f1", "base", "tool0"), fixed("f2", "tool0", "flange")),
    ),
    "massless moving link whose welded child has mass": robot(
        Link("base", inertial=MASSIVE),
        Link("shaft", inertial=ZERO),
        Link("disc", inertial=MASSIVE),
        joints=(rev("j", "base", "shaft"), fixed("f", "shaft", "disc")),
    ),
    "massless middle link of a universal joint": robot(
        Link("base", inertial=MASSIVE),
        Link("cross", inertial=ZERO),
        Link("yoke", inertial=MASSIVE),
        joints=(rev("j1", "base", "cross"), rev("j2", "cross", "yoke")),
    ),
    "massless leaf on a revolute joint": robot(
        Link("base", inertial=MASSIVE),
        Link("tip", inertial=ZERO),
        joints=(rev("j", "base", "tip"),),
    ),
    "massless moving link whose welded child is a point mass": robot(
        Link("base", inertial=MASSIVE),
        Link("a"),
        Link("b", inertial=urdf_inertial(1.0, (0,) * 6)),
        joints=(rev("j", "base", "a"), fixed("f", "a", "b")),
    ),
}


@pytest.mark.parametrize("case", ZERO_MASS_CASES)
def test_zero_mass_is_repaired_only_where_mujoco_rejects_the_model(case):
    rob = ZERO_MASS_CASES[case]
    m = convert(rob)
    massless_as_urdf = {link.name: m.inertials[link.name] for link in rob.links}
    repaired = {
        n.element for n in m.notes if n.kind == "repaired" and "body with joints" in n.message
    }
    for element in repaired:
        massless_as_urdf[element.split("'")[1]] = None
    mujoco_rejects = mujoco_error(rob, massless_as_urdf)
    assert bool(repaired) == (mujoco_rejects is not None), mujoco_rejects
    if mujoco_rejects is not None:
        assert "mass and inertia of moving bodies" in mujoco_rejects
    assert mujoco_error(rob, m.inertials) is None


def test_massless_universal_joint_cross_gets_the_documented_fallback():
    m = convert(ZERO_MASS_CASES["massless middle link of a universal joint"])
    cross = m.inertials["cross"]
    assert (cross.mass, cross.pos, cross.fullinertia, cross.source) == (
        1e-3,
        (0.0, 0.0, 0.0),
        (1e-6, 1e-6, 1e-6, 0.0, 0.0, 0.0),
        "repaired",
    )
    assert [n.element for n in m.notes] == ["link 'cross'"]


def test_massless_moving_leaf_with_geometry_gets_mass_from_it():
    rob = ZERO_MASS_CASES["massless leaf on a revolute joint"]
    m = convert(
        rob, InertiaConfig(density=2000.0), **collision("tip", geom("box", (0.01, 0.02, 0.03)))
    )
    tip = m.inertials["tip"]
    assert tip.mass == pytest.approx(2000 * 0.02 * 0.04 * 0.06, rel=1e-12)
    assert tip.source == "repaired"
    (note,) = notes_of(m, "repaired")
    assert "collision geometry (box) at density 2000 kg/m^3" in note
    assert mujoco_error(rob, m.inertials) is None


def test_massless_root_needs_mass_only_when_it_gets_a_free_joint():
    rob = robot(Link("base", inertial=ZERO))
    assert convert(rob).inertials["base"] is None
    assert convert(rob, InertiaConfig(free_root=True)).inertials["base"].source == "repaired"
