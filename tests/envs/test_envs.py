"""The Gymnasium environments: Gymnasium's own checker, finite rollouts, seeded resets
that reproduce make-facility's jitter without rebuilding, frames and depth that agree
with MuJoCo's ray casting, and the default tasks' rewards against world positions."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence

import urdf2mjcf.envs  # noqa: F401  (registers the ids)
from urdf2mjcf.bundle_manifest import Manifest
from urdf2mjcf.envs import build as env_build
from urdf2mjcf.envs.base import tilt
from urdf2mjcf.envs.mira3d import START_JITTER, Mira3DEnv
from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.runner.perception import red_mask

ROOT = Path(__file__).resolve().parents[2]
IDS = ("IMetro-v0", "Mira3D-v0")
RECIPES = {"IMetro-v0": "imetro", "Mira3D-v0": "mira3d-floor"}
SMALL = (33, 25)  # odd: the centre pixel lies on the optical axis

# check_env's advice that we do not follow, on purpose: unbounded velocities and forces
# are honest, and actions are the actuators' own ranges (metres, radians, rad/s).
ALLOWED_WARNINGS = ("infinity", "symmetric and normalized")


@pytest.fixture(scope="session")
def built(_session_cache: Path) -> dict[str, Path]:
    """Each facility built once per test session (the cache the environments use)."""
    return {eid: env_build.facility_folder(r, root=ROOT)[0] for eid, r in RECIPES.items()}


@pytest.fixture(scope="session")
def can_render(request: pytest.FixtureRequest) -> bool:
    """Whether an offscreen OpenGL context can be made: the gl_context fixture decides."""
    try:
        request.getfixturevalue("gl_context")
    except pytest.skip.Exception:
        return False
    return True


def _make(eid: str, **kwargs):  # type: ignore[no-untyped-def]
    return gym.make(eid, root=ROOT, **kwargs)


@pytest.mark.parametrize("eid", IDS)
def test_gymnasium_check_env_passes(built, can_render, eid):
    kwargs = {"render_mode": "rgb_array", "camera_obs": True, "camera_size": SMALL}
    env = _make(eid, **(kwargs if can_render else {}), render_size=(64, 48))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=not can_render)
    env.close()
    unexpected = [
        str(w.message) for w in caught if not any(a in str(w.message) for a in ALLOWED_WARNINGS)
    ]
    assert unexpected == []


@pytest.mark.parametrize("eid", IDS)
def test_random_200_step_rollout_stays_finite_and_drives_the_actuators(built, eid):
    env = _make(eid)
    env.action_space.seed(7)
    obs, _ = env.reset(seed=7)
    u = env.unwrapped
    for _ in range(200):
        action = env.action_space.sample()
        obs, reward, terminated, truncated, info = env.step(action)
        assert all(np.all(np.isfinite(v)) for v in obs.values())
        assert math.isfinite(reward) and not info["unstable"]
        # the action is exactly the actuators' targets, within their control ranges
        np.testing.assert_array_equal(u.data.ctrl[u.actuators()], action.astype(np.float64))
        assert obs in env.observation_space
        if terminated:  # the rover tipped over: a legal end, start again
            obs, _ = env.reset()
    assert u.data.time > 0
    env.close()


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _placed_bodies(folder: Path, manifest: Manifest) -> dict[str, str]:
    """Component -> the name of the world child that stands at its placement in the built
    facility as MuJoCo compiles it (named by the component's prefix or its roles' base)."""
    m = mujoco.MjModel.from_xml_path(str(folder / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    out = {}
    for name, comp in manifest.components.items():
        if comp.pose is None:
            continue
        prefix, base = comp.prefix, (comp.roles or {}).get("base")
        for b in range(1, m.nbody):
            body = m.body(b).name
            if m.body_parentid[b] != 0 or not (body == base or (prefix and body.startswith(prefix))):
                continue
            if np.allclose(d.xpos[b], comp.pose.xyz, atol=1e-9) and abs(
                _wrap(_yaw(d.xquat[b]) - comp.pose.yaw)
            ) < 1e-9:
                out[name] = body
    return out


def _poses(env) -> dict[str, tuple[np.ndarray, float]]:  # type: ignore[no-untyped-def]
    u = env.unwrapped
    bodies = _placed_bodies(u.folder, u.manifest)
    ids = {n: u.model.body(b).id for n, b in bodies.items()}
    return {n: (u.data.xpos[b].copy(), _yaw(u.data.xquat[b])) for n, b in ids.items()}


@pytest.mark.parametrize("eid", IDS)
def test_seeded_reset_is_deterministic_and_moves_within_the_jitter_ranges(built, eid):
    env = _make(eid)
    u = env.unwrapped
    obs_a, info_a = env.reset(seed=3)
    poses_a = _poses(env)
    obs_b, info_b = env.reset(seed=3)
    assert data_equivalence(obs_a, obs_b, exact=True)
    assert info_a == info_b
    _, info_c = env.reset(seed=4)
    poses_c = _poses(env)

    recipe = load_recipe(ROOT / "recipes" / f"{RECIPES[eid]}.yaml", root=ROOT)
    moved = set()
    for name, (xyz_a, _) in poses_a.items():
        comp = u.manifest.components[name]
        ranges = recipe.jitter_ranges(name)
        if eid == "Mira3D-v0" and name == u.rover.name:
            ranges = START_JITTER  # the environment's documented start-pose ranges
        nominal_xyz, nominal_yaw = np.array(comp.pose.xyz), comp.pose.yaw
        for (xyz, yaw), info in ((poses_a[name], info_a), (poses_c[name], info_c)):
            off = info["offsets"].get(name, {"dx": 0.0, "dy": 0.0, "dyaw": 0.0})
            pos, ang = (ranges or {}).get("position", 0.0), (ranges or {}).get("yaw", 0.0)
            assert abs(off["dx"]) <= pos and abs(off["dy"]) <= pos and abs(off["dyaw"]) <= ang
            # the body stands where its offsets put it (its frame is the placement's)
            np.testing.assert_allclose(xyz, nominal_xyz + [off["dx"], off["dy"], 0], atol=1e-9)
            assert abs(_wrap(yaw - nominal_yaw - off["dyaw"])) < 1e-9
        if ranges and any(ranges.values()):
            moved.add(name)
            assert not np.allclose(xyz_a, poses_c[name][0])  # another seed, another pose
        else:
            np.testing.assert_array_equal(xyz_a, poses_c[name][0])
    if eid == "IMetro-v0":
        free = {n for n, c in u.manifest.components.items() if c.free}
        assert free and free <= moved  # the CTB moves
        assert moved - free  # and so do the mockups
        assert u.manifest.components["robot"].roles  # the robot, the reference, does not
        assert "robot" not in moved
    else:
        assert moved == {u.rover.name}
    env.close()


def test_reset_gives_the_facility_make_facility_builds_with_that_seed(built, tmp_path):
    # Independent reference: the xacro and MuJoCo's compiler place the seeded facility.
    env = _make("IMetro-v0")
    u = env.unwrapped
    _, info = env.reset(seed=11)
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml", root=ROOT)
    report = build_facility(
        recipe, tmp_path / "seeded", root=ROOT, seed=info["jitter_seed"], components=False
    )
    assert report.manifest["offsets"] == info["offsets"]
    m = mujoco.MjModel.from_xml_path(str(report.scene))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    assert m.nbody == u.model.nbody
    for b in range(1, m.nbody):
        mine = mujoco.mj_name2id(u.model, mujoco.mjtObj.mjOBJ_BODY, m.body(b).name)
        np.testing.assert_allclose(u.data.xpos[mine], d.xpos[b], atol=1e-9, err_msg=m.body(b).name)
        np.testing.assert_allclose(u.data.xmat[mine], d.xmat[b], atol=1e-9, err_msg=m.body(b).name)
    env.close()
    # a facility the user built is used as it is: loaded, not built again
    before = env_build.builds
    given = _make("IMetro-v0", facility=report.output)
    assert given.unwrapped.folder == report.output and env_build.builds == before
    assert all(np.isfinite(v).all() for v in given.reset(seed=0)[0].values())
    given.close()


def test_reset_never_builds_and_a_build_happens_once_per_inputs(built, tmp_path):
    cache = tmp_path / "cache"
    before = env_build.builds
    folder, _ = env_build.facility_folder("imetro", root=ROOT, cache_dir=cache)
    assert env_build.builds == before + 1
    stamp = {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}
    env = _make("IMetro-v0", cache_dir=cache)
    model = env.unwrapped.model
    for seed in range(5):
        env.reset(seed=seed)
        env.step(env.action_space.sample())
    assert env_build.builds == before + 1  # neither the new environment nor its resets
    assert env.unwrapped.model is model
    assert {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()} == stamp
    env.close()


@pytest.mark.parametrize("eid", IDS)
def test_render_and_camera_depth_agree_with_mujoco_ray_casting(built, gl_context, eid):
    # ideal sensors here: the depth noise (2 % at 2 m) is checked in tests/runner/test_noise.py
    env = _make(
        eid, render_mode="rgb_array", camera_obs=True, camera_size=SMALL, sensor_noise=False
    )
    obs, _ = env.reset(seed=5)
    frame = env.render()
    assert frame.shape == (360, 480, 3) and frame.dtype == np.uint8
    assert frame.std() > 10 and len(np.unique(frame.reshape(-1, 3), axis=0)) > 50
    assert obs["rgb"].shape == (SMALL[1], SMALL[0], 3) and obs["rgb"].std() > 1
    u = env.unwrapped
    m, d, cam = u.model, u.data, u.camera_id
    # Each pixel's depth is the distance along the optical axis (-z) to what it sees: cast
    # MuJoCo's ray through the pixel centre with a direction of unit z-component, so the
    # distance it returns is that depth. Rays start at the near plane, as rendering does.
    w, h = SMALL
    f = (h / 2) / math.tan(math.radians(m.cam_fovy[cam]) / 2)
    near = m.vis.map.znear * m.stat.extent
    rot = d.cam_xmat[cam].reshape(3, 3)
    groups = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)  # the groups the renderer shows
    geomid = np.zeros(1, dtype=np.int32)
    rays = np.full((h, w), np.inf)
    for v in range(h):
        for x in range(w):
            vec = rot @ np.array([(x + 0.5 - w / 2) / f, -(v + 0.5 - h / 2) / f, -1.0])
            hit = mujoco.mj_ray(m, d, d.cam_xpos[cam] + near * vec, vec, groups, 1, -1, geomid)
            if hit >= 0:
                rays[v, x] = near + hit
    seen = np.isfinite(rays) & (rays < 20)
    assert seen.mean() > 0.3  # the camera sees the facility, not the sky
    close = np.abs(obs["depth"][seen] - rays[seen]) < 0.01 * rays[seen] + 0.005
    assert close.mean() > 0.95  # all but pixels on the silhouettes of things
    env.close()


def test_force_torque_carries_the_recipes_noise_seeded_by_the_reset(built):
    """The observed wrench is the sensor's reading plus this reset's bias and white
    noise (runner/noise.py's model, from facility.json's ``noise``): the same seed gives
    the same readings, another seed another bias; without noise it is the reading."""
    from urdf2mjcf.runner.noise import SensorNoise

    env = _make("IMetro-v0")
    u = env.unwrapped
    obs, info = env.reset(seed=3)
    reading = u.data.sensordata[u._ft].reshape(2, 3)
    expected = SensorNoise.from_manifest(u.manifest, info["jitter_seed"]).wrench(*reading)
    np.testing.assert_allclose(obs["force_torque"], np.concatenate(expected), atol=1e-12)
    bias = np.r_[u.noise.force_bias, u.noise.torque_bias]
    assert np.linalg.norm(bias[:3]) > 0 and np.linalg.norm(bias[3:]) > 0
    again, _ = env.reset(seed=3)
    np.testing.assert_array_equal(again["force_torque"], obs["force_torque"])
    env.reset(seed=4)
    assert not np.allclose(np.r_[u.noise.force_bias, u.noise.torque_bias], bias)
    ideal = _make("IMetro-v0", sensor_noise=False)
    obs, _ = ideal.reset(seed=3)
    v = ideal.unwrapped
    np.testing.assert_array_equal(obs["force_torque"], v.data.sensordata[v._ft])
    env.close()
    ideal.close()


def test_imetro_reward_is_minus_the_grasp_site_distance_to_the_red_strap(built):
    env = _make("IMetro-v0")
    u = env.unwrapped
    env.reset(seed=2)
    _, reward, *_ = env.step(env.action_space.sample())
    m, d = u.model, u.data
    (bag,) = [c.prefix for c in u.manifest.components.values() if c.free]
    mine = np.array([m.body(int(b)).name.startswith(bag) for b in m.geom_bodyid])
    rgba = np.array([m.mat_rgba[i] if i >= 0 else m.geom_rgba[g] for g, i in enumerate(m.geom_matid)])
    red = red_mask((rgba[None, :, :3] * 255).astype(np.uint8))[0]
    strap = d.geom_xpos[mine & red].mean(axis=0)  # the bag's red strap, in the world
    grasp = d.site_xpos[u.robot.sites["grasp"]]
    assert reward == pytest.approx(-np.linalg.norm(grasp - strap), abs=1e-9)
    env.close()


def test_mira3d_reward_is_the_forward_progress_of_the_base(built):
    env = _make("Mira3D-v0")
    u = env.unwrapped
    env.reset(seed=1)
    start = u.data.xpos[u.rover.base][:2].copy()
    heading = u.data.xmat[u.rover.base].reshape(3, 3)[:2, 0].copy()
    hi = env.action_space.high
    forward = np.r_[np.full(4, hi[0] / 2), u.data.ctrl[u.rover.arm]].astype(np.float32)
    total = sum(env.step(forward)[1] for _ in range(50))
    travelled = (u.data.xpos[u.rover.base][:2] - start) @ heading
    assert travelled > 0.5  # 2 s at half speed
    assert total == pytest.approx(travelled, rel=0.02)
    assert tilt(u.data.xmat[u.rover.base]) < 0.1
    backward = forward.copy()
    backward[:4] *= -1
    assert sum(env.step(backward)[1] for _ in range(50)) < 0
    env.close()


def test_bad_options_are_input_errors_naming_the_option(built):
    with pytest.raises(InputError, match="camera.*no camera 'nose'.*wrist"):
        _make("IMetro-v0", camera_obs=True, camera="nose")
    with pytest.raises(InputError, match="jitter.kitchen.*unknown component"):
        _make("IMetro-v0", jitter={"kitchen": {"position": 0.1}})
    with pytest.raises(InputError, match="render_size: 4000 x 300 exceeds the offscreen"):
        _make("Mira3D-v0", render_size=(4000, 300))
    with pytest.raises(InputError, match="frame_skip: must be >= 1"):
        _make("Mira3D-v0", frame_skip=0)
    with pytest.raises(InputError, match="render_mode.*'human' is not one of rgb_array"):
        Mira3DEnv(root=ROOT, render_mode="human")  # gym.make would wrap it for human


def test_import_without_gymnasium_says_how_to_install_it():
    code = "import sys; sys.modules['gymnasium'] = None; import urdf2mjcf.envs"
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=dict(os.environ)
    )
    assert run.returncode != 0
    assert "pip install 'mjcf-forge[gym]'" in run.stderr
