"""The stowage unit ("trainer") mockup with its bench seat: conversion, joints,
masses, the lid that stays open, sweeps without interpenetration, rest, and
its generated meshes (facility/mockups/stowage_unit, meshes/stowage_unit)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from .mechanism_checks import (
    ROOT,
    collision_bounds,
    convert,
    joints,
    mesh_bounds,
    mesh_volume,
    penetrations,
    pose,
    run_mesh_script,
    sweep,
)

SOURCE = ROOT / "facility" / "mockups" / "stowage_unit" / "urdf" / "stowage_unit.urdf.xacro"
MESHES = ROOT / "meshes" / "stowage_unit"
SCRIPT = MESHES / "make_stowage_unit.py"
MESH_FILES = (
    "base_frame.stl",
    "drawer_tray.stl",
    "recess_cup.stl",
    "seat_bin.stl",
    "tower_shell.stl",
)

LID_OPEN = 1.658  # 95 deg
# name: (type, world axis with the unit at the origin, range, damping, friction)
JOINTS = {
    "lid_joint": ("revolute", (0, -1, 0), (0.0, LID_OPEN), 3.0, 3.0),
    "drawer_left_joint": ("prismatic", (1, 0, 0), (0.0, 0.305), 10.0, 5.0),
    "drawer_right_joint": ("prismatic", (1, 0, 0), (0.0, 0.292), 10.0, 5.0),
    "door_left_rear_joint": ("revolute", (0, 0, 1), (0.0, math.pi), 2.0, 2.0),
    "door_left_front_joint": ("revolute", (0, 0, -1), (0.0, math.pi), 2.0, 2.0),
    "door_right_rear_joint": ("revolute", (0, 0, -1), (0.0, math.pi), 2.0, 2.0),
    "door_right_front_joint": ("revolute", (0, 0, 1), (0.0, math.pi), 2.0, 2.0),
    # latches: push-button into the left rear door (its outward normal is +y)
    "push_button_joint": ("prismatic", (0, -1, 0), (0.0, 0.005), 5.0, 1.0),
    "push_handle_joint": ("revolute", (-1, 0, 0), (0.0, math.pi / 3), 0.2, 0.3),
    "paddle_joint": ("revolute", (-1, 0, 0), (0.0, 0.785), 0.2, 0.3),
    "recessed_latch_joint": ("revolute", (0, -1, 0), (0.0, math.pi / 2), 0.2, 0.2),
    # the catches inside the doors, drawn back along the door by their latches
    "door_left_rear_catch_joint": ("prismatic", (-1, 0, 0), (0.0, 0.045), 1.0, 0.0),
    "door_left_front_catch_joint": ("prismatic", (1, 0, 0), (0.0, 0.045), 1.0, 0.0),
    "door_right_rear_catch_joint": ("prismatic", (-1, 0, 0), (0.0, 0.045), 1.0, 0.0),
    "door_right_front_catch_joint": ("prismatic", (1, 0, 0), (0.0, 0.045), 1.0, 0.0),
}
# latch -> (its door's catch, the latch's released value): catch = 0.045 / released x latch
CATCHES = {
    "push_button_joint": ("door_left_rear_catch_joint", 0.005),
    "push_handle_joint": ("door_left_front_catch_joint", math.pi / 3),
    "paddle_joint": ("door_right_rear_catch_joint", 0.785),
    "recessed_latch_joint": ("door_right_front_catch_joint", math.pi / 2),
}
# every latch operated and its catch drawn back: the doors are free
DRAWN = {c: 0.045 for c, _ in CATCHES.values()} | {n: r for n, (_, r) in CATCHES.items()}
# Contacts between mockup bodies that are allowed to be deeper than 1 mm: none.
ALLOWED: tuple[frozenset[str], ...] = ()

DENSITY = {"aluminium": 2700.0, "plywood": 600.0, "abs": 1050.0, "anodized": 2700.0}
TUBE_AREA = 0.04**2 - 0.034**2  # 40 x 40 x 3 mm


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    return convert(SOURCE, tmp_path_factory.mktemp("stowage_unit") / "stowage_unit.xml")


@pytest.fixture(scope="module")
def model(converted) -> mujoco.MjModel:
    return converted[0]


def simulate(m, d, seconds, watch=None):
    """Step ``seconds``; the values of qpos[watch] along the way."""
    trace = []
    for _ in range(int(round(seconds / m.opt.timestep))):
        mujoco.mj_step(m, d)
        if watch is not None:
            trace.append(float(d.qpos[watch]))
    return np.array(trace)


def box_corners(m, d) -> np.ndarray:
    """World positions of the 8 corners of every box geom (visual and collision)."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    pts = []
    for g in range(m.ngeom):
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            r = d.geom_xmat[g].reshape(3, 3)
            pts.append(d.geom_xpos[g] + (signs * m.geom_size[g]) @ r.T)
    return np.concatenate(pts)


# ------------------------------------------------------------------ conversion


def test_converts_without_warnings_or_decomposition(converted):
    m, report = converted
    assert not report.warnings, [n.message for n in report.warnings]
    assert not report.estimated, "every link has its inertial from the xacro"
    assert not report.decomposed and not report.cached, "collision is primitives only"
    assert m.body("stowage_unit").parentid == 0  # on the world by stowage_unit_mount
    for b in range(m.nbody):
        for g in range(m.ngeom):
            if m.geom_bodyid[g] == b and m.geom_contype[g]:
                assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX, m.geom(g).name


def test_prefix_applies_to_every_name(tmp_path):
    src = tmp_path / "two.urdf.xacro"
    src.write_text(
        """<?xml version="1.0"?>
<robot name="two" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="$(find stowage_unit)/urdf/stowage_unit.xacro"/>
  <xacro:material_colors/>
  <link name="world"/>
  <xacro:stowage_unit prefix="a_" parent="world"><origin xyz="0 0 0" rpy="0 0 0"/></xacro:stowage_unit>
  <xacro:stowage_unit prefix="b_" parent="world"><origin xyz="0 3 0" rpy="0 0 ${pi}"/></xacro:stowage_unit>
</robot>"""
    )
    m, report = convert(src, tmp_path / "out" / "two.xml")
    names = [m.body(b).name for b in range(1, m.nbody)] + [m.joint(j).name for j in range(m.njnt)]
    assert all(n.startswith(("a_", "b_")) for n in names), names
    assert {"a_stowage_unit_mount", "b_stowage_unit_mount"} <= {
        j.name for j in report.model.robot.joints
    }
    assert m.njnt == 2 * len(JOINTS)


# ------------------------------------------------------------------ joints


def test_joints_names_types_ranges_dynamics(model):
    found = joints(model)
    assert set(found) == set(JOINTS)
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    for name, (kind, axis, rng, damping, friction) in JOINTS.items():
        j = found[name]
        assert j.type == kind, name
        assert j.range == pytest.approx(rng, abs=1e-9), name
        assert j.damping == pytest.approx(damping), name
        assert j.frictionloss == pytest.approx(friction), name
        assert d.xaxis[model.joint(name).id] == pytest.approx(axis, abs=1e-9), name


def test_lid_hinge_at_the_back_edge_and_opens_upward(model):
    d = mujoco.MjData(model)
    pose(model, d, {})
    hinge = d.xanchor[model.joint("lid_joint").id].copy()
    assert hinge == pytest.approx([0.551, 0.0, 0.948], abs=1e-9)
    assert d.xpos[model.body("lid_hinge").id] == pytest.approx(hinge, abs=1e-9)
    closed = d.xipos[model.body("lid").id].copy()
    assert closed[0] > hinge[0]  # the lid lies forward of its hinge (towards the bench front)
    pose(model, d, {"lid_joint": math.pi / 2})
    upright = d.xipos[model.body("lid").id]
    assert upright[2] > closed[2] + 0.3  # positive angles lift the lid
    # the bench seat frame of the facts, and the bench box under the lid
    assert d.xpos[model.body("bench_seat").id] == pytest.approx([1.261, 0, 0.477])


def test_bin_holds_a_ctb_and_leaves_room_above(model):
    """Inside of the bin 0.60 x 0.55 x 0.32 at the documented place (unit frame)."""
    d = mujoco.MjData(model)
    pose(model, d, {})
    assert d.xpos[model.body("seat_bin").id] == pytest.approx([0.92, 0.0, 0.615], abs=1e-9)
    lo, hi = collision_bounds(model, d, "seat_bin")
    # the walls and floor enclose the inside: outer box 10 mm larger all round
    assert lo == pytest.approx([-0.31, -0.285, -0.138], abs=1e-9)  # cleats reach the deck
    assert hi == pytest.approx([0.31, 0.285, 0.32], abs=1e-9)
    inside = np.array([0.60, 0.55, 0.32])
    ctb = np.array([0.50, 0.43, 0.25 + 0.036])  # with its handle
    assert np.all(inside - ctb >= [0.05, 0.05, 0.03])
    # closed lid clears a stowed CTB; nothing above the bin when the lid is open
    lid_underside = 0.948
    assert 0.615 + ctb[2] < lid_underside - 0.04


# ------------------------------------------------------------------ masses


def test_known_masses(model):
    assert model.body("lid").mass[0] == pytest.approx(9.07)
    assert model.body("bench_back").mass[0] == pytest.approx(12.3)
    assert model.body("bench_side_left").mass[0] == pytest.approx(3.07)
    assert model.body("bench_side_right").mass[0] == pytest.approx(3.07)
    assert model.body("bench_front").mass[0] == pytest.approx(3.88)


def test_masses_from_density(model):
    frame_length = mesh_volume(MESHES / "base_frame.stl") / 0.04**2  # the mesh is solid bars
    assert frame_length == pytest.approx(13.51, abs=1e-3)
    assert model.body("stowage_unit").mass[0] == pytest.approx(
        2700 * TUBE_AREA * frame_length, rel=1e-5
    )
    assert model.body("deck").mass[0] == pytest.approx(600 * 1.27 * 0.90 * 0.007)
    assert model.body("tower").mass[0] == pytest.approx(
        600 * mesh_volume(MESHES / "tower_shell.stl"), rel=1e-5
    )
    cleats = 2 * 600 * 0.60 * 0.04 * 0.128
    bin_abs = 1050 * mesh_volume(MESHES / "seat_bin.stl")
    assert model.body("seat_bin").mass[0] == pytest.approx(bin_abs + cleats, rel=1e-5)
    tray = 1050 * mesh_volume(MESHES / "drawer_tray.stl")
    front = 600 * 0.018 * 0.40 * 0.40
    handle = 2700 * (2 * 0.025 * 0.015 * 0.015 + 0.015 * 0.15 * 0.015)
    for drawer in ("drawer_left", "drawer_right"):
        assert model.body(drawer).mass[0] == pytest.approx(tray + front + handle, rel=1e-5)
    for door in ("door_left_rear", "door_left_front", "door_right_rear", "door_right_front"):
        leaf = 600 * 0.38 * 0.015 * 0.41
        knuckles = 2 * 2700 * 0.02 * 0.02 * 0.05
        assert model.body(door).mass[0] == pytest.approx(leaf + knuckles)
    total = sum(model.body_mass[1:])
    assert 100 < total < 125  # about 112 kg


def test_inertias_are_physical(model):
    for b in range(1, model.nbody):
        if model.body_mass[b] == 0:
            continue
        i = np.sort(model.body_inertia[b])
        assert i[0] > 0 and i[0] + i[1] >= i[2] * (1 - 1e-9), model.body(b).name


# ------------------------------------------------------------------ the lid


def test_lid_opened_to_95_deg_stays_open(model):
    d = mujoco.MjData(model)
    pose(model, d, {"lid_joint": LID_OPEN})
    adr = model.joint("lid_joint").qposadr[0]
    # past vertical: gravity holds it against its upper limit
    assert d.xipos[model.body("lid").id][0] < d.xanchor[model.joint("lid_joint").id][0]
    trace = simulate(model, d, 3.0, adr)
    assert trace.min() > LID_OPEN - math.radians(0.5)
    assert abs(trace[-1] - LID_OPEN) < math.radians(0.1)


def test_lid_left_just_past_vertical_does_not_fall_back(model):
    """The demo opens it by 8 x 11.5 = 92 deg and lets go."""
    d = mujoco.MjData(model)
    pose(model, d, {"lid_joint": math.radians(92)})
    trace = simulate(model, d, 3.0, model.joint("lid_joint").qposadr[0])
    assert trace.min() > math.radians(92) - math.radians(0.2)


def test_closed_lid_stays_closed(model):
    d = mujoco.MjData(model)
    pose(model, d, {})
    trace = simulate(model, d, 3.0, model.joint("lid_joint").qposadr[0])
    assert np.abs(trace).max() < 1e-3  # rad: the front edge moves < 0.7 mm


def test_lid_at_60_deg_falls_shut(model):
    """Friction (3 N m) holds the lid only near vertical: gravity closes it from 60 deg."""
    d = mujoco.MjData(model)
    pose(model, d, {"lid_joint": math.radians(60)})
    trace = simulate(model, d, 3.0, model.joint("lid_joint").qposadr[0])
    assert abs(trace[-1]) < 2e-3


# ------------------------------------------------------------------ interpenetration


@pytest.mark.parametrize("joint", sorted(JOINTS))
def test_joint_sweeps_full_range_without_interpenetration(model, joint):
    lo, hi = JOINTS[joint][2]
    # a door swings with its catch drawn back (thrown, it stops the door: test_mechanisms.py)
    fixed = DRAWN if joint.startswith("door_") else None
    if joint in DRAWN:  # a latch or a catch itself, alone
        fixed = None
    bad = sweep(model, {joint: np.linspace(lo, hi, 61)}, fixed=fixed, allowed=ALLOWED)
    assert not bad, bad[:5]


def test_lid_sweeps_with_everything_else_open(model):
    """The demo pose family: the lid through its range with drawers and doors open."""
    others = {n: rng[1] for n, (_, _, rng, _, _) in JOINTS.items() if n != "lid_joint"}
    bad = sweep(model, {"lid_joint": np.linspace(0, LID_OPEN, 31)}, fixed=others, allowed=ALLOWED)
    assert not bad, bad[:5]


def test_random_joint_combinations_without_interpenetration(model):
    rng = np.random.default_rng(7)
    d = mujoco.MjData(model)
    for _ in range(300):
        q = {n: rng.uniform(*r) for n, (_, _, r, _, _) in JOINTS.items()} | DRAWN
        pose(model, d, q)
        assert not penetrations(model, d, ALLOWED), q


def test_interpenetration_check_can_fail(model):
    """Control: a lid forced below its range cuts into the bench front."""
    d = mujoco.MjData(model)
    pose(model, d, {"lid_joint": -0.03})
    found = penetrations(model, d)
    assert any(pair == {"lid", "bench_front"} for pair, _ in found), found


# ------------------------------------------------------------------ staying put


def test_at_rest_nothing_moves(model):
    d = mujoco.MjData(model)
    pose(model, d, {})
    start = box_corners(model, d)
    simulate(model, d, 5.0)
    drift = np.linalg.norm(box_corners(model, d) - start, axis=1).max()
    assert drift < 1e-3, drift
    assert d.ncon == 0


@pytest.mark.parametrize(
    "joint", sorted(set(JOINTS) - {"lid_joint"} - {c for c, _ in CATCHES.values()})
)
def test_mechanisms_stay_where_they_are_put(model, joint):
    """Set half open (and fully open): after 2 s each joint is within 1 mm (or 1 mrad).
    A latch is set with its catch where it drives it; a door with its catch drawn back."""
    lo, hi = JOINTS[joint][2]
    d = mujoco.MjData(model)
    adr = model.joint(joint).qposadr[0]
    for q in (0.5 * (lo + hi), hi):
        with_catch = DRAWN if joint.startswith("door_") else {}
        if joint in CATCHES:
            catch, released = CATCHES[joint]
            with_catch = {catch: 0.045 * q / released}
        pose(model, d, {joint: q} | with_catch)
        trace = simulate(model, d, 2.0, adr)
        assert np.abs(trace - q).max() < 1e-3, (joint, q, trace[-1])


# ------------------------------------------------------------------ meshes


def test_mesh_script_is_deterministic_and_matches_checked_in_files(tmp_path):
    first = run_mesh_script(SCRIPT, tmp_path / "a")
    second = run_mesh_script(SCRIPT, tmp_path / "b")
    assert sorted(first) == sorted(MESH_FILES)
    assert first == second
    for name, data in first.items():
        assert data[:80] == b"\0" * 80, name  # binary STL with a zero header
        assert (MESHES / name).read_bytes() == data, f"{name}: rerun {SCRIPT.name}"


def test_meshes_agree_with_the_collision_boxes(model):
    d = mujoco.MjData(model)
    pose(model, d, {})
    for body, mesh in (
        ("stowage_unit", "base_frame.stl"),
        ("tower", "tower_shell.stl"),
    ):
        assert collision_bounds(model, d, body) == pytest.approx(
            mesh_bounds(MESHES / mesh), abs=1e-6
        )
    lo, hi = collision_bounds(model, d, "seat_bin")
    bin_lo, bin_hi = mesh_bounds(MESHES / "seat_bin.stl")
    assert hi == pytest.approx(bin_hi, abs=1e-6)
    assert lo[:2] == pytest.approx(bin_lo[:2], abs=1e-6)  # the cleats reach lower
    # the tray walls: the drawer's collision boxes behind its front panel
    tray = mesh_bounds(MESHES / "drawer_tray.stl")
    b = model.body("drawer_left").id
    boxes = [
        (d.geom_xpos[g] - d.xpos[b], model.geom_size[g])
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == b
        and model.geom_contype[g]
        and (d.geom_xpos[g] - d.xpos[b])[0] < 0
    ]
    lo = np.min([p - s for p, s in boxes], axis=0)
    hi = np.max([p + s for p, s in boxes], axis=0)
    assert np.array([lo, hi]) == pytest.approx(tray, abs=1e-6)
    # volumes: the bin mesh is exactly its five walls
    assert mesh_volume(MESHES / "seat_bin.stl") == pytest.approx(
        0.62 * 0.57 * 0.33 - 0.60 * 0.55 * 0.32, rel=1e-5
    )
