"""Collision filtering in the facility keeps every contact that can happen.

`make-facility` makes every collision geom a fixture (contype 2, conaffinity 1)
unless its description marks it as colliding with everything (contype 1,
conaffinity 1, MuJoCo's default): the robot, the CTB and the hatch's latch bolt.
Fixtures touch marked geoms, never each other. The reference is MuJoCo itself:
the same compiled facility with every fixture put back in MuJoCo's default class
(the model as it was before filtering), compared contact for contact at swept
poses and step for step in simulation."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]
RECIPES = sorted((ROOT / "recipes").glob("imetro*.yaml"))
FIXTURE = (2, 1)
EVERYTHING = (1, 1)


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> dict[str, Path]:
    """Each iMETRO recipe, built once."""
    base = tmp_path_factory.mktemp("filtered")
    out = {}
    for path in RECIPES:
        recipe = load_recipe(path)
        out[path.stem] = build_facility(recipe, base / recipe.name, root=ROOT).output
    return out


def load(folder: Path) -> tuple[mujoco.MjModel, mujoco.MjModel, dict]:
    """The facility as built, its unfiltered twin, and the manifest."""
    scene = folder / "scene.xml"
    spec = mujoco.MjSpec.from_file(str(scene))
    for g in spec.geoms:
        if (g.contype, g.conaffinity) == FIXTURE:
            g.contype, g.conaffinity = EVERYTHING
    twin = spec.compile()
    model = mujoco.MjModel.from_xml_path(str(scene))
    assert twin.ngeom == model.ngeom and twin.nq == model.nq
    return model, twin, json.loads((folder / "facility.json").read_text())


def classes(m: mujoco.MjModel, g: int) -> tuple[int, int]:
    return int(m.geom_contype[g]), int(m.geom_conaffinity[g])


def collides(m: mujoco.MjModel, g1: int, g2: int) -> bool:
    """MuJoCo's bitmask rule (bodies welded together aside)."""
    return bool(
        m.geom_contype[g1] & m.geom_conaffinity[g2] or m.geom_contype[g2] & m.geom_conaffinity[g1]
    )


def subtree(m: mujoco.MjModel, joint: str) -> set[int]:
    """Every body of the kinematic tree holding ``joint``."""
    root = m.body_rootid[m.jnt_bodyid[m.joint(joint).id]]
    return {b for b in range(m.nbody) if m.body_rootid[b] == root}


def colliding_geoms(m: mujoco.MjModel, bodies: set[int] | None = None) -> list[int]:
    return [
        g
        for g in range(m.ngeom)
        if (m.geom_contype[g] or m.geom_conaffinity[g])
        and (bodies is None or m.geom_bodyid[g] in bodies)
    ]


def excluded(m: mujoco.MjModel) -> set[frozenset[int]]:
    return {frozenset((int(s) >> 16, int(s) & 0xFFFF)) for s in m.exclude_signature}


def touching(m: mujoco.MjModel, d: mujoco.MjData, qpos: np.ndarray) -> set[tuple[str, str]]:
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    found = set()
    for c in d.contact[: d.ncon]:
        a, b = sorted(
            (m.geom(c.geom[0]).name or str(c.geom[0]), m.geom(c.geom[1]).name or str(c.geom[1]))
        )
        found.add((a, b))
    return found


def mockup_joints(m: mujoco.MjModel, manifest: dict) -> list[str]:
    return [
        j
        for name, comp in manifest["components"].items()
        if name not in ("robot", "ctb")
        for j in comp.get("joints", [])
    ]


def home(m: mujoco.MjModel) -> np.ndarray:
    return m.key("home").qpos.copy()


def one_joint_at_a_time(
    m: mujoco.MjModel, names: list[str], q0: np.ndarray, samples: int
) -> list[np.ndarray]:
    """``q0`` with each joint of ``names`` in turn at ``samples`` points across its range."""
    poses = []
    for name in names:
        j = m.joint(name)
        for q in np.linspace(*j.range, samples):
            pose = q0.copy()
            pose[j.qposadr[0]] = q
            poses.append(pose)
    return poses


def pushed_open(model: mujoco.MjModel, manifest: dict, steps: int = 1500) -> np.ndarray:
    """qpos after each step with every mockup joint pushed towards its upper limit
    (twice its friction, plus 0.1) and the lid let go at 92 deg, the robot at home."""
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
    d.qpos[model.joint("trainer_lid_joint").qposadr[0]] = math.radians(92)
    trace = []
    for _ in range(steps):
        for name in mockup_joints(model, manifest):
            j = model.joint(name)
            d.qfrc_applied[j.dofadr[0]] = 2.0 * model.dof_frictionloss[j.dofadr[0]] + 0.1
        mujoco.mj_step(model, d)
        trace.append(d.qpos.copy())
    return np.array(trace)


# ------------------------------------------------------------------ the classes


@pytest.mark.parametrize("recipe", [p.stem for p in RECIPES])
def test_robot_and_bag_collide_with_every_geom_and_mockups_are_fixtures(built, recipe):
    m, _, manifest = load(built[recipe])
    agents: set[int] = set()
    if "robot" in manifest["components"]:
        robot = subtree(m, manifest["components"]["robot"]["roles"]["joints"][0])
        agents |= robot
        assert len(colliding_geoms(m, robot)) == 36
    bag = subtree(m, manifest["components"]["ctb"]["joints"][0])
    agents |= bag
    everything = colliding_geoms(m)
    for g in colliding_geoms(m, agents):
        assert classes(m, g) == EVERYTHING, m.geom(g).name
        for h in everything:
            assert collides(m, g, h), (m.geom(g).name, m.geom(h).name)
    # every exclude is the robot's own (its nested lift stages, its carriage on the rail)
    for pair in excluded(m):
        assert pair <= agents, [m.body(b).name for b in pair]
    # the hatches' latch bolts (their bodies: <prefix>latch, e.g. hatch_4060_latch)
    bolts = {
        c["prefix"] + "latch" for n, c in manifest["components"].items() if n.startswith("hatch")
    }
    latches = {g for g in everything if m.body(m.geom_bodyid[g]).name in bolts}
    for g in set(everything) - set(colliding_geoms(m, agents)):
        assert classes(m, g) == (EVERYTHING if g in latches else FIXTURE), m.geom(g).name
    assert not any(
        collides(m, g, h)
        for g in everything
        for h in everything
        if classes(m, g) == classes(m, h) == FIXTURE
    )


def test_assets_compiled_on_their_own_keep_every_contact(built):
    """components/ (and the mechanism tests, which compile the same sources) see
    every geom in MuJoCo's default class: parts of one mockup still collide."""
    folder = built["imetro"]
    files = sorted((folder / "components").glob("*/*.xml"))
    files = [f for f in files if f.name != "scene.xml"]
    assert {f.stem for f in files} == {
        "ctb",
        "express_rack",
        "hatch",
        "imetro_robot",
        "stowage_unit",
    }
    for f in files:
        m = mujoco.MjModel.from_xml_path(str(f))
        geoms = colliding_geoms(m)
        assert geoms, f
        assert all(classes(m, g) == EVERYTHING for g in geoms), f


# ------------------------------------------------------------------ same contacts


@pytest.mark.parametrize("recipe", [p.stem for p in RECIPES])
def test_every_mockup_joint_through_its_range_finds_the_same_contacts(built, recipe):
    m, twin, manifest = load(built[recipe])
    d, dt = mujoco.MjData(m), mujoco.MjData(twin)
    q0 = home(m)
    names = mockup_joints(m, manifest)
    poses = one_joint_at_a_time(m, names, q0, 13)
    # everything at one end, then random combinations
    rng = np.random.default_rng(3)
    for where in [0.0, 1.0] + list(rng.uniform(size=60)):
        pose = q0.copy()
        for name in names:
            j = m.joint(name)
            lo, hi = j.range
            pose[j.qposadr[0]] = lo + (hi - lo) * (where if where in (0.0, 1.0) else rng.uniform())
        poses.append(pose)
    bag = m.joint(manifest["components"]["ctb"]["joints"][0]).qposadr[0]
    for pose in poses:
        pose[bag + 2] -= 0.006  # the bag 1 mm into the floor: a contact both must find
        found = touching(m, d, pose)
        assert found == touching(twin, dt, pose), pose
        assert any(name.startswith("floor") for pair in found for name in pair), found


def test_a_part_pushed_out_of_its_range_shows_what_filtering_drops(built):
    """Control: the lid 0.03 rad below its range cuts into the bench front; only
    the unfiltered twin sees it (fixtures never touch each other)."""
    m, twin, _ = load(built["imetro"])
    pose = home(m)
    pose[m.joint("trainer_lid_joint").qposadr[0]] = -0.03
    lost = touching(twin, mujoco.MjData(twin), pose) - touching(m, mujoco.MjData(m), pose)
    assert lost and all(a.startswith("trainer_") and b.startswith("trainer_") for a, b in lost), (
        lost
    )


def test_thrown_latch_stops_the_hatch_door_in_the_facility(built):
    """The one contact within a mockup that is its mechanism: bolt on keeper."""
    m, _, _ = load(built["imetro"])
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    d.qpos[m.joint("hatch_4060_latch_joint").qposadr[0]] = 0.035
    d.ctrl[:] = m.key("home").ctrl
    door = m.joint("hatch_4060_door_joint")
    pairs = set()
    for _ in range(1000):
        d.qfrc_applied[door.dofadr[0]] = 10.0
        mujoco.mj_step(m, d)
        for c in d.contact[: d.ncon]:
            pairs.add(frozenset(m.body(m.geom_bodyid[g]).name for g in c.geom))
    assert d.qpos[door.qposadr[0]] < 0.01, "the bolt in the keeper holds the door closed"
    assert frozenset(("hatch_4060_latch", "hatch_4060_frame")) in pairs


def test_bag_touches_floor_bin_and_finger_pads(built):
    m, _, _ = load(built["imetro"])
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    bag = m.joint("ctb_joint").qposadr[0]

    folded = json.loads((built["imetro"] / "facility.json").read_text()).get("folded_geoms", {})

    def link(g: int) -> str:  # the link a geom was described on (static fixtures are folded)
        return folded.get(m.geom(g).name) or m.body(m.geom_bodyid[g]).name

    def bodies_touching_bag() -> set[str]:
        out = set()
        for c in d.contact[: d.ncon]:
            names = {link(g) for g in c.geom}
            if "ctb" in names:
                out |= names - {"ctb"}
        return out

    for _ in range(250):  # it starts 5 mm up
        mujoco.mj_step(m, d)
    assert bodies_touching_bag() == {"floor"}
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    # lying in the seat bin (its frame: the inner floor's centre), 2 mm up: it settles on the bin
    seat_bin = m.body("trainer_seat_bin").id
    d.qpos[bag : bag + 3] = d.xpos[seat_bin] + [0.0, 0.0, 0.002]
    d.qpos[bag + 3 : bag + 7] = d.xquat[seat_bin]
    for _ in range(250):
        mujoco.mj_step(m, d)
    assert "trainer_seat_bin" in bodies_touching_bag()
    # the strap where a finger pad is: they touch
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    pad = d.geom_xpos[m.geom("finger_1_pad").id]
    strap = m.geom("ctb_collision_1")
    d.qpos[bag : bag + 3] += pad - d.geom_xpos[strap.id]
    mujoco.mj_forward(m, d)
    assert "finger_1_link" in bodies_touching_bag()


# ------------------------------------------------------------------ same simulation


def test_mockups_pushed_open_simulate_exactly_as_unfiltered(built):
    """Every mockup joint pushed towards its upper limit (twice its friction, plus
    the lid let go at 92 deg as the demo does), the robot holding home: the
    filtered facility and its unfiltered twin step through identical states."""
    m, twin, manifest = load(built["imetro"])
    filtered, unfiltered = (pushed_open(model, manifest) for model in (m, twin))
    moved = np.abs(filtered[-1] - filtered[0]).max()
    assert moved > 0.1, "the mockups moved"
    np.testing.assert_array_equal(filtered, unfiltered)
