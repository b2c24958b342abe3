"""The localizer against the truth: the facility rendered headlessly from a camera 1 m
from a tag, the estimate compared with the component's placement pose from
facility.json (the build's own record, which the localizer never sees). The issue's
bound: within 5 mm and 0.5 deg at 1 m, with the recipe's sensor noise on, at the
nominal poses and under seeded jitter of +-2 cm and +-2 deg."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.bundle_manifest import from_json
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.runner.camera import CameraModel
from urdf2mjcf.runner.localize import (
    camera_pose,
    detect,
    localization_record,
    localize,
    locate,
)
from urdf2mjcf.runner.noise import SensorNoise
from urdf2mjcf.runner.perception import Camera

ROOT = Path(__file__).resolve().parents[2]
POSITION_MM, YAW_DEG = 5.0, 0.5
JITTER = {"jitter.default.position": "0.02", "jitter.default.yaw": "0.0349"}  # 2 cm, 2 deg
# Without the robot: these views are placed around the tags, wherever the robot stands.
SETS = {**JITTER, "robot": "none"}


def _build(base: Path, name: str, seed: int | None) -> dict:
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml", SETS, root=ROOT)
    out = build_facility(recipe, base / name, root=ROOT, seed=seed, components=False).output
    return {"dir": out, "manifest": json.loads((out / "facility.json").read_text())}


@pytest.fixture(scope="module")
def nominal(tmp_path_factory: pytest.TempPathFactory) -> dict:
    return _build(tmp_path_factory.mktemp("localize"), "nominal", None)


@pytest.fixture(scope="module")
def jittered(tmp_path_factory: pytest.TempPathFactory) -> dict:
    return _build(tmp_path_factory.mktemp("localize"), "seed5", 5)


def _tag_frame(manifest: dict, tag_id: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the robot expects a tag (the nominal layout): face centre and axes."""
    f = next(f for f in manifest["fiducials"] if f["id"] == tag_id)
    pose = manifest["components"][f["component"]]["pose"]
    c, s = math.cos(pose["yaw"]), math.sin(pose["yaw"])
    r = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    centre = np.array(pose["xyz"]) + r @ np.array(f["pose_in_component"]["xyz"])
    return centre, r @ np.reshape(f["pose_in_component"]["matrix"], (3, 3))


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Quaternion of a MuJoCo camera at ``eye`` looking at ``target``, image up as near
    the world's +z as the view allows (+y when looking straight down)."""
    z = eye - target
    z /= np.linalg.norm(z)
    up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([x, np.cross(z, x), z]).ravel())
    return quat


def _render(folder: Path, eye: np.ndarray, target: np.ndarray, seed: int | None) -> tuple:
    """RGB and depth of a 640 x 480, 58 deg camera (a D435 as simulated) at ``eye``
    looking at ``target``, with the facility's sensor noise for ``seed`` (None: ideal)."""
    spec = mujoco.MjSpec.from_file(str(folder / "scene.xml"))
    quat = _look_at(eye, target)
    spec.worldbody.add_camera(name="probe", pos=eye, quat=quat, fovy=58, resolution=[640, 480])
    m = spec.compile()
    d = mujoco.MjData(m)
    manifest = json.loads((folder / "facility.json").read_text())
    noise = SensorNoise.from_manifest(from_json(manifest), seed) if seed is not None else None
    if noise is not None:
        noise.light(m)
    mujoco.mj_forward(m, d)
    cam = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "probe")
    with mujoco.Renderer(m, 480, 640) as r:
        r.update_scene(d, camera=cam)
        rgb = r.render().copy()
        r.enable_depth_rendering()
        r.update_scene(d, camera=cam)
        depth = r.render().copy()
    if noise is not None:
        rgb, depth = noise.rgb(rgb), noise.depth(depth, 58.0)
    return rgb, depth, camera_pose(d.cam_xpos[cam], d.cam_xmat[cam])


def _errors(estimate, truth: dict) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    dp = 1000 * float(np.linalg.norm(estimate.position - np.array(truth["xyz"])))
    dyaw = math.degrees(estimate.yaw - truth["yaw"])
    return dp, abs((dyaw + 180) % 360 - 180)


CASES = [(0, "trainer", 0.3), (20, "hatch_4060", -0.3), (40, "express_rack", 0.25)]


@pytest.mark.parametrize("noise_seed", [None, 11])
@pytest.mark.parametrize(("tag", "component", "side"), CASES)
def test_a_component_is_found_within_5_mm_and_half_a_degree_from_1_m(
    gl_context: None, nominal: dict, tag: int, component: str, side: float, noise_seed: int | None
) -> None:
    centre, axes = _tag_frame(nominal["manifest"], tag)
    eye = centre + axes[:, 2] * math.sqrt(1 - side**2) + axes[:, 0] * side  # 1 m, oblique
    rgb, depth, cam = _render(nominal["dir"], eye, centre, noise_seed)
    found = localize(rgb, depth, CameraModel(640, 480, 58.0), cam, nominal["manifest"]["fiducials"])
    assert tag in found[component].tags
    dp, dyaw = _errors(found[component], nominal["manifest"]["components"][component]["pose"])
    assert dp < POSITION_MM and dyaw < YAW_DEG, (dp, dyaw)


@pytest.mark.parametrize(("tag", "component", "side"), CASES)
def test_the_jittered_pose_is_recovered_from_the_nominal_drawings(
    gl_context: None, nominal: dict, jittered: dict, tag: int, component: str, side: float
) -> None:
    """The robot aims where the tag should be (nominal layout) and knows only the
    drawings (the nominal build's fiducials); the mockup stands elsewhere (seed 5)."""
    offsets = jittered["manifest"]["offsets"][component]
    assert math.hypot(offsets["dx"], offsets["dy"]) > 0.002 or abs(offsets["dyaw"]) > 0.003
    centre, axes = _tag_frame(nominal["manifest"], tag)
    eye = centre + axes[:, 2] * math.sqrt(1 - side**2) + axes[:, 0] * side
    rgb, depth, cam = _render(jittered["dir"], eye, centre, 5)
    found = localize(rgb, depth, CameraModel(640, 480, 58.0), cam, nominal["manifest"]["fiducials"])
    truth = jittered["manifest"]["components"][component]["pose"]
    dp, dyaw = _errors(found[component], truth)
    assert dp < POSITION_MM and dyaw < YAW_DEG, (dp, dyaw)
    # And the nominal pose is not what it found: the jitter is larger than the error.
    nominal_dp, nominal_dyaw = _errors(
        found[component], nominal["manifest"]["components"][component]["pose"]
    )
    assert nominal_dp > dp or nominal_dyaw > dyaw


def test_no_tag_in_view_finds_nothing() -> None:
    assert detect(np.full((480, 640, 3), 128, np.uint8)) == {}
    grey = np.full((480, 640, 3), 128, np.uint8)
    assert localize(grey, None, CameraModel(640, 480, 58.0), np.eye(4), []) == {}


def test_locate_renders_through_the_runners_camera_and_records_the_errors(
    gl_context: None, jittered: dict
) -> None:
    """The runner's path: perception.Camera with the trial's noise, then locate();
    localization_record gives the report's estimate-minus-truth figures."""
    manifest = jittered["manifest"]
    centre, axes = _tag_frame(manifest, 0)
    spec = mujoco.MjSpec.from_file(str(jittered["dir"] / "scene.xml"))
    eye = centre + axes[:, 2] * math.sqrt(1 - 0.3**2) + axes[:, 0] * 0.3
    quat = _look_at(eye, centre)
    spec.worldbody.add_camera(name="probe", pos=eye, quat=quat, fovy=58, resolution=[640, 480])
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    noise = SensorNoise.from_manifest(from_json(manifest), seed=5)
    noise.light(m)
    camera = Camera(m, mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "probe"), noise=noise)
    found = locate(camera, d, from_json(manifest))
    camera.close()
    record = localization_record(found, from_json(manifest).poses())
    assert set(record) == {"trainer"}
    assert record["trainer"]["position_error_m"] < POSITION_MM / 1000
    assert abs(record["trainer"]["yaw_error_deg"]) < YAW_DEG
    # A point of the drawings lands where the jittered model has it.
    tag = manifest["fiducials"][0]
    body = m.body(tag["body"]).id
    local = np.array(tag["pose_in_component"]["xyz"])
    tag_world = d.xpos[body] + d.xmat[body].reshape(3, 3) @ np.array(tag["pose_in_body"]["xyz"])
    assert np.linalg.norm(found["trainer"].to_world(local) - tag_world) < POSITION_MM / 1000
