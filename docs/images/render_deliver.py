"""Render the deliver task's picture in docs/mira3d.md (headless).

    python docs/images/render_deliver.py

Builds recipes/mira3d-pair.yaml in a temporary folder, runs ``rover-drive --task
deliver``'s task (seed 0) and renders the printed layer, the printer with the regolith
in its hopper and the collector beside it, with MuJoCo's offscreen renderer.
"""

from __future__ import annotations

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
from urdf2mjcf.runner.rover.deliver import run_deliver  # noqa: E402
from urdf2mjcf.runner.rover.sim import RoverSim  # noqa: E402

OUT = ROOT / "docs" / "images" / "mira3d-deliver.png"
WIDTH, HEIGHT = 960, 600


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        recipe = load_recipe(ROOT / "recipes" / "mira3d-pair.yaml")
        folder = build_facility(recipe, Path(tmp) / "pair", root=ROOT, components=False).output
        sim = RoverSim(folder)
        result, _ = run_deliver(sim, seed=0)
        m, d = sim.m, sim.d
        m.vis.global_.offwidth, m.vis.global_.offheight = 1280, 800
        base = m.body("printer_base_link").id
        with mujoco.Renderer(m, HEIGHT, WIDTH) as r:
            cam = mujoco.MjvCamera()
            cam.lookat[:] = d.xpos[base] + d.xmat[base].reshape(3, 3)[:, 0] * 0.8
            cam.distance, cam.azimuth, cam.elevation = 3.2, 200.0, -35.0
            r.update_scene(d, cam)
            Image.fromarray(r.render()).quantize(256).save(OUT, optimize=True)
        print(OUT.relative_to(ROOT), result.summary())


if __name__ == "__main__":
    main()
