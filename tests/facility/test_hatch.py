"""The pressurized hatch mockup (facility/mockups/hatch): both variants
(4060 and 4040) convert, have the mechanisms of the facts with their ranges
and dynamics, never interpenetrate over their ranges, stay put undriven, and
the door swings open when pushed and stops at its limit."""

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

SOURCE = ROOT / "facility" / "mockups" / "hatch" / "urdf" / "hatch.urdf.xacro"
MESHES = ROOT / "meshes" / "hatch"
SCRIPT = MESHES / "make_hatch.py"
VARIANTS = {"4060": (3.0, 3.0), "4040": (0.5, 0.2)}  # door damping, friction (facts)
# the door's hinge point (the door's frame, at its mid-height) and the door and frame masses:
# 4060 the facts'; 4040 derived (hatch.xacro: its 40 x 40 in opening centred 0.705 m up,
# masses the 4060's scaled by area)
HINGE = {"4060": (0.678, 0.057, 0.716), "4040": (0.678, 0.057, 0.705)}
MASSES = {"4060": (18.65, 7.38), "4040": (20.5, 5.79)}
BOLT_OUT = 0.035  # the latch joint drawn back: the bolt clear of the keeper
# the bolt drawn back as a full turn of the wheels leaves it (their joint equalities)
UNLATCHED = {"latch_joint": BOLT_OUT, "outer_wheel_joint": 2 * math.pi, "inner_wheel_joint": 2 * math.pi}
ALUMINIUM = 2700.0  # materials.xacro: aluminium and anodized


@pytest.fixture(scope="module", params=sorted(VARIANTS))
def hatch(request, tmp_path_factory):
    variant = request.param
    out = tmp_path_factory.mktemp(f"hatch_{variant}") / "hatch.xml"
    m, report = convert(SOURCE, out, variant=variant)
    return variant, f"hatch_{variant}_", m, report


def test_converts_cleanly_with_primitive_collisions(hatch):
    variant, p, m, report = hatch
    assert not report.warnings, [n.message for n in report.warnings]
    assert not report.decomposed and not report.cached, "collision is primitives only"
    bodies = {m.body(b).name for b in range(1, m.nbody)}
    assert bodies == {
        p + n
        for n in (
            "frame",
            "door",
            "latch",
            "outer_wheel",
            "outer_wheel_handle",
            "inner_wheel",
            "inner_wheel_handle",
            "outer_grab_handle",
            "inner_grab_handle",
        )
    }


def test_joints_types_ranges_and_dynamics(hatch):
    variant, p, m, _ = hatch
    damping, friction = VARIANTS[variant]
    table = joints(m)
    expected = {
        "door_joint": ("revolute", (0.0, 1.658), (0, 0, 1), damping, friction),
        "latch_joint": ("prismatic", (0.0, 0.035), (0, 1, 0), 5.0, 2.0),
        "outer_wheel_joint": ("revolute", (0.0, 2 * math.pi), (0, 0, 1), 0.5, 0.5),
        "inner_wheel_joint": ("revolute", (0.0, 2 * math.pi), (0, 0, 1), 0.5, 0.5),
        "outer_wheel_handle_joint": ("revolute", (0.0, math.pi / 2), (0, 1, 0), 0.02, 0.15),
        "inner_wheel_handle_joint": ("revolute", (0.0, math.pi / 2), (0, 1, 0), 0.02, 0.15),
    }
    assert set(table) == {p + n for n in expected}, "grab handles and the mount are fixed"
    for name, (kind, rng, axis, damp, fric) in expected.items():
        j = table[p + name]
        assert j.type == kind, name
        assert j.range == pytest.approx(rng), name
        assert j.axis == pytest.approx(axis), name
        assert (j.damping, j.frictionloss) == pytest.approx((damp, fric)), name
        assert j.damping > 0 and j.frictionloss > 0, f"{name} must hold still when not driven"


def test_door_hinge_is_the_facts_vertical_axis_and_opens_outwards(hatch):
    variant, p, m, _ = hatch
    d = home(m)
    door = m.body(p + "door").id
    assert d.xpos[door] == pytest.approx(HINGE[variant], abs=1e-9)
    assert d.xmat[door].reshape(3, 3) @ m.joint(p + "door_joint").axis == pytest.approx([0, 0, 1])
    plate_closed = d.xipos[door].copy()
    pose(m, d, {p + "door_joint": math.pi / 2} | {p + k: v for k, v in UNLATCHED.items()})
    # the door swings out of the bulkhead's front face (+x), away from the opening
    assert d.xipos[door][0] - plate_closed[0] > 0.4
    assert d.xipos[door][1] > plate_closed[1] + 0.4


def test_known_masses_and_density_masses(hatch):
    variant, p, m, _ = hatch
    assert m.body(p + "door").mass[0] == pytest.approx(MASSES[variant][0])
    assert m.body(p + "frame").mass[0] == pytest.approx(MASSES[variant][1])
    wheel = ALUMINIUM * mesh_volume(MESHES / "crank_wheel.stl")
    for side in ("outer", "inner"):
        # the mesh adds the handle's pivot boss; the link's mass is rim, spokes, hub and axle
        assert m.body(p + f"{side}_wheel").mass[0] == pytest.approx(wheel, rel=0.03)


def test_meshes_agree_with_the_collision_primitives(hatch):
    variant, p, m, _ = hatch
    if variant != "4060":
        pytest.skip("hatch 4040 is drawn with its collision boxes (no meshes)")
    d = home(m)
    for body, mesh in (("frame", "hatch_frame.stl"), ("door", "hatch_door.stl")):
        assert collision_bounds(m, d, p + body) == pytest.approx(
            mesh_bounds(MESHES / mesh), abs=1e-3
        ), body
    # the frame's bounding box is the facts' 0.68 x 1.31 x 2.11 (plus the latch keeper in front)
    lo, hi = mesh_bounds(MESHES / "hatch_frame.stl")
    assert hi - lo == pytest.approx([0.747, 1.31, 2.11], abs=1e-6)


def test_4040_has_its_own_40_by_40_inch_opening(hatch):
    """The gap between the bulkhead's slabs (its collision boxes) is 1.016 x 1.016 m
    for hatch 4040, 0.90 x 1.00 m for the 4060; the door covers it."""
    variant, p, m, _ = hatch
    d = home(m)
    frame = m.body(p + "frame").id
    slabs = [
        (d.geom_xpos[g], m.geom_size[g])
        for g in range(m.ngeom)
        if m.geom_bodyid[g] == frame
        and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
        and m.geom_contype[g]
        and m.geom_size[g][0] == pytest.approx(0.025)  # the 50 mm bulkhead
    ]
    lo = [c - h for c, h in slabs]
    hi = [c + h for c, h in slabs]
    wide = [i for i, (a, b) in enumerate(zip(lo, hi, strict=True)) if b[2] - a[2] > 1.5]
    low = min((i for i in range(len(slabs)) if i not in wide), key=lambda i: lo[i][2])
    high = max((i for i in range(len(slabs)) if i not in wide), key=lambda i: hi[i][2])
    width = min(lo[i][1] for i in wide if lo[i][1] > -0.5) - max(hi[i][1] for i in wide if hi[i][1] < -0.5)
    height = lo[high][2] - hi[low][2]
    want = (1.016, 1.016) if variant == "4040" else (0.90, 1.00)
    assert (width, height) == pytest.approx(want, abs=1e-6)
    door = collision_bounds(m, d, p + "door")
    assert door[1][1] - door[0][1] > want[0] and door[1][2] - door[0][2] > want[1]


def test_every_joint_sweeps_its_range_without_interpenetration(hatch):
    _, p, m, _ = hatch
    table = joints(m)
    unlatched = {p + k: v for k, v in UNLATCHED.items()}
    for name in table:
        # the door with the bolt drawn back; every other part with the hatch as it rests
        fixed = unlatched if name == p + "door_joint" else None
        assert sweep(m, {name: span(m, name, 60)}, fixed=fixed) == [], name
    for side in ("outer", "inner"):
        wheel, handle = p + f"{side}_wheel_joint", p + f"{side}_wheel_handle_joint"
        assert sweep(m, {wheel: span(m, wheel, 37), handle: span(m, handle, 7)}) == [], side
    # the door with the wheels turned anywhere and their handles out, and the
    # latch bolt thrown with the door closed (it sits in the keeper, clear)
    grid = {
        p + "door_joint": span(m, p + "door_joint", 40),
        p + "outer_wheel_joint": np.linspace(0, 2 * math.pi, 9),
        p + "inner_wheel_joint": np.linspace(0, 2 * math.pi, 9),
    }
    handles_out = {
        p + "outer_wheel_handle_joint": math.pi / 2,
        p + "inner_wheel_handle_joint": math.pi / 2,
    }
    assert sweep(m, grid, fixed=handles_out | {p + "latch_joint": BOLT_OUT}) == []
    assert sweep(m, {p + "latch_joint": span(m, p + "latch_joint", 8)}, fixed=handles_out) == []


def test_thrown_latch_stops_the_door_in_the_keeper(hatch):
    _, p, m, _ = hatch
    d = home(m)
    pose(m, d, {})  # as it rests: wheels at 0, so the bolt is thrown
    assert d.qpos[m.joint(p + "latch_joint").qposadr[0]] == 0.0
    trace = push(m, d, p + "door_joint", 10.0, 2.0)
    assert trace.max() < 0.01, "the bolt in the keeper holds the door closed"
    touching = {
        frozenset((m.body(m.geom_bodyid[c.geom1]).name, m.body(m.geom_bodyid[c.geom2]).name))
        for c in d.contact[: d.ncon]
    }
    assert touching == {frozenset((p + "latch", p + "frame"))}, (
        "the intended contact: bolt on keeper"
    )
    assert penetrations(m, d) == []


@pytest.mark.parametrize("where", [0.0, 0.3, 0.5, 0.8, 1.0])
def test_undriven_hatch_stays_put(hatch, where):
    _, p, m, _ = hatch
    table = joints(m)
    d = home(m)
    pose(m, d, {n: j.range[0] + where * (j.range[1] - j.range[0]) for n, j in table.items()})
    assert rest_drift(m, d, 5.0) < 1e-3


def test_door_swings_open_when_pushed_and_stops_at_its_limit(hatch):
    variant, p, m, _ = hatch
    _, friction = VARIANTS[variant]
    door = p + "door_joint"
    d = home(m)
    # a push below the door's friction does not move it
    assert np.abs(push(m, d, door, 0.8 * friction, 1.0)).max() < 1e-3
    d = home(m)
    pose(m, d, {p + k: v for k, v in UNLATCHED.items()})  # the wheels have drawn the bolt
    trace = push(m, d, door, 10.0, 4.0)
    dt = m.opt.timestep
    reached = np.argmax(trace > 1.6) * dt
    assert 0.3 < reached < 3.0, "it swings, neither instantly nor never"
    assert np.all(np.diff(trace[: int(reached / dt)]) > 0), "opening all the way"
    assert trace.max() < 1.658 + 0.02, "the limit stops it"
    assert trace[-1] == pytest.approx(1.658, abs=2e-3), "and holds it there while pushed"
    assert rest_drift(m, d, 2.0) < 1e-3, "released, it stays open"
    assert penetrations(m, d) == []


def test_mesh_script_is_deterministic(tmp_path):
    first = run_mesh_script(SCRIPT, tmp_path / "a")
    second = run_mesh_script(SCRIPT, tmp_path / "b")
    assert set(first) == {"hatch_frame.stl", "hatch_door.stl", "crank_wheel.stl"}
    assert first == second
    for name, data in first.items():
        assert (MESHES / name).read_bytes() == data, (
            f"{name} is stale: run {SCRIPT.relative_to(ROOT)}"
        )
        assert data[:80] == b"\0" * 80
