"""Render the pictures in docs/mira3d.md (headless).

    python docs/images/render_mira3d.py

Builds the three MIRA3D recipes in a temporary folder, drives the rover down the
ramp for one picture with the runner, and renders with MuJoCo's offscreen renderer.
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from urdf2mjcf import headless  # noqa: E402

headless.configure()

import mujoco  # noqa: E402
from PIL import Image  # noqa: E402

from urdf2mjcf.facility.build import build_facility  # noqa: E402
from urdf2mjcf.facility.recipe import load_recipe  # noqa: E402
from urdf2mjcf.runner.rover import RoverSim, Straight, Turn  # noqa: E402

OUT = ROOT / "docs" / "images"
WIDTH, HEIGHT = 960, 600


def shot(m, d, out: Path, lookat, distance, azimuth, elevation) -> None:
    m.vis.global_.offwidth, m.vis.global_.offheight = 1280, 800
    with mujoco.Renderer(m, HEIGHT, WIDTH) as r:
        cam = mujoco.MjvCamera()
        cam.lookat[:] = lookat
        cam.distance, cam.azimuth, cam.elevation = distance, azimuth, elevation
        r.update_scene(d, cam)
        # a 256-colour palette: the regolith's speckle makes full-colour PNGs large
        Image.fromarray(r.render()).quantize(256).save(out, optimize=True)
    print(out.relative_to(ROOT))


def camera_shot(m, d, out: Path, camera: str, grey: bool = False) -> None:
    w, h = (int(v) for v in m.cam_resolution[m.camera(camera).id])
    m.vis.global_.offwidth, m.vis.global_.offheight = max(w, 1280), max(h, 800)
    with mujoco.Renderer(m, h, w) as r:
        r.update_scene(d, camera=camera)
        image = Image.fromarray(r.render())
    image = image.convert("L") if grey else image
    image = image.resize((w // 2, h // 2))
    (image if grey else image.quantize(256)).save(out, optimize=True)
    print(out.relative_to(ROOT))


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        built = {}
        for name in ("floor", "moon", "pair"):
            recipe = load_recipe(ROOT / "recipes" / f"mira3d-{name}.yaml")
            built[name] = build_facility(recipe, Path(tmp) / name, root=ROOT, components=False)

        sim = RoverSim(built["floor"].output)
        sim.settle(0.5)
        shot(sim.m, sim.d, OUT / "mira3d-floor.png", (-3.2, 3.0, 0.4), 10.0, 115, -18)

        sim = RoverSim(built["moon"].output)
        sim.settle(0.5)
        shot(sim.m, sim.d, OUT / "mira3d-moon.png", (30.2, 0.0, 0.8), 3.6, 142, -10)
        shot(sim.m, sim.d, OUT / "mira3d-moon-wide.png", (20.0, 5.0, 0.0), 45.0, 235, -20)
        camera_shot(sim.m, sim.d, OUT / "mira3d-stereo-left.png", "stereo_left_optical_frame")
        camera_shot(sim.m, sim.d, OUT / "mira3d-rear-camera.png", "rear_camera_optical_frame", True)
        sim.run({"rover": Straight(20.0, speed=0.8)})
        pose = sim.d.xpos[sim.rover().base]
        shot(sim.m, sim.d, OUT / "mira3d-ramp.png", (pose[0], pose[1], pose[2] + 0.6), 6.0, 100, -8)

        sim = RoverSim(built["pair"].output)
        sim.settle(0.5)
        sim.run({"printer": Turn(math.radians(-60))})
        shot(sim.m, sim.d, OUT / "mira3d-pair.png", (-1.5, 0.3, 0.5), 9.0, 235, -25)


if __name__ == "__main__":
    main()
