"""Every recipe builds into a facility that simulates correctly: the robot
holds its pose under its controllers, static mockups stay put, the CTB
settles upright, every mockup joint moves through its range without
interpenetration, and builds are reproducible."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from lxml import etree

from tests.facility.mechanism_checks import marker_points, penetrations
from tests.same_model import differences
from urdf2mjcf.facility.build import FacilityReport, build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]
# The iMETRO recipes (MIRA3D's worlds have their own tests: test_mira3d.py).
RECIPES = sorted((ROOT / "recipes").glob("imetro*.yaml"))


@pytest.fixture(scope="module")
def reports(tmp_path_factory) -> dict[str, FacilityReport]:
    """Each shipped recipe, built once."""
    out = {}
    base = tmp_path_factory.mktemp("facilities")
    for path in RECIPES:
        recipe = load_recipe(path)
        out[path.stem] = build_facility(recipe, base / recipe.name, root=ROOT)
    return out


@pytest.fixture(scope="module")
def built(reports) -> dict[str, Path]:
    return {name: report.output for name, report in reports.items()}


@pytest.mark.parametrize("recipe", [p.stem for p in RECIPES])
def test_what_is_written_is_what_was_validated(reports, recipe):
    """The scene.xml on disk, compiled again, is bit for bit the model validation
    stepped: folding and tags are passes on the scene in memory, before the
    conversion validates and writes it, and nothing validates it again."""
    report = reports[recipe]
    assert report.compiled is not None and report.compiled is report.conversion.compiled
    written = mujoco.MjModel.from_xml_path(str(report.output / "scene.xml"))
    assert differences(written, report.compiled) == []
    folded = report.manifest.get("folded_geoms", {})
    assert folded and all(written.geom(g).bodyid[0] != written.body(b).id for g, b in folded.items())
    tags = [f"{e['family']}_{e['id']}" for e in report.manifest["fiducials"]]
    assert tags and all(written.geom(name).matid[0] >= 0 for name in tags)


def _load(folder: Path) -> tuple[mujoco.MjModel, mujoco.MjData, dict]:
    m = mujoco.MjModel.from_xml_path(str(folder / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return m, d, json.loads((folder / "facility.json").read_text())


def _component_bodies(m: mujoco.MjModel, prefix: str) -> list[int]:
    return [b for b in range(1, m.nbody) if m.body(b).name.startswith(prefix)]


def _mockup_prefixes(manifest: dict) -> list[str]:
    return [
        c["prefix"]
        for name, c in manifest["components"].items()
        if name not in ("robot", "ctb") and c.get("prefix")
    ]


@pytest.mark.parametrize("recipe", [p.stem for p in RECIPES])
def test_facility_compiles_and_lists_its_contents(built, recipe):
    m, d, manifest = _load(built[recipe])
    assert manifest["recipe"] == load_recipe(ROOT / "recipes" / f"{recipe}.yaml").name
    assert manifest["counts"]["bodies"] == m.nbody and manifest["counts"]["joints"] == m.njnt
    assert {j["name"] for j in manifest["joints"]} == {m.joint(j).name for j in range(m.njnt)}
    for comp in manifest["component_mjcf"].values():
        assert (built[recipe] / comp).is_file()
    for _ in range(500):
        mujoco.mj_step(m, d)
    assert not any(d.warning[i].number for i in range(len(d.warning)))


# facility-facts.md section 1: the real facility's layout (world frame), the frames of
# the real description: (x, y, z), yaw
FACT_POSES = {
    "trainer": ((-2.0992, 2.4346, 0.0), 4.7112),
    "hatch_4060": ((1.402, -0.802, -0.002), 0.0),
    "ctb": ((0.8, 0.8, 0.005), math.pi / 2),  # our CTB frame: its bottom centre
}


def _yaw(r: np.ndarray) -> float:
    return math.atan2(r[1, 0], r[0, 0])


def _same_yaw(a: float, b: float) -> bool:
    return abs(math.remainder(a - b, 2 * math.pi)) < 1e-6


def test_default_facility_is_laid_out_as_the_real_one(built):
    """facility.json reports the fact sheet's poses, and the compiled bodies stand there:
    the trainer frame, the bench seat at (1.261, 0, 0.477) in it with the lid hinge
    0.127 m in front and 0.0475 m above, the hatch frame and its door hinge at
    (0.678, 0.057, 0.716) in it, the rack (the real frame (0.508, 1.168, 0.984) rpy
    (pi/2, 0, 0) is our rack frame 0.984 m up, y up, z out of the front), MERLIN in it."""
    m, d, manifest = _load(built["imetro"])
    comps = manifest["components"]
    for name, (xyz, yaw) in FACT_POSES.items():
        assert comps[name]["pose"]["xyz"] == pytest.approx(list(xyz), abs=1e-9), name
        assert _same_yaw(comps[name]["pose"]["yaw"], yaw), name
    assert comps["express_rack"]["pose"]["xyz"] == pytest.approx([0.508, 1.168, 0.0])

    def frame(body: str) -> tuple[np.ndarray, np.ndarray]:
        b = m.body(body).id
        return d.xpos[b].copy(), d.xmat[b].reshape(3, 3).copy()

    p, r = frame("trainer_frame")
    np.testing.assert_allclose(p, FACT_POSES["trainer"][0], atol=1e-9)
    assert _same_yaw(_yaw(r), FACT_POSES["trainer"][1])
    bench, r_bench = frame("trainer_bench_seat")
    np.testing.assert_allclose(bench, p + r @ [1.261, 0.4475, 0.477], atol=1e-9)
    lid = m.joint("trainer_lid_joint").id
    np.testing.assert_allclose(d.xanchor[lid], bench + r_bench @ [0.127, 0, 0.0475], atol=1e-3)
    np.testing.assert_allclose(d.xaxis[lid], -r[:, 1], atol=1e-9)
    # the real description's lid hinge line (its bench_lid body: (-2.10085, 1.0466, 0.5244))
    assert d.xanchor[lid][1] == pytest.approx(1.0466, abs=2e-3)
    assert d.xanchor[lid][2] == pytest.approx(0.5244, abs=2e-3)

    p, r = frame("hatch_4060_frame")
    np.testing.assert_allclose(p, FACT_POSES["hatch_4060"][0], atol=1e-9)
    door = m.joint("hatch_4060_door_joint").id
    np.testing.assert_allclose(d.xanchor[door], p + r @ [0.678, 0.057, 0.716], atol=1e-6)

    rack_real = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)  # rpy (pi/2, 0, 0)
    p, r = frame("express_rack_rack")
    np.testing.assert_allclose(p + [0, 0, 0.984], [0.508, 1.168, 0.984], atol=1e-9)
    # the real frame's x, y (up), z (out of the front) are our y, z and x
    np.testing.assert_allclose(r[:, [1, 2, 0]], rack_real, atol=1e-9)
    # MERLIN at (-0.229, 0.083, 0) in the real rack frame
    merlin = [m.body(b).name for b in range(m.nbody) if m.body(b).name.startswith("express_rack_merlin")]
    assert merlin
    ctb, r_ctb = frame("ctb")
    np.testing.assert_allclose(ctb[:2], [0.8, 0.8], atol=1e-3)


@pytest.mark.parametrize("recipe", [p.stem for p in RECIPES])
def test_robot_holds_home_mockups_stay_put_and_ctb_settles_upright(built, recipe):
    m, d, manifest = _load(built[recipe])
    mockup = [b for p in _mockup_prefixes(manifest) for b in _component_bodies(m, p)]
    assert mockup, "the recipe has mockups"
    start_markers = marker_points(m, d)
    robot = manifest["components"].get("robot", {}).get("roles")
    tool = m.site(robot["sites"]["tool"]).id if robot else None
    tool_start = d.site_xpos[tool].copy() if robot else None
    tool_worst = 0.0
    for _ in range(int(5.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        if robot:
            tool_worst = max(tool_worst, float(np.linalg.norm(d.site_xpos[tool] - tool_start)))
    moved = (
        np.linalg.norm(marker_points(m, d) - start_markers, axis=1)
        .reshape(m.nbody - 1, 4)
        .max(axis=1)
    )
    worst_mockup = max(moved[b - 1] for b in mockup)
    assert worst_mockup < 1e-3, f"a static mockup moved {worst_mockup * 1000:.2f} mm"
    if robot:
        assert tool_worst < 1e-3, f"tool moved {tool_worst * 1000:.2f} mm"
    ctb = m.joint("ctb_joint")
    body = m.jnt_bodyid[ctb.id]
    up = d.xmat[body].reshape(3, 3)[:, 2]
    tilt = math.degrees(math.acos(min(1.0, up[2])))
    speed = float(np.linalg.norm(d.qvel[ctb.dofadr[0] : ctb.dofadr[0] + 3]))
    assert tilt < 5 and speed < 0.01, (tilt, speed)
    assert abs(d.xpos[body][2]) < 0.01, "resting on the floor"
    assert not any(d.warning[i].number for i in range(len(d.warning)))


@pytest.mark.parametrize("recipe", [p.stem for p in RECIPES])
def test_every_mockup_joint_moves_through_its_range_without_interpenetration(built, recipe):
    m, d, manifest = _load(built[recipe])
    home = d.qpos.copy()
    checked = 0
    for name, comp in manifest["components"].items():
        if name in ("robot", "ctb"):
            continue
        for joint in comp.get("joints", []):
            j = m.joint(joint)
            for q in np.linspace(*j.range, 9):
                d.qpos[:] = home
                d.qpos[j.qposadr[0]] = q
                mujoco.mj_forward(m, d)
                bad = penetrations(m, d)
                assert not bad, f"{joint} at {q:.3f}: {bad[:3]}"
            checked += 1
    assert checked >= 10


def test_lid_opens_to_95_degrees_and_stays_open(built):
    m, d, _ = _load(built["imetro"])
    lid = m.joint("trainer_lid_joint")
    assert lid.range[1] == pytest.approx(math.radians(95), abs=1e-3)
    d.qpos[lid.qposadr[0]] = lid.range[1]
    mujoco.mj_forward(m, d)
    for _ in range(int(3.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert d.qpos[lid.qposadr[0]] > math.radians(93)


def test_robot_actuators_sensors_and_cameras_have_stable_names(built):
    m, d, manifest = _load(built["imetro"])
    roles = manifest["components"]["robot"]["roles"]
    assert len(roles["joints"]) == 8 and len(roles["actuators"]) == 8
    actuated = {a["joint"] for a in manifest["actuators"]}
    assert set(roles["joints"]) <= actuated and roles["gripper"]["actuator"] in actuated
    assert len(manifest["actuators"]) == 9, "8 joints plus the gripper"
    sensors = {s["name"]: s["type"] for s in manifest["sensors"]}
    assert sensors[roles["force_torque"]["force"]] == "force"
    assert sensors[roles["force_torque"]["torque"]] == "torque"
    for joint in roles["joints"]:
        assert sensors[f"{joint}_pos"] == "jointpos" and sensors[f"{joint}_vel"] == "jointvel"
    cameras = {c["name"]: c for c in manifest["cameras"]}
    for cam in roles["cameras"].values():
        assert cameras[cam]["resolution"] == [640, 480]
        assert cameras[cam]["fovy"] == pytest.approx(58.0, abs=1e-6)


def test_both_cameras_render_rgb_and_depth_headlessly(built, gl_context):
    m, d, manifest = _load(built["imetro"])
    renderer = mujoco.Renderer(m, 480, 640)
    with renderer:
        for cam in manifest["components"]["robot"]["roles"]["cameras"].values():
            renderer.disable_depth_rendering()
            renderer.update_scene(d, camera=cam)
            rgb = renderer.render()
            renderer.enable_depth_rendering()
            renderer.update_scene(d, camera=cam)
            depth = renderer.render()
            assert rgb.shape == (480, 640, 3) and rgb.std() > 5, "the image shows something"
            assert depth.shape == (480, 640) and 0.05 < float(np.median(depth)) < 10


def _attribute_differences(a: Path, b: Path) -> list[tuple[str, str, str]]:
    """(element name, tag, attribute) of every attribute that differs; trees must match otherwise."""
    ta, tb = etree.parse(str(a)).getroot(), etree.parse(str(b)).getroot()
    out = []
    for ea, eb in zip(ta.iter(), tb.iter(), strict=True):
        assert ea.tag == eb.tag and set(ea.attrib) == set(eb.attrib)
        for key in ea.attrib:
            if ea.get(key) != eb.get(key):
                out.append((ea.get("name", ""), ea.tag, key))
    return out


def test_same_seed_gives_identical_files_and_other_seeds_move_only_jittered_poses(tmp_path):
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
    a = build_facility(recipe, tmp_path / "a", root=ROOT, seed=7, components=False).output
    b = build_facility(recipe, tmp_path / "b", root=ROOT, seed=7, components=False).output
    c = build_facility(recipe, tmp_path / "c", root=ROOT, seed=8, components=False).output

    def files(root: Path) -> dict:
        return {p.relative_to(root): p.read_bytes() for p in root.rglob("*") if p.is_file()}

    assert files(a) == files(b)
    manifest = json.loads((a / "facility.json").read_text())
    assert manifest["seed"] == 7 and set(manifest["offsets"]) >= {"ctb", "trainer"}
    m = mujoco.MjModel.from_xml_path(str(a / "scene.xml"))
    ctb_body = m.body(m.jnt_bodyid[m.joint("ctb_joint").id]).name
    prefixes = [c_["prefix"] for c_ in manifest["components"].values() if c_.get("prefix")]
    diffs = _attribute_differences(a / "scene.xml", c / "scene.xml")
    assert diffs, "a different seed moves something"
    for name, tag, key in diffs:
        if tag == "key":
            assert key == "qpos", "the home keyframe carries the CTB's jittered pose"
            continue
        assert tag == "body" and key in ("pos", "quat"), (name, tag, key)
        assert name == ctb_body or any(name.startswith(p) for p in prefixes), name


def test_the_scene_as_written_is_stepped_after_folding_and_tags(tmp_path, monkeypatch):
    """Validation (compile and step) runs once, on the scene as folding and tags left
    it in memory: the text it compiled is the text written, and the model the build
    reports is the one it stepped."""
    from urdf2mjcf.passes import validate

    calls: list[tuple[str, object]] = []
    real = validate.run

    def spy(xml_path, cfg, **kwargs):
        result = real(xml_path, cfg, **kwargs)
        calls.append((Path(xml_path).read_text(), result))
        return result

    monkeypatch.setattr(validate, "run", spy)
    recipe = load_recipe(ROOT / "recipes" / "imetro-no-robot.yaml")
    report = build_facility(recipe, tmp_path / "f", root=ROOT, components=False)
    assert len(calls) == 1
    ((validated, result),) = calls
    written = (report.output / "scene.xml").read_text()
    assert validated == written
    assert "tag36h11_" in written and report.manifest.get("folded_geoms")
    assert result is not None and result.steps > 0 and report.compiled is result.model
