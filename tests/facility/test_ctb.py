"""The cargo transfer bag (facility/mockups/ctb): a free body of known mass and
inertia with a red-taped handle strap on top; it settles upright on the floor
and stays upright in the stowage unit's seat bin."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from .mechanism_checks import ROOT, convert, penetrations, pose

SOURCE = ROOT / "facility" / "mockups" / "ctb" / "urdf" / "ctb.urdf.xacro"
IN_BIN = ROOT / "tests" / "facility" / "data" / "ctb_in_seat_bin.urdf.xacro"

SIZE = np.array([0.50, 0.43, 0.25])
STATED_INERTIA = (0.0505, 0.0675, 0.0326)
# the stated moments on our axes: x along the 0.50 m length, z up through the 0.25 m
LINK_AXES_INERTIA = (0.0326, 0.0505, 0.0675)
RED = np.array([0.85, 0.05, 0.05])

BIN_FLOOR = np.array([0.92, 0.0, 0.615])  # stowage unit frame = world in the test scene
BIN_INSIDE = np.array([0.60, 0.55, 0.32])


@pytest.fixture(scope="module")
def standalone(tmp_path_factory):
    return convert(SOURCE, tmp_path_factory.mktemp("ctb") / "ctb.xml")


@pytest.fixture(scope="module")
def in_bin(tmp_path_factory):
    return convert(IN_BIN, tmp_path_factory.mktemp("ctb_in_bin") / "ctb_in_bin.xml")[0]


def geoms_of(m, body, collision):
    b = m.body(body).id
    return [
        g
        for g in range(m.ngeom)
        if m.geom_bodyid[g] == b and bool(m.geom_contype[g] or m.geom_conaffinity[g]) == collision
    ]


def tilt_deg(d, body_id):
    return math.degrees(math.acos(np.clip(d.xmat[body_id][8], -1.0, 1.0)))


def set_pose(m, d, joint, xyz, rpy=(0.0, 0.0, 0.0)):
    adr = m.joint(joint).qposadr[0]
    quat = np.zeros(4)
    mujoco.mju_euler2Quat(quat, np.asarray(rpy, float), "xyz")
    d.qpos[adr : adr + 3] = xyz
    d.qpos[adr + 3 : adr + 7] = quat
    d.qvel[:] = 0.0
    mujoco.mj_forward(m, d)


def settle(m, d, joint, seconds):
    """Step ``seconds``; the bag's final linear and angular speed."""
    for _ in range(int(round(seconds / m.opt.timestep))):
        mujoco.mj_step(m, d)
    dof = m.joint(joint).dofadr[0]
    return float(np.linalg.norm(d.qvel[dof : dof + 3])), float(
        np.linalg.norm(d.qvel[dof + 3 : dof + 6])
    )


def bag_corners(m, d, body):
    """World corners of the bag's main collision box."""
    g = m.geom(f"{body}_collision_0").id
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    return d.geom_xpos[g] + (signs * m.geom_size[g]) @ d.geom_xmat[g].reshape(3, 3).T


# ------------------------------------------------------------------ description


def test_converts_to_a_free_body(standalone):
    m, report = standalone
    assert not report.warnings, [n.message for n in report.warnings]
    j = m.joint("ctb_joint")
    assert j.type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert m.body("ctb").parentid[0] == 0
    assert m.nu == 0  # nothing drives it


def test_mass_and_inertia(standalone):
    m, _ = standalone
    b = m.body("ctb")
    assert b.mass[0] == pytest.approx(1.8)
    assert sorted(b.inertia) == pytest.approx(sorted(STATED_INERTIA), rel=1e-9)
    # the tensor in link axes: the stated moments about z (length), x (width), y (height)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, b.iquat)
    rot = rot.reshape(3, 3)
    tensor = rot @ np.diag(b.inertia) @ rot.T
    assert tensor == pytest.approx(np.diag(LINK_AXES_INERTIA), abs=1e-12)
    assert b.ipos == pytest.approx([0, 0, SIZE[2] / 2])
    # consistent with a uniform box of the bag's size, within 15 %
    box = (
        1.8
        / 12
        * np.array(
            [SIZE[1] ** 2 + SIZE[2] ** 2, SIZE[0] ** 2 + SIZE[2] ** 2, SIZE[0] ** 2 + SIZE[1] ** 2]
        )
    )
    assert np.diag(tensor) == pytest.approx(box, rel=0.15)


def test_bag_body_and_bottom_contact(standalone):
    m, _ = standalone
    body = m.geom("ctb_collision_0")
    assert body.type[0] == mujoco.mjtGeom.mjGEOM_BOX
    assert 2 * body.size == pytest.approx(SIZE)
    assert body.pos == pytest.approx([0, 0, SIZE[2] / 2])  # frame at the centre of the bottom
    assert body.friction[0] >= 1.0 and body.condim[0] >= 4  # grippy fabric, torsional friction
    fabric = [
        g for g in geoms_of(m, "ctb", collision=False) if m.geom_size[g][0] == pytest.approx(0.25)
    ]
    assert len(fabric) == 1


def test_handle_strap_is_red_graspable_and_rigid(standalone):
    m, _ = standalone
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    top = SIZE[2]
    # visual: red tape, and only the handle is red
    red = [g for g in geoms_of(m, "ctb", collision=False) if np.allclose(m.geom_rgba[g][:3], RED)]
    red += [
        g
        for g in geoms_of(m, "ctb", collision=False)
        if m.geom_matid[g] >= 0 and np.allclose(m.mat_rgba[m.geom_matid[g]][:3], RED)
    ]
    assert len(red) == 3
    for g in red:
        assert m.geom_pos[g][2] > top  # all above the bag
    # collision: strap and loops are geoms of the bag's own body (rigid)
    strap = m.geom("ctb_collision_1")
    assert strap.bodyid[0] == m.body("ctb").id
    length, width, thick = 2 * strap.size
    assert 0.20 <= length <= 0.25 and width == pytest.approx(0.03)
    under = strap.pos[2] - strap.size[2] - top
    over = strap.pos[2] + strap.size[2] - top
    assert 0.02 <= under and 0.02 <= over <= 0.04  # finger room under it, 2-4 cm proud
    loops = [m.geom(f"ctb_collision_{k}") for k in (2, 3)]
    for loop in loops:  # they join the strap to the bag
        assert loop.pos[2] - loop.size[2] == pytest.approx(top)
        assert loop.pos[2] + loop.size[2] == pytest.approx(strap.pos[2] + strap.size[2])
    gap = min(abs(loop.pos[0]) - loop.size[0] for loop in loops)
    assert gap >= 0.08  # a 0.16 m+ long opening for the fingers


def test_red_handle_found_on_a_camera_image(standalone, gl_context):
    """A camera 0.6 m above the bag, looking down: the red mask is the strap."""
    m, _ = standalone
    d = mujoco.MjData(m)
    set_pose(m, d, "ctb_joint", [0, 0, 0], [0, 0, math.radians(30)])
    renderer = mujoco.Renderer(m, 240, 320)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = [0, 0, 0.25]
    cam.distance, cam.azimuth, cam.elevation = 0.6, 90.0, -90.0
    opt = mujoco.MjvOption()
    renderer.update_scene(d, cam, opt)
    img = renderer.render().astype(int)
    renderer.close()
    mask = (img[..., 0] > 120) & (img[..., 1] < 60) & (img[..., 2] < 60)
    ys, xs = np.nonzero(mask)
    assert 300 < mask.sum() < 8000, mask.sum()
    assert abs(xs.mean() - 160) < 10 and abs(ys.mean() - 120) < 10  # centred, as the bag
    cov = np.cov(np.vstack([xs, ys]))
    evals, evecs = np.linalg.eigh(cov)
    assert evals[1] > 10 * evals[0]  # a long thin strip
    angle = math.degrees(math.atan2(evecs[1, 1], evecs[0, 1])) % 180
    assert min(abs(angle - 30), abs(angle - 150)) < 8  # along the bag's length, turned 30 deg


# ------------------------------------------------------------------ on the floor


@pytest.mark.parametrize("seed", range(5))
def test_dropped_from_5_cm_settles_upright(standalone, seed):
    m, _ = standalone
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    tilt = np.radians(rng.uniform(-3, 3, 2)) if seed else np.zeros(2)
    xy = rng.uniform(-0.2, 0.2, 2) if seed else np.zeros(2)
    set_pose(m, d, "ctb_joint", [*xy, 0.05], [tilt[0], tilt[1], rng.uniform(-math.pi, math.pi)])
    speed, spin = settle(m, d, "ctb_joint", 3.0)
    b = m.body("ctb").id
    assert tilt_deg(d, b) < 5.0
    assert speed < 0.01 and spin < 0.05
    assert abs(bag_corners(m, d, "ctb")[:, 2].min()) < 0.002  # resting on the floor (top z = 0)
    assert np.linalg.norm(d.xpos[b][:2] - xy) < 0.02  # where it was dropped


# ------------------------------------------------------------------ in the seat bin


def inside_bin(corners, tol=0.001):
    lo = BIN_FLOOR - [BIN_INSIDE[0] / 2, BIN_INSIDE[1] / 2, 0] - tol
    hi = BIN_FLOOR + [BIN_INSIDE[0] / 2, BIN_INSIDE[1] / 2, BIN_INSIDE[2]] + tol
    return bool(np.all(corners >= lo) and np.all(corners <= hi))


def test_placed_upright_in_the_bin_stays_upright(in_bin):
    m = in_bin
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    b = m.body("bag_ctb").id
    assert d.xpos[b] == pytest.approx(BIN_FLOOR + [0, 0, 0.002])
    assert inside_bin(bag_corners(m, d, "bag_ctb"))
    speed, spin = settle(m, d, "bag_ctb_joint", 3.0)
    assert tilt_deg(d, b) < 1.0
    assert speed < 0.01 and spin < 0.05
    assert inside_bin(bag_corners(m, d, "bag_ctb"))
    assert d.xpos[b] == pytest.approx(BIN_FLOOR, abs=0.002)


@pytest.mark.parametrize("seed", range(4))
def test_released_off_centre_in_the_bin_stays_upright_inside(in_bin, seed):
    """As a robot places it: up to 3 cm off centre, turned up to 6 deg, let go 3 cm up."""
    m = in_bin
    d = mujoco.MjData(m)
    rng = np.random.default_rng(100 + seed)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    xy = BIN_FLOOR[:2] + rng.uniform(-0.03, 0.03, 2)
    set_pose(m, d, "bag_ctb_joint", [*xy, BIN_FLOOR[2] + 0.03], [0, 0, rng.uniform(-0.1, 0.1)])
    speed, spin = settle(m, d, "bag_ctb_joint", 3.0)
    assert tilt_deg(d, m.body("bag_ctb").id) < 5.0
    assert speed < 0.01 and spin < 0.05
    assert inside_bin(bag_corners(m, d, "bag_ctb"))


def test_lid_closes_over_a_stowed_bag(in_bin):
    m = in_bin
    d = mujoco.MjData(m)
    for q in np.linspace(0, 1.658, 31):
        pose(m, d, {"su_lid_joint": q})
        bodies = [
            {m.body(m.geom_bodyid[g]).name for g in (c.geom1, c.geom2)} for c in d.contact[: d.ncon]
        ]
        assert {"bag_ctb", "su_lid"} not in bodies, q  # not even touching
        assert not penetrations(m, d), q


def test_room_for_a_gripper_above_the_bag_with_the_lid_open(in_bin):
    """Nothing of the unit within 0.6 m above the strap over a 0.20 x 0.20 m area."""
    m = in_bin
    d = mujoco.MjData(m)
    pose(m, d, {"su_lid_joint": 1.658})
    top = m.geom("bag_ctb_collision_1")
    strap_top = d.geom_xpos[top.id][2] + top.size[2]
    geomid = np.zeros(1, np.int32)
    group = np.array([0, 0, 0, 1, 0, 0], np.uint8)  # collision geoms
    for dx in np.linspace(-0.1, 0.1, 5):
        for dy in np.linspace(-0.1, 0.1, 5):
            start = np.array([BIN_FLOOR[0] + dx, dy, strap_top + 0.001])
            dist = mujoco.mj_ray(m, d, start, np.array([0, 0, 1.0]), group, 1, -1, geomid)
            assert dist == -1 or dist > 0.6, (dx, dy, dist, m.geom(geomid[0]).name)


def test_only_the_strap_is_red_in_the_bin_scene(in_bin):
    """The demo finds the handle by colour: nothing else may look red."""
    m = in_bin
    for g in range(m.ngeom):
        rgba = m.mat_rgba[m.geom_matid[g]] if m.geom_matid[g] >= 0 else m.geom_rgba[g]
        r, gr, b = rgba[:3]
        if r > 0.5 and gr < 0.3 and b < 0.3:
            assert m.body(m.geom_bodyid[g]).name == "bag_ctb", m.geom(g).name
            assert m.geom_pos[g][2] > 0.25, m.geom(g).name  # above the bag: the strap
