"""Sensor noise against its models: depth error on a rendered flat wall against
Intel's RMS formula, image noise against the shot/read model, the force-torque bias
constant in a trial and different across seeds, the same seed the same noise, and the
recipe's noise section checked like every recipe key."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.bundle_manifest import from_json
from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.noise import DEFAULTS
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.runner.noise import SensorNoise
from urdf2mjcf.runner.perception import Camera

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def config() -> dict:
    """The default facility recipe's noise section, as facility.json lists it."""
    return dict(load_recipe(ROOT / "recipes" / "imetro.yaml", root=ROOT).noise)


WALL = """<mujoco>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1"/>
    <geom type="box" size="20 20 0.01" pos="0 0 -0.01" rgba="0.7 0.7 0.7 1"/>
    <camera name="d435" pos="0 0 {z}" fovy="58" resolution="640 480"/>
  </worldbody>
</mujoco>"""


@pytest.mark.parametrize("distance", [1.0, 2.0])
def test_depth_error_on_a_flat_wall_follows_intels_rms_formula(
    gl_context: None, config: dict, distance: float
) -> None:
    m = mujoco.MjModel.from_xml_string(WALL.format(z=distance))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    ideal = Camera(m, 0)
    noisy = Camera(m, 0, noise=SensorNoise(config, seed=3, fovy_deg=58.0))
    _, clean = ideal.rgbd(d)
    _, depth = noisy.rgbd(d)
    ideal.close()
    noisy.close()
    assert clean == pytest.approx(distance, abs=1e-4)  # the camera faces the wall squarely
    # Intel: RMS = z^2 * subpixel / (focal * baseline), focal of the 640 x 480 camera.
    focal = 240 / math.tan(math.radians(29))
    expected = distance**2 * config["depth"]["subpixel"] / (focal * 0.050)
    measured = float(np.std(depth.astype(np.float64) - distance))
    assert measured == pytest.approx(expected, rel=0.10)
    assert float(np.mean(depth) - distance) == pytest.approx(0, abs=expected / 50)


def test_depth_error_grows_with_the_square_of_range(config: dict) -> None:
    noise = SensorNoise(config, seed=1, fovy_deg=58.0)
    near, far = (float(noise.depth_std(z, 480)) for z in (1.0, 2.0))
    assert far == pytest.approx(4 * near)
    # The D435 datasheet's bound, 2 % RMS at 2 m, with its 50 mm baseline and the
    # 433 px focal length of the 640 x 480 camera: the default subpixel 0.2165.
    assert far / 2.0 == pytest.approx(0.02, rel=1e-3)


def test_image_noise_has_the_configured_gain_shot_and_read_noise(config: dict) -> None:
    noise = SensorNoise(config, seed=4)
    assert abs(noise.gain - 1) <= config["exposure"]["gain"]
    image = np.full((400, 400, 3), 100, np.uint8)
    out = noise.rgb(image).astype(np.float64)
    signal = 100 * noise.gain
    std = math.sqrt(config["rgb"]["read_std"] ** 2 + config["rgb"]["shot_gain"] * signal)
    assert out.mean() == pytest.approx(signal, abs=0.05)
    assert out.std() == pytest.approx(math.sqrt(std**2 + 1 / 12), rel=0.03)  # + rounding


def test_exposure_and_lighting_vary_per_seed_within_their_ranges(config: dict) -> None:
    gains = {round(SensorNoise(config, seed=s).gain, 9) for s in range(20)}
    scales = [SensorNoise(config, seed=s).light_scale for s in range(20)]
    assert len(gains) == 20
    assert all(abs(s - 1) <= config["exposure"]["light"] for s in scales)
    m = mujoco.MjModel.from_xml_string(WALL.format(z=1))
    before = (m.light_diffuse.copy(), np.array(m.vis.headlight.diffuse))
    noise = SensorNoise(config, seed=2)
    noise.light(m)
    assert m.light_diffuse == pytest.approx(before[0] * noise.light_scale)
    assert np.array(m.vis.headlight.diffuse) == pytest.approx(before[1] * noise.light_scale)


def test_force_torque_bias_is_constant_in_a_trial_and_differs_across_seeds(config: dict) -> None:
    cfg = config["wrench"]
    noise = SensorNoise(config, seed=7)
    readings = np.array(
        [np.concatenate(noise.wrench(np.zeros(3), np.zeros(3))) for _ in range(20000)]
    )
    bias = np.concatenate([noise.force_bias, noise.torque_bias])
    std = np.array([cfg["force_std"]] * 3 + [cfg["torque_std"]] * 3)
    # The mean of a trial's readings is its bias; the spread is the white noise.
    assert readings.mean(0) == pytest.approx(bias, abs=float(4 * std.max() / math.sqrt(20000)))
    assert readings.std(0) == pytest.approx(std, rel=0.03)
    # The first and the last thousand readings share the bias: it does not drift.
    first, last = readings[:1000].mean(0), readings[-1000:].mean(0)
    assert np.all(np.abs(first - last) < 5 * std * math.sqrt(2 / 1000))
    biases = np.array([SensorNoise(config, seed=s).force_bias for s in range(50)])
    assert len({tuple(b) for b in biases.round(9)}) == 50
    assert biases.std(0) == pytest.approx([cfg["force_bias"]] * 3, rel=0.35)


def test_the_same_seed_gives_identical_noise_and_another_seed_other_noise(config: dict) -> None:
    def draw(seed: int) -> list[np.ndarray]:
        noise = SensorNoise(config, seed=seed, fovy_deg=58.0)
        image = np.full((48, 64, 3), 90, np.uint8)
        depth = np.full((48, 64), 1.5, np.float32)
        f, t = noise.wrench(np.ones(3), np.ones(3))
        return [noise.rgb(image), noise.depth(depth), f, t, noise.depth(depth)]

    a, b, c = draw(9), draw(9), draw(10)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not any(np.array_equal(x, y) for x, y in zip(a, c, strict=True))
    assert not np.array_equal(a[1], a[4])  # a new draw per frame


def test_a_channel_turned_off_passes_its_data_through(config: dict) -> None:
    off = SensorNoise({**config, "depth": False, "rgb": False, "exposure": False}, seed=1)
    image = np.full((8, 8, 3), 77, np.uint8)
    depth = np.full((8, 8), 1.0, np.float32)
    assert np.array_equal(off.rgb(image), image) and np.array_equal(off.depth(depth), depth)
    none = SensorNoise.from_manifest(from_json({"schema_version": 1, "components": {}}), seed=1)  # a build without a noise section
    f, t = none.wrench(np.ones(3), np.zeros(3))
    assert f.tolist() == [1, 1, 1] and t.tolist() == [0, 0, 0]


def test_noise_defaults_are_on_and_the_section_is_checked(tmp_path: Path) -> None:
    base = "name: r\nxacro: w.urdf.xacro\n"
    (tmp_path / "r.yaml").write_text(base)
    assert load_recipe(tmp_path / "r.yaml").noise == DEFAULTS  # no section: all on
    (tmp_path / "r.yaml").write_text(base + "noise: false\n")
    assert not any(load_recipe(tmp_path / "r.yaml").noise.values())
    for text, key in [
        ("noise:\n  depth: {subpixl: 0.1}\n", "noise.depth.subpixl"),
        ("noise:\n  wrench: {force_std: -1}\n", "noise.wrench.force_std"),
        ("noise:\n  lidar: {}\n", "noise.lidar"),
    ]:
        (tmp_path / "r.yaml").write_text(base + text)
        with pytest.raises(InputError, match=rf"r\.yaml: {key}: .*\(line 4\)"):
            load_recipe(tmp_path / "r.yaml")
