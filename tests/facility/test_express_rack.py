"""The EXPRESS rack mockup with the MERLIN freezer in its bay
(facility/mockups/express_rack): converts, the rack's mass is its solid's,
the freezer sits in its bay where the facts put it, and the freezer's door,
latch pulls and latch lock move through their ranges without
interpenetration and stay put undriven."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from .mechanism_checks import (
    ROOT,
    collision_bounds,
    convert,
    home,
    joints,
    mesh_bounds,
    mesh_volume,
    penetrations,
    pose,
    push,
    rest_drift,
    run_mesh_script,
    span,
    sweep,
)

SOURCE = ROOT / "facility" / "mockups" / "express_rack" / "urdf" / "express_rack.urdf.xacro"
MESHES = ROOT / "meshes" / "express_rack"
SCRIPT = MESHES / "make_express_rack.py"
P = "express_rack_"
F = "express_rack_merlin_"
ALUMINIUM, PANEL = 2700.0, 1050.0  # materials.xacro
BOLT_OUT = 0.025  # the bolt drawn back (the lock up, pi/2): clear of the keeper's lip
UNLOCKED = {F + "latch_lock_joint": math.pi / 2, F + "bolt_joint": BOLT_OUT}
KEEPER_FRONT = 0.054  # the keeper's lip stands this far in front of the body (x)


@pytest.fixture(scope="module")
def rack(tmp_path_factory):
    return convert(SOURCE, tmp_path_factory.mktemp("express_rack") / "express_rack.xml")


def test_converts_cleanly_with_primitive_collisions(rack):
    m, report = rack
    assert not report.warnings, [n.message for n in report.warnings]
    assert not report.decomposed and not report.cached, "collision is primitives only"
    assert {m.body(b).name for b in range(1, m.nbody)} == {
        P + "rack",
        F + "body",
        F + "door",
        F + "latch_pull_upper",
        F + "latch_pull_lower",
        F + "latch_lock",
        F + "bolt",
    }


def test_rack_is_fixed_and_freezer_joints_match_the_facts(rack):
    m, _ = rack
    table = joints(m)
    expected = {
        "door_joint": ("revolute", (-math.pi / 2, 0.0), (0, 0, 1)),
        "latch_pull_upper_joint": ("prismatic", (-0.0084, 0.0084), (0, 0, 1)),
        "latch_pull_lower_joint": ("prismatic", (-0.0084, 0.0084), (0, 0, 1)),
        "latch_lock_joint": ("revolute", (0.0, math.pi / 2), (-1, 0, 0)),
        "bolt_joint": ("prismatic", (0.0, BOLT_OUT), (0, -1, 0)),  # driven by the lock
    }
    assert set(table) == {F + n for n in expected}, "the rack and the freezer body are fixed"
    for name, (kind, rng, axis) in expected.items():
        j = table[F + name]
        assert (j.type, j.range, j.axis) == (kind, pytest.approx(rng), pytest.approx(axis)), name
        if name != "bolt_joint":  # the bolt is held by its coupling to the lock
            assert j.damping > 0 and j.frictionloss > 0, f"{name} must hold still when not driven"


def test_masses_come_from_the_solids(rack):
    m, _ = rack
    assert m.body(P + "rack").mass[0] == pytest.approx(
        ALUMINIUM * mesh_volume(MESHES / "express_rack.stl"), rel=1e-6
    )
    assert 400 < m.body(P + "rack").mass[0] < 600
    assert m.body(F + "body").mass[0] == pytest.approx(
        ALUMINIUM * mesh_volume(MESHES / "merlin_body.stl"), rel=1e-6
    )
    assert m.body(F + "door").mass[0] == pytest.approx(PANEL * 0.018 * 0.41 * 0.23)


def test_meshes_agree_with_the_collision_primitives(rack):
    m, _ = rack
    d = home(m)
    for body, mesh in (
        (P + "rack", "express_rack.stl"),
        (F + "body", "merlin_body.stl"),
        (F + "door", "merlin_door.stl"),
    ):
        want = mesh_bounds(MESHES / mesh).copy()
        if body == F + "body":  # plus the lock's keeper, standing in front of the face
            want[1][0] = KEEPER_FRONT
        assert collision_bounds(m, d, body) == pytest.approx(want, abs=1e-3), body
    lo, hi = mesh_bounds(MESHES / "express_rack.stl")
    assert hi - lo == pytest.approx([0.86, 1.05, 2.0])  # deep, wide, tall
    lo, hi = mesh_bounds(MESHES / "merlin_body.stl")
    assert hi - lo == pytest.approx([0.52, 0.44, 0.26])  # a mid-deck locker


def test_freezer_sits_in_its_bay_clear_of_the_rack(rack):
    m, _ = rack
    d = home(m)
    body = m.body(F + "body").id
    assert d.xpos[body] == pytest.approx([0.0, -0.229, 1.067])
    mine = [g for g in range(m.ngeom) if m.geom_bodyid[g] == body and m.geom_contype[g]]
    for g in range(m.ngeom):
        if m.geom_bodyid[g] == m.body(P + "rack").id and m.geom_contype[g]:
            for f in mine:  # the shell and the keeper
                gap = mujoco.mj_geomDistance(m, d, f, g, 0.05, None)
                assert gap > 0.0015, f"freezer against rack geom {m.geom(g).name}: {gap}"
    # its front (the shell, its first box) is flush with the rack's front
    shell = mine[0]
    assert d.geom_xpos[shell][0] + m.geom_size[shell][0] == pytest.approx(0.0)


def test_facility_pose_puts_the_freezer_where_the_facts_do(tmp_path):
    # The facts: rack frame at (0.508, 1.168, 0.984) rpy (pi/2, 0, 0) (y up),
    # freezer at (-0.229, 0.083, 0) in it: world (0.279, 1.168, 1.067). Our
    # z-up rack on the floor below that, turned to face -y (yaw -pi/2), agrees.
    src = tmp_path / "placed.urdf.xacro"
    src.write_text(
        '<robot name="placed" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:include filename="$(find express_rack)/urdf/express_rack.xacro"/><xacro:material_colors/>'
        '<link name="world"/><xacro:express_rack prefix="" parent="world">'
        '<origin xyz="0.508 1.168 0" rpy="0 0 ${-pi / 2}"/></xacro:express_rack></robot>'
    )
    m, _ = convert(src, tmp_path / "out" / "placed.xml")
    d = home(m)
    assert d.xpos[m.body("merlin_body").id] == pytest.approx([0.279, 1.168, 1.067], abs=1e-9)
    assert d.xmat[m.body("merlin_body").id].reshape(3, 3)[:, 0] == pytest.approx(
        [0, -1, 0], abs=1e-12
    ), "front faces -y"


def test_every_joint_sweeps_its_range_without_interpenetration(rack):
    m, _ = rack
    table = joints(m)
    for name in table:
        # the door with its bolt drawn back; the rest as the freezer rests (door shut)
        fixed = UNLOCKED if name == F + "door_joint" else None
        assert sweep(m, {name: span(m, name, 60)}, fixed=fixed) == [], name
    # every combination: the door anywhere with the pulls and the lever anywhere, the
    # bolt drawn back (thrown, it stops the door: test_mechanisms.py)
    grid = {name: span(m, name, 9) for name in table if name != F + "bolt_joint"}
    assert sweep(m, grid, fixed={F + "bolt_joint": BOLT_OUT}) == []


@pytest.mark.parametrize("where", [0.0, 0.3, 0.5, 0.8, 1.0])
def test_undriven_freezer_stays_put(rack, where):
    m, _ = rack
    d = home(m)
    pose(m, d, {n: j.range[0] + where * (j.range[1] - j.range[0]) for n, j in joints(m).items()})
    assert rest_drift(m, d, 5.0) < 1e-3


@pytest.mark.parametrize(
    "joint, effort",
    [
        ("door_joint", 1.0),
        ("latch_pull_upper_joint", 2.0),
        ("latch_pull_lower_joint", 2.0),
        ("latch_lock_joint", 0.1),
    ],
)
def test_door_and_latches_move_through_their_ranges_when_driven(rack, joint, effort):
    m, _ = rack
    name = F + joint
    lo, hi = m.joint(name).range
    d = home(m)
    if joint == "door_joint":
        pose(m, d, UNLOCKED)  # the lever up: the bolt is out of the keeper
    for target, sign in ((lo, -1), (hi, 1), (lo, -1)):
        trace = push(m, d, name, sign * effort, 1.5)
        assert trace[-1] == pytest.approx(target, abs=0.02 * (hi - lo)), f"{joint} reaches {target}"
        assert penetrations(m, d) == []
        assert rest_drift(m, d, 0.5) < 1e-3, f"{joint} stays at {target} when let go"
    # below the friction it does not move
    start = d.qpos[m.joint(name).qposadr[0]]
    trace = push(m, d, name, 0.5 * m.dof_frictionloss[m.joint(name).dofadr[0]], 0.5)
    assert np.abs(trace - start).max() < 1e-3 * (hi - lo)


def test_mesh_script_is_deterministic(tmp_path):
    first = run_mesh_script(SCRIPT, tmp_path / "a")
    second = run_mesh_script(SCRIPT, tmp_path / "b")
    assert set(first) == {"express_rack.stl", "merlin_body.stl", "merlin_door.stl"}
    assert first == second
    for name, data in first.items():
        assert (MESHES / name).read_bytes() == data, (
            f"{name} is stale: run {SCRIPT.relative_to(ROOT)}"
        )
        assert data[:80] == b"\0" * 80
