"""Render the pictures in docs/facility.md (headless).

    python docs/images/render.py
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

VIEWS = {
    "imetro": [("overview", (-0.2, 0.7, 0.6), 6.2, 70, -30), ("seat", (-1.65, 0.85, 0.45), 2.4, 55, -38)],
    "imetro-two-hatches": [("overview", (0.6, 0.4, 0.7), 8.5, 70, -35)],
}


def render(scene: Path, out: Path, lookat, distance, azimuth, elevation, qpos=None) -> None:
    m = mujoco.MjModel.from_xml_path(str(scene))
    m.vis.global_.offwidth, m.vis.global_.offheight = 1280, 800
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    for name, value in (qpos or {}).items():
        d.qpos[m.joint(name).qposadr[0]] = value
    mujoco.mj_forward(m, d)
    with mujoco.Renderer(m, 600, 960) as r:
        cam = mujoco.MjvCamera()
        cam.lookat[:] = lookat
        cam.distance, cam.azimuth, cam.elevation = distance, azimuth, elevation
        r.update_scene(d, cam)
        Image.fromarray(r.render()).save(out, optimize=True)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for recipe_name, views in VIEWS.items():
            recipe = load_recipe(ROOT / "recipes" / f"{recipe_name}.yaml")
            report = build_facility(recipe, Path(tmp) / recipe_name, root=ROOT, components=False)
            for view, lookat, distance, azimuth, elevation in views:
                qpos = {"trainer_lid_joint": 1.658} if view == "seat" else None
                render(report.scene, ROOT / "docs" / "images" / f"{recipe_name}-{view}.png", lookat, distance, azimuth, elevation, qpos)
                print(f"docs/images/{recipe_name}-{view}.png")


if __name__ == "__main__":
    main()
