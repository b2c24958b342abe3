"""Folding static fixture geoms into their weld bodies changes no contact and no motion.

The reference is the same recipe built without folding (``fold_fixtures=False``),
compiled by MuJoCo: every geom keeps its name, classes and world pose, contacts
at swept mockup poses are the same geom pairs, and the mockups pushed open move
through the same states. A small hand-written model checks the rules (what moves,
what stays) and the composed poses under rotated frames.
"""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
from lxml import etree

from tests.facility.test_collision_filtering import (
    home,
    mockup_joints,
    one_joint_at_a_time,
    pushed_open,
    touching,
)
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.fold import fold_fixtures
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.mjcf.document import mjcf_bytes
from urdf2mjcf.runner.load import load as load_facility

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> tuple[Path, Path]:
    """The default recipe built folded (as make-facility does) and unfolded."""
    base = tmp_path_factory.mktemp("fold")
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
    folded = build_facility(recipe, base / "folded", root=ROOT, components=False)
    plain = build_facility(recipe, base / "plain", root=ROOT, components=False, fold_fixtures=False)
    return folded.output, plain.output


def models(pair) -> tuple[mujoco.MjModel, mujoco.MjModel, dict]:
    folded, plain = pair
    manifest = json.loads((folded / "facility.json").read_text())
    return (
        mujoco.MjModel.from_xml_path(str(folded / "scene.xml")),
        mujoco.MjModel.from_xml_path(str(plain / "scene.xml")),
        manifest,
    )


def collidable_bodies(m: mujoco.MjModel) -> set[str]:
    return {m.body(b).name for b in range(1, m.nbody) if m.body_contype[b] or m.body_conaffinity[b]}


def test_geoms_keep_names_classes_and_world_poses(pair):
    m, ref, manifest = models(pair)
    folded = manifest["folded_geoms"]
    assert m.nbody == ref.nbody and m.nq == ref.nq
    # fixtures that took over their visual twin: drawn in the visual group, with its material
    merged = [
        g
        for g in range(m.ngeom)
        if m.geom_group[g] == 2 and m.geom_contype[g] | m.geom_conaffinity[g]
    ]
    assert len(merged) == ref.ngeom - m.ngeom > 30
    assert all(m.geom_matid[g] >= 0 for g in merged)
    assert [m.body(b).name for b in range(m.nbody)] == [ref.body(b).name for b in range(ref.nbody)]
    d, dr = mujoco.MjData(m), mujoco.MjData(ref)
    for model, data in ((m, d), (ref, dr)):
        mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
        mujoco.mj_forward(model, data)
    named = [ref.geom(g).name for g in range(ref.ngeom) if ref.geom(g).name]
    for name in named:
        g, r = m.geom(name).id, ref.geom(name).id
        assert (m.geom_contype[g], m.geom_conaffinity[g], m.geom_size[g].tolist()) == (
            ref.geom_contype[r],
            ref.geom_conaffinity[r],
            ref.geom_size[r].tolist(),
        )
        np.testing.assert_allclose(d.geom_xpos[g], dr.geom_xpos[r], atol=1e-12, err_msg=name)
        np.testing.assert_allclose(d.geom_xmat[g], dr.geom_xmat[r], atol=1e-12, err_msg=name)
        original = ref.body(ref.geom_bodyid[r]).name
        now = m.body(m.geom_bodyid[g]).name
        if name in folded:
            assert folded[name] == original != now
            # into the body it is welded to: the same weld, so MuJoCo filters the same pairs
            assert m.body_weldid[m.geom_bodyid[g]] == ref.body_weldid[ref.geom_bodyid[r]]
            assert m.geom_bodyid[g] != 0, "never into the world body"
        else:
            assert now == original, name
    # fixtures only: the robot and the bag (contype & conaffinity) keep theirs
    for name in folded:
        g = m.geom(name).id
        assert not (m.geom_contype[g] & m.geom_conaffinity[g]), name
    # what it is for: fewer bodies for the broad phase to bound and sweep
    assert len(collidable_bodies(m)) < len(collidable_bodies(ref)) - 10


def test_the_same_contacts_at_swept_mockup_poses(pair):
    m, ref, manifest = models(pair)
    d, dr = mujoco.MjData(m), mujoco.MjData(ref)
    names = mockup_joints(m, manifest)
    q0 = home(m)
    bag = m.joint(manifest["components"]["ctb"]["joints"][0]).qposadr[0]
    rng = np.random.default_rng(5)
    poses = one_joint_at_a_time(m, names, q0, 9)
    for _ in range(40):  # random combinations, some pushed a little past their ranges
        pose = q0.copy()
        for name in names:
            j = m.joint(name)
            lo, hi = j.range
            pose[j.qposadr[0]] = rng.uniform(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo))
        poses.append(pose)
    seen = 0
    for pose in poses:
        pose[bag + 2] -= 0.006  # the bag 1 mm into the floor
        found = touching(m, d, pose)
        assert found == touching(ref, dr, pose), pose
        seen += len(found)
    assert seen > len(poses)


def test_mockups_pushed_open_move_as_unfolded(pair):
    m, ref, manifest = models(pair)
    folded, plain = (pushed_open(model, manifest) for model in (m, ref))
    assert np.abs(folded[-1] - folded[0]).max() > 0.1, "the mockups moved"
    np.testing.assert_allclose(folded, plain, atol=1e-9)


def test_the_runner_reports_the_link_a_geom_was_described_on(pair):
    folded, _ = pair
    _, ref, manifest = models(pair)
    fac = load_facility(folded)
    m = fac.model
    assert manifest["folded_geoms"]
    for g in range(m.ngeom):
        name = m.geom(g).name
        if name:
            assert fac.link_of_geom(g) == ref.body(ref.geom_bodyid[ref.geom(name).id]).name


def test_cameras_see_the_same_pictures(pair):
    """The merged fixtures are drawn as their visual twins were: every camera of the
    scene and a free view over the facility give the same image (a handful of pixels
    at coincident faces aside)."""
    m, ref, _ = models(pair)
    images = []
    for model in (m, ref):
        d = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
        mujoco.mj_forward(model, d)
        shots = []
        with mujoco.Renderer(model, 240, 320) as renderer:
            free = mujoco.MjvCamera()
            free.lookat[:], free.distance, free.azimuth, free.elevation = [0, 1, 0.8], 5, 120, -25
            for camera in [*range(model.ncam), free]:
                renderer.update_scene(d, camera=camera)
                shots.append(renderer.render().astype(int))
        images.append(shots)
    for ours, theirs in zip(*images, strict=True):
        differ = np.abs(ours - theirs).max(axis=2) > 0
        assert differ.mean() < 1e-3, differ.mean()


# ------------------------------------------------------------------ the rules, by hand

SMALL = """<mujoco>
  <default>
    <default class="visual"><geom contype="0" conaffinity="0" group="2"/></default>
    <default class="collision"><geom contype="2" conaffinity="1" group="3"/></default>
  </default>
  <asset><material name="oak" rgba="0.6 0.4 0.2 1"/></asset>
  <worldbody>
    <body name="root" pos="1 2 0" quat="0.9238795 0 0 0.3826834">
      <geom class="visual" type="box" size="0.1 0.1 0.1" material="oak"/>
      <geom name="root_box" class="collision" type="box" size="0.1 0.1 0.1"/>
      <body name="panel" pos="0.3 0 0.2" quat="0.7071068 0.7071068 0 0">
        <geom class="visual" type="box" size="0.2 0.1 0.05" pos="0 0.1 0" quat="0.9659258 0 0.258819 0" rgba="1 0 0 1"/>
        <geom name="panel_box" class="collision" type="box" size="0.2 0.1 0.05" pos="0 0.1 0" quat="0.9659258 0 0.258819 0"/>
        <geom class="visual" type="box" size="0.2 0.1 0.06" material="oak"/>
        <body name="post" pos="0 0.5 0">
          <geom name="post_box" class="collision" type="box" size="0.02 0.02 0.3"/>
        </body>
      </body>
      <body name="door" pos="0 -0.5 0">
        <joint name="hinge" axis="0 0 1"/>
        <geom name="door_box" class="collision" type="box" size="0.3 0.02 0.4" mass="1"/>
        <body name="handle" pos="0.2 -0.05 0" euler="0 0 0.3">
          <geom name="handle_box" class="collision" type="box" size="0.01 0.03 0.1"/>
        </body>
        <body name="knob" pos="-0.2 -0.05 0">
          <geom name="knob_box" class="collision" type="box" size="0.02 0.02 0.02"/>
        </body>
      </body>
      <body name="arm_mount" pos="0 0 0.5">
        <geom class="visual" type="box" size="0.05 0.05 0.05"/>
        <geom name="mount_box" type="box" size="0.05 0.05 0.05"/>
      </body>
      <body name="kept" pos="0 0 -0.3">
        <geom name="kept_box" class="collision" type="box" size="0.05 0.05 0.05"/>
      </body>
    </body>
    <body name="probe" pos="5 5 1">
      <freejoint/>
      <geom name="probe_box" type="box" size="0.05 0.05 0.05" mass="1"/>
    </body>
  </worldbody>
  <contact><exclude body1="kept" body2="probe"/></contact>
</mujoco>
"""


def _fold_file(path, m):
    """Fold the document in ``path`` (compiled as ``m``) and write it back, as the build
    writes its scene: by our one writer."""
    root = etree.fromstring(path.read_bytes())
    folded = fold_fixtures(root, m)
    path.write_bytes(mjcf_bytes(root))
    return folded


def test_what_moves_and_where(tmp_path):
    scene = tmp_path / "scene.xml"
    scene.write_text(SMALL)
    before = mujoco.MjModel.from_xml_path(str(scene))
    folded = _fold_file(scene, before)
    after = mujoco.MjModel.from_xml_path(str(scene))
    # panel and post into root (no joint between), knob into the door (its weld body);
    # the handle's frame is given by euler (not composed here), the mount collides with
    # everything (contype 1 & conaffinity 1), 'kept' is named by an exclude, the root's own
    # geom is on a body standing on the world, and nothing goes into the world body
    assert folded.moved == {"panel_box": "panel", "post_box": "post", "knob_box": "knob"}
    # a fixture with a visual twin (same shape, same pose) takes over its look; the
    # panel's other visual (another size) and the robot-like mount's twin stay
    assert folded.merged == ["root_box", "panel_box"]
    assert after.ngeom == before.ngeom - 2
    root_box, panel_box = after.geom("root_box"), after.geom("panel_box")
    assert root_box.group[0] == panel_box.group[0] == 2
    assert after.material(root_box.matid[0]).name == "oak"
    np.testing.assert_allclose(panel_box.rgba, [1, 0, 0, 1])
    owner = {after.geom(g).name: after.body(after.geom_bodyid[g]).name for g in range(after.ngeom)}
    assert owner["panel_box"] == owner["post_box"] == "root"
    assert owner["knob_box"] == "door"
    for stays in ("root_box", "handle_box", "mount_box", "kept_box", "probe_box"):
        if stays in owner:
            assert owner[stays] == before.body(before.geom(stays).bodyid[0]).name, stays
    visuals = [g for g in range(after.ngeom) if not after.geom(g).name]
    assert [after.body(after.geom_bodyid[g]).name for g in visuals] == ["panel", "arm_mount"]
    d0, d1 = mujoco.MjData(before), mujoco.MjData(after)
    for q in (0.0, 0.7, -2.0):
        for model, data in ((before, d0), (after, d1)):
            data.qpos[model.joint("hinge").qposadr[0]] = q
            mujoco.mj_kinematics(model, data)
        for g in range(before.ngeom):
            name = before.geom(g).name
            if name:
                h = after.geom(name).id
                np.testing.assert_allclose(d1.geom_xpos[h], d0.geom_xpos[g], atol=1e-12)
                np.testing.assert_allclose(d1.geom_xmat[h], d0.geom_xmat[g], atol=1e-12)
    # the file is rewritten deterministically: folding a fresh copy gives the same bytes
    again = tmp_path / "again.xml"
    again.write_text(SMALL)
    _fold_file(again, before)
    assert again.read_bytes() == scene.read_bytes()
    # folding what is folded moves nothing
    again_folded = _fold_file(scene, after)
    assert again_folded.moved == {} and again_folded.merged == []
