"""MIRA3D (facility-facts.md section 5): the lunar rover with an arm, on the institute
floor and on lunar terrain, alone and as a pair. The three recipes build with
make-facility and compile without warnings; the model matches the facts (control box
inertia, UR10 kinematics, gravity); the rover drives through its wheel actuators
(straight on the floor, down the 10 deg ramp on the Moon, two rovers at once) and the
runner's wheel odometry is compared with the true pose.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from tests.facility.mechanism_checks import dh_flange
from tests.same_model import differences
from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe, parse_recipe
from urdf2mjcf.facility.scatter import parse_rocks, scatter
from urdf2mjcf.runner.rover import (
    ArmWave,
    RoverSim,
    Straight,
    Turn,
    rover_drive_command,
    true_pose,
)

ROOT = Path(__file__).resolve().parents[2]
RECIPES = {name: ROOT / "recipes" / f"mira3d-{name}.yaml" for name in ("floor", "moon", "pair")}
HEIGHTMAP = json.loads((ROOT / "meshes" / "lunar" / "heightmap.json").read_text())
ARM = [
    "ur_shoulder_pan_joint",
    "ur_shoulder_lift_joint",
    "ur_elbow_joint",
    "ur_wrist_1_joint",
    "ur_wrist_2_joint",
    "ur_wrist_3_joint",
]
WHEELS = ["front_left", "front_right", "rear_left", "rear_right"]
# UR10 (CB-series) standard DH parameters and link masses (Universal_Robots_ROS2_Description)
DH_D = (0.1273, 0.0, 0.0, 0.163941, 0.1157, 0.0922)
DH_A = (0.0, -0.612, -0.5723, 0.0, 0.0, 0.0)
DH_ALPHA = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
UR10_MASSES = {
    "ur_base_link_inertia": 4.0,
    "ur_shoulder_link": 7.1,
    "ur_upper_arm_link": 12.7,
    "ur_forearm_link": 4.27,
    "ur_wrist_1_link": 2.0,
    "ur_wrist_2_link": 2.0,
    "ur_wrist_3_link": 0.365,
}


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> dict:
    """Each MIRA3D recipe, built once: name -> FacilityReport."""
    base = tmp_path_factory.mktemp("mira3d")
    return {
        name: build_facility(load_recipe(path), base / f"mira3d-{name}", root=ROOT)
        for name, path in RECIPES.items()
    }


@pytest.mark.parametrize("name", list(RECIPES))
def test_what_is_written_is_what_was_validated(built, name):
    report = built[name]
    written = mujoco.MjModel.from_xml_path(str(report.output / "scene.xml"))
    assert report.compiled is not None
    assert differences(written, report.compiled) == []


def _load(folder: Path) -> tuple[mujoco.MjModel, mujoco.MjData]:
    m = mujoco.MjModel.from_xml_path(str(folder / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return m, d


def _names(m: mujoco.MjModel, kind: mujoco.mjtObj, count: int) -> list[str]:
    return [mujoco.mj_id2name(m, kind, i) or "" for i in range(count)]


def _ground_z(m: mujoco.MjModel, d: mujoco.MjData, x: float, y: float) -> float:
    """Height of the terrain (geom 'lunar_terrain') under (x, y), by a ray from above."""
    terrain = m.geom("lunar_terrain").id
    geomid = np.zeros(1, np.int32)
    top = 100.0
    dist = mujoco.mj_ray(
        m, d, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid
    )
    assert geomid[0] == terrain, "the ray hits the terrain"
    return top - dist


# -- building -------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(RECIPES))
def test_recipe_builds_and_compiles_without_warnings(built, name):
    report = built[name]
    assert report.conversion.warnings == (), [n.message for n in report.conversion.warnings]
    manifest = json.loads((report.output / "facility.json").read_text())
    rovers = {n: c for n, c in manifest["components"].items() if c.get("roles")}
    expected = {"floor": {"rover"}, "moon": {"rover"}, "pair": {"collector", "printer"}}[name]
    # each rover compiled on its own is the model attached: one folder per rover where
    # the facility holds more than one
    folders = ["mira3d_rover"] if len(expected) == 1 else sorted(expected)
    for folder in folders:
        assert (report.output / "components" / folder / "mira3d_rover.xml").is_file()
    assert set(rovers) == expected
    m, d = _load(report.output)
    assert m.nu == 10 * len(expected), "4 wheels + 6 arm joints per rover"
    for _ in range(int(1.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    fired = {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(d.warning) if w.number}
    assert not fired, fired


def test_two_rovers_share_no_names_and_each_has_every_part(built):
    m, _ = _load(built["pair"].output)
    kinds = {
        "body": (mujoco.mjtObj.mjOBJ_BODY, m.nbody),
        "joint": (mujoco.mjtObj.mjOBJ_JOINT, m.njnt),
        "actuator": (mujoco.mjtObj.mjOBJ_ACTUATOR, m.nu),
        "sensor": (mujoco.mjtObj.mjOBJ_SENSOR, m.nsensor),
        "camera": (mujoco.mjtObj.mjOBJ_CAMERA, m.ncam),
        "site": (mujoco.mjtObj.mjOBJ_SITE, m.nsite),
    }
    for kind, (obj, count) in kinds.items():
        names = [n for n in _names(m, obj, count) if n]
        assert len(names) == len(set(names)), kind
        collector = {n[len("collector_") :] for n in names if n.startswith("collector_")}
        printer = {n[len("printer_") :] for n in names if n.startswith("printer_")}
        assert collector == printer and collector, kind
    # every joint, actuator, sensor and camera belongs to one of the two rovers (or, a
    # joint, to a regolith grain of the deliver task: mira3d-pair.yaml sets deliver)
    for kind in ("joint", "actuator", "sensor", "camera"):
        obj, count = kinds[kind]
        owners = ("collector_", "printer_") + (("regolith_",) if kind == "joint" else ())
        assert all(n.startswith(owners) for n in _names(m, obj, count)), kind
    manifest = json.loads((built["pair"].output / "facility.json").read_text())
    assert manifest["components"]["printer"]["roles"]["wheel_actuators"]["left"] == [
        "printer_front_left_wheel_joint",
        "printer_rear_left_wheel_joint",
    ]


# -- the rover model --------------------------------------------------------------------


def test_control_box_is_35_kg_with_the_uniform_box_inertia(built):
    m, _ = _load(built["floor"].output)
    box = m.body("control_box_link")
    assert box.mass[0] == pytest.approx(35.0, abs=1e-12)
    # the paper's eq. 1-2: Ixx = Iyy = m (0.5^2 + 0.3^2) / 12, Izz = m (0.5^2 + 0.5^2) / 12
    np.testing.assert_allclose(box.inertia, [0.992, 0.992, 1.458], rtol=1e-3)
    np.testing.assert_allclose(box.iquat, [1, 0, 0, 0], atol=1e-12)
    # the IMU sits at the box's centre, with its axes
    _, d = _load(built["floor"].output)
    imu = m.site("imu_link").id
    np.testing.assert_allclose(d.site_xpos[imu], d.xpos[box.id], atol=1e-12)
    np.testing.assert_allclose(d.site_xmat[imu], d.xmat[box.id], atol=1e-12)


def test_wheels_are_continuous_velocity_driven_and_the_arm_position_driven(built):
    m, _ = _load(built["floor"].output)
    for wheel in WHEELS:
        j = m.joint(f"{wheel}_wheel_joint")
        assert j.type[0] == mujoco.mjtJoint.mjJNT_HINGE and not j.limited[0], "continuous"
        np.testing.assert_allclose(j.axis, [0, 1, 0])
        a = m.actuator(f"{wheel}_wheel_joint")
        assert a.biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE and a.biasprm[1] == 0, "velocity"
        assert a.gainprm[0] == pytest.approx(400) and a.biasprm[2] == pytest.approx(-400)
        np.testing.assert_allclose(a.ctrlrange, [-7.5, 7.5])
        tyre = m.geom(f"{wheel}_wheel_tyre")
        assert tyre.type[0] == mujoco.mjtGeom.mjGEOM_CYLINDER
        assert tyre.friction[0] == pytest.approx(0.9) and tyre.priority[0] == 1
    for joint in ARM:
        a = m.actuator(joint)
        assert a.biasprm[1] == pytest.approx(-a.gainprm[0]) and a.gainprm[0] > 0, "position servo"
    for body, mass in UR10_MASSES.items():
        assert m.body(body).mass[0] == pytest.approx(mass, abs=1e-12), body
    sensors = set(_names(m, mujoco.mjtObj.mjOBJ_SENSOR, m.nsensor))
    assert {"imu_link_accelerometer", "imu_link_gyro", "imu_link_orientation"} <= sensors
    cameras = {c: m.camera(c) for c in _names(m, mujoco.mjtObj.mjOBJ_CAMERA, m.ncam)}
    assert set(cameras) == {
        "stereo_left_optical_frame",
        "stereo_right_optical_frame",
        "rear_camera_optical_frame",
        "left_wheel_camera_optical_frame",
        "right_wheel_camera_optical_frame",
        "arm_camera_optical_frame",
    }
    np.testing.assert_allclose(
        m.cam_resolution[cameras["stereo_left_optical_frame"].id], [1280, 720]
    )
    np.testing.assert_allclose(
        m.cam_resolution[cameras["rear_camera_optical_frame"].id], [752, 480]
    )


def _dh(q) -> np.ndarray:
    return dh_flange(q, DH_D, DH_A, DH_ALPHA)


@pytest.mark.parametrize(
    "arm",
    [(0, 0, 0, 0, 0, 0), (0, -2.2, 2.6, -1.9708, -1.5708, 0), (0.3, -1.1, 1.4, -2.0, 0.7, 2.5)],
)
def test_tool0_matches_ur10_dh_forward_kinematics(built, arm):
    m, d = _load(built["floor"].output)
    for joint, q in zip(ARM, arm, strict=True):
        d.qpos[m.joint(joint).qposadr[0]] = q
    mujoco.mj_forward(m, d)
    base = m.body("ur_base").id
    tool = m.body("ur_tool0").id
    r_base = d.xmat[base].reshape(3, 3)
    t = _dh(arm)
    np.testing.assert_allclose(d.xpos[tool], d.xpos[base] + r_base @ t[:3, 3], atol=1e-9)
    np.testing.assert_allclose(d.xmat[tool].reshape(3, 3), r_base @ t[:3, :3], atol=1e-9)


def test_home_pose_is_folded_clear_of_the_rover_and_standing_on_four_wheels(built):
    m, d = _load(built["floor"].output)
    tip = d.site_xpos[m.site("printhead_tip").id]
    assert 0.4 < tip[2] < 0.5 and tip[0] < 0.6, "printhead points down just ahead of the wheels"
    for _ in range(int(1.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    touching = set()
    for c in d.contact[: d.ncon]:
        names = {m.geom(c.geom1).name, m.geom(c.geom2).name}
        assert "floor_collision" in names, f"only the tyres touch the floor: {names}"
        touching |= names - {"floor_collision"}
    assert touching == {f"{w}_wheel_tyre" for w in WHEELS}


# -- the worlds --------------------------------------------------------------------------


@pytest.mark.parametrize("name, g", [("floor", 9.81), ("moon", 1.62)])
def test_imu_reads_gravity_upwards_at_rest(built, name, g):
    sim = RoverSim(built[name].output)
    sim.settle(1.5)
    magnitude, up = sim.imu_up(sim.rover())
    assert sim.m.opt.gravity[2] == pytest.approx(-g)
    assert magnitude == pytest.approx(g, rel=0.01)
    assert up == pytest.approx(g, rel=0.01), "the specific force points up"


def test_lunar_terrain_is_the_heightmap_at_its_real_extent_and_heights(built):
    m, d = _load(built["moon"].output)
    h = m.hfield("lunar_terrain")
    assert (int(h.nrow[0]), int(h.ncol[0])) == tuple(HEIGHTMAP["pixels"])
    # MuJoCo's size: half extents, the height of white above black, the base below black
    np.testing.assert_allclose(h.size, [500.0, 500.0, 30.0, 2.0])
    assert m.geom("lunar_terrain").pos[2] == pytest.approx(HEIGHTMAP["z_min"])
    # (MuJoCo keeps height fields in single precision: 1e-5 m over a 30 m range)
    assert _ground_z(m, d, 0.0, 0.0) == pytest.approx(0.0, abs=1e-5), "landing site at z = 0"
    assert _ground_z(m, d, 20.0, -15.0) == pytest.approx(0.0, abs=1e-5)
    slope = math.tan(math.radians(HEIGHTMAP["ramp"]["slope_deg"]))
    for x in (41.0, 55.5, 70.0, 99.0):
        assert _ground_z(m, d, x, 3.0) == pytest.approx(-(x - 40.0) * slope, abs=1e-5)
    assert HEIGHTMAP["ramp"]["slope_deg"] == pytest.approx(10.0, abs=0.01)
    cx, cy = HEIGHTMAP["crater"]["center"]
    assert _ground_z(m, d, cx, cy) == pytest.approx(-24.0, abs=1e-5), "the crater floor is black"
    rim = max(
        _ground_z(m, d, cx + 230.0 * math.cos(a), cy + 230.0 * math.sin(a))
        for a in (0, 1, 2, 3, 4, 5)
    )
    assert rim - _ground_z(m, d, cx, cy) > 20.0, "a crater more than 20 m deep"
    assert m.opt.gravity[2] == pytest.approx(-1.62)
    assert m.vis.map.haze == 0, "no atmosphere"


def test_heightmap_script_is_deterministic_and_small(tmp_path):
    script = ROOT / "meshes" / "lunar" / "make_heightmap.py"
    subprocess.run([sys.executable, str(script), "--out", str(tmp_path)], check=True, cwd=ROOT)
    shipped = ROOT / "meshes" / "lunar"
    for name in ("heightmap.png", "heightmap.json"):
        assert (tmp_path / name).read_bytes() == (shipped / name).read_bytes(), name
    assert (shipped / "heightmap.png").stat().st_size < 1_000_000


def test_rocks_come_from_a_seeded_scatter_clear_of_the_rovers(built, tmp_path):
    manifest = json.loads((built["moon"].output / "facility.json").read_text())
    recipe = load_recipe(RECIPES["moon"])
    rocks = manifest["rocks"]["rocks"]
    assert manifest["rocks"]["seed"] == recipe.rocks["seed"] and len(rocks) == recipe.rocks["count"]
    m, _ = _load(built["moon"].output)
    assert sum(1 for b in range(m.nbody) if m.body(b).name.startswith("rock_")) == len(rocks)
    rover = recipe.placements["rover"].xyz
    for r in rocks:
        assert math.hypot(r["x"] - rover[0], r["y"] - rover[1]) >= 3.0
        for x0, x1, y0, y1 in recipe.rocks["keepout"]:
            assert not (x0 <= r["x"] <= x1 and y0 <= r["y"] <= y1)
    again = scatter(recipe.rocks, recipe.rocks["seed"], [rover[:2]])
    assert [(a.x, a.y, a.size) for a in again] == [(r["x"], r["y"], r["size"]) for r in rocks]
    other = scatter(recipe.rocks, recipe.rocks["seed"] + 1, [rover[:2]])
    assert [a.x for a in other] != [r["x"] for r in rocks]
    # --seed replaces the recipe's rock seed
    seeded = build_facility(recipe, tmp_path / "seeded", root=ROOT, seed=11, components=False)
    assert seeded.manifest["rocks"]["seed"] == 11


def test_a_users_dem_becomes_the_terrain_at_its_real_extent(tmp_path):
    """A GeoTIFF-like float DEM (a 50 x 40 m patch at 0.25 m, a 10 deg plane around
    1700 m) through dem_to_heightmap.py (MuJoCo's float height field) into the moon
    recipe with --set: the ground is the plane, and the rover stands on it."""
    cols, rows, px, zero = 201, 161, 0.25, 1700.0
    slope = math.tan(math.radians(10))
    dem = zero - slope * np.arange(cols)[None, :].repeat(rows, 0) * px
    Image.fromarray(dem.astype(np.float32), mode="F").save(tmp_path / "dem.tif")
    script = ROOT / "meshes" / "lunar" / "dem_to_heightmap.py"
    out = subprocess.run(
        [
            sys.executable,
            str(script),
            str(tmp_path / "dem.tif"),
            "--pixel-size",
            str(px),
            "--out",
            str(tmp_path / "dem.bin"),
            "--zero",
            str(zero),
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    sets = dict(item.split("=", 1) for item in out.split("--set ")[1:])
    sets = {k: v.strip() for k, v in sets.items()}
    assert float(sets["terrain_size_x"]) == 50.0 and float(sets["terrain_size_y"]) == 40.0
    ground = lambda x: -slope * (x + 25.0)  # noqa: E731 (the patch's west edge is x = -25)
    sets |= {"rocks.count": "0", "placements.rover.xyz": f"[-20, 0, {ground(-20.0)!r}]"}
    recipe = load_recipe(RECIPES["moon"], sets)
    report = build_facility(recipe, tmp_path / "dem", root=ROOT, components=False)
    m, d = _load(report.output)
    for x, y in ((-24.0, -19.0), (-3.3, 2.0), (10.0, 7.5), (24.5, 19.0)):
        assert _ground_z(m, d, x, y) == pytest.approx(ground(x), abs=1e-4)
    sim = RoverSim(report.output)
    sim.settle(2.0)
    pose = true_pose(sim.m, sim.d, sim.rover())
    assert math.degrees(pose.pitch) == pytest.approx(10.0, abs=0.2), "standing on the slope"
    assert pose.z == pytest.approx(ground(pose.x), abs=0.01) and not sim.warnings()


@pytest.mark.parametrize(
    "rocks, key",
    [
        ({"count": -1}, "rocks.count"),
        ({"count": 3, "area": [1, 0, 0, 1]}, "rocks.area"),
        ({"count": 3, "size": [0.5]}, "rocks.size"),
        ({"colour": "grey"}, "rocks.colour"),
        ({"count": 400, "area": [0, 2, 0, 2]}, "rocks.count"),
    ],
)
def test_bad_rock_settings_are_input_errors_naming_the_key(rocks, key):
    with pytest.raises(InputError) as info:
        recipe = parse_recipe({"name": "x", "xacro": "w.xacro", "rocks": rocks}, Path("r.yaml"))
        scatter(recipe.rocks, 0, [], Path("r.yaml"))
    assert key in str(info.value)
    assert parse_rocks(None, None) == {}


# -- driving ----------------------------------------------------------------------------


def test_rover_drives_10_m_straight_on_the_floor_while_moving_its_arm(built, record_property):
    sim = RoverSim(built["floor"].output)
    sim.settle(1.0)
    report = sim.run({"rover": Straight(10.0, speed=0.5)}, arm={"rover": ArmWave()})["rover"]
    record_property("floor_drive", report.summary())
    print(report.summary())
    assert report.true_distance == pytest.approx(10.0, rel=0.05)
    assert abs(report.true["y"]) < 0.1 and abs(report.true_turn) < 2.0, "straight"
    assert report.odometry_position_error < 0.05
    assert not report.tipped and report.max_tilt < 2.0
    # the arm followed its swing (+-0.4 rad on the shoulder pan) within 0.05 rad
    assert report.arm_error < 0.05
    assert not sim.warnings()


def test_rover_drives_down_the_10_deg_ramp_without_tipping(built, record_property):
    sim = RoverSim(built["moon"].output)
    rover = sim.rover()
    sim.settle(1.0)
    start = true_pose(sim.m, sim.d, rover)
    assert start.x == pytest.approx(30.0, abs=0.01), "10 m before the top of the ramp"
    report = sim.run({"rover": Straight(24.0, speed=0.5)}, arm={"rover": ArmWave()})["rover"]
    record_property("slope_drive", report.summary())
    print(report.summary())
    # on the ramp: pitched nose down by the slope, level across it, never tipping
    assert 9.5 < report.max_pitch < 11.5 and report.true["pitch"] == pytest.approx(10.0, abs=0.5)
    assert report.max_roll < 2.0 and not report.tipped
    end = true_pose(sim.m, sim.d, rover)
    slope = math.tan(math.radians(HEIGHTMAP["ramp"]["slope_deg"]))
    assert end.x > 50.0 and end.z == pytest.approx(-(end.x - 40.0) * slope, abs=0.05)
    # the wheels' path length is the true path; planar wheel odometry misses the slope's
    # cosine, wheel + IMU odometry follows it
    assert report.true_path == pytest.approx(24.0, rel=0.02)
    assert 0.05 < report.odometry_position_error < 0.5
    assert report.fused_position_error < 0.05
    assert not sim.warnings()


def test_two_rovers_driven_at_once_one_drives_one_turns(built, record_property):
    sim = RoverSim(built["pair"].output)
    sim.settle(1.0)
    collector = sim.rover("collector")
    positions = []  # the collector's position after every step
    reports = sim.run(
        {"collector": Straight(5.0, speed=0.5), "printer": Turn(math.radians(90))},
        arm={"printer": ArmWave()},
        on_step=lambda s: positions.append(s.d.xpos[collector.base].copy()),
    )
    for r in reports.values():
        record_property(r.rover, r.summary())
        print(r.summary())
    c, p = reports["collector"], reports["printer"]
    assert c.true_distance == pytest.approx(5.0, rel=0.05) and abs(c.true_turn) < 2.0
    assert p.true_turn == pytest.approx(90.0, abs=2.0), "turned by the IMU"
    assert p.true_distance < 0.5, "turned in place (skid steer drifts a little)"
    # skid steering: the wheels turned far more than the rover
    assert p.odometry["turn"] > 1.5 * p.true_turn and p.slip > 0.3
    # one rover stood still, braked, while the other went on
    assert c.duration < p.duration, "the collector finished first"
    done = int(round(c.duration / sim.dt))
    held = np.linalg.norm(np.array(positions[done:]) - positions[done - 1], axis=1).max()
    assert held < 0.005
    assert not sim.warnings()


def test_rover_drive_command_writes_a_report(built, tmp_path):
    out = tmp_path / "r.json"
    result = CliRunner().invoke(
        rover_drive_command,
        [
            str(built["floor"].output / "scene.xml"),
            "--distance",
            "2",
            "--speed",
            "0.5",
            "--turn",
            "30",
            "--report",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "rover: straight 2 m" in result.output and "rover: turn 30 deg" in result.output
    tasks = json.loads(out.read_text())["tasks"]
    assert [t["task"] for t in tasks] == ["straight", "turn"]
    assert tasks[0]["true_distance"] == pytest.approx(2.0, rel=0.05)
