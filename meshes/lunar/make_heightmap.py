"""Generate the lunar terrain of the MIRA3D world: a heightmap PNG and its description.

    python meshes/lunar/make_heightmap.py [--out DIR]     (default: this folder)

``heightmap.png`` is an 8-bit greyscale image, darker = lower, 501 x 501 pixels
over a 1 km x 1 km square (2 m between pixel centres), modelled on the Dune
crater region south of the Apollo 15 landing site that the MIRA3D simulation
used in Gazebo (the facts, section 5). The image's top row is the north edge
(+y), its left column the west edge (-x), as MuJoCo reads a PNG height field.
Pixel value v is the elevation ``Z_MIN + v / 255 * (Z_MAX - Z_MIN)``: black is
24 m below the landing site, white 6 m above it, in steps of 0.118 m.

What it holds (world frame: x east, y north, z up, the landing site at z = 0):

* **landing site**: a flat disc of radius 45 m at the origin, exactly z = 0
  (pixel value 204 = 0.8 x 255), blending into the terrain by 75 m;
* **the ramp**: east of the landing site, a plane sloping down at 10 deg
  (exactly 3 grey levels per 2 m pixel: atan(0.3529 / 2) = 10.008 deg) from
  x = 40 m to x = 100 m, 24 m wide (|y| <= 12 m), down to a flat apron at
  z = -10.59 m that runs to x = 140 m; its sides blend into the terrain;
* **the crater** (Dune class): centre (-230, 200) m, rim radius 230 m, a bowl
  from a rim 4 m above the plain to a flat floor at z = -24 m (black), more
  than 20 m below its surroundings;
* a hill in the south-east whose top is the white plateau (z = 6 m), sixty
  small craters (radius 3 to 35 m) away from the landing site and the ramp,
  and gentle rolling ground (about +-1.5 m).

Every feature comes from the numbers below and one seeded generator, so the
output is the same bytes on every run (PNG written by Pillow with fixed
settings). ``heightmap.json`` records the extent, the height range and the
regions for the recipes, tests and docs.
"""

from __future__ import annotations

import argparse
import io
import json
import math
from pathlib import Path

import numpy as np
from PIL import Image

PIXELS = 501  # per side
EXTENT = 1000.0  # m, side of the square, pixel centre to pixel centre
Z_MIN = -24.0  # m, black (world z with the landing site at 0)
Z_MAX = 6.0  # m, white
LEVEL = (Z_MAX - Z_MIN) / 255  # m per grey level
SITE_LEVEL = 204  # the landing site, z = 0
SITE_RADIUS = 45.0
SITE_BLEND = 75.0  # the terrain is natural from this radius on
RAMP_X = (40.0, 100.0)  # m, top and foot of the 10 deg ramp
RAMP_LEVELS_PER_PIXEL = 3  # 3 x LEVEL per 2 m: tan(slope) = 0.17647
RAMP_HALF_WIDTH = 12.0
RAMP_BLEND = 18.0  # sides blend into the terrain over this width
APRON_X = (100.0, 140.0)  # flat foot of the ramp
CRATER = (-230.0, 200.0, 230.0)  # centre x, y and rim radius, m
CRATER_RIM = 4.0  # m above the plain
HILL = (330.0, -320.0, 120.0, 10.0)  # centre x, y, radius (m), height (m): its top clips white
SMALL_CRATERS = 60
SEED = 1969


def grid() -> tuple[np.ndarray, np.ndarray]:
    """x (east) and y (north) of every pixel centre, in the PNG's row order (top = north)."""
    c = np.linspace(-EXTENT / 2, EXTENT / 2, PIXELS)
    x, y = np.meshgrid(c, c[::-1])
    return x, y


def _smoothstep(t: np.ndarray) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t)


def natural(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The terrain before the landing site and the ramp are cut in (m)."""
    rng = np.random.default_rng(SEED)
    z = np.zeros_like(x)
    # rolling ground: a few long waves
    for _ in range(6):
        wavelength = rng.uniform(150.0, 400.0)
        angle = rng.uniform(0.0, math.pi)
        phase = rng.uniform(0.0, 2 * math.pi)
        k = 2 * math.pi / wavelength
        z += 0.25 * np.sin(k * (x * math.cos(angle) + y * math.sin(angle)) + phase)
    # the crater: a parabolic bowl from the rim down past the floor (clipped black), and a rim
    cx, cy, radius = CRATER
    r = np.hypot(x - cx, y - cy) / radius
    bowl = np.where(
        r < 1.0, CRATER_RIM - 30.0 * (1.0 - r * r), CRATER_RIM * np.exp(-(((r - 1.0) / 0.25) ** 2))
    )
    z += bowl
    # the hill
    hx, hy, hr, hh = HILL
    z += hh * np.exp(-((np.hypot(x - hx, y - hy) / hr) ** 2))
    # small craters, clear of the landing site, the ramp and the big crater
    placed = 0
    while placed < SMALL_CRATERS:
        cr = float(rng.uniform(3.0, 35.0))
        px, py = rng.uniform(-EXTENT / 2 + 40, EXTENT / 2 - 40, size=2)
        if math.hypot(px, py) < SITE_BLEND + 2 * cr:
            continue
        if RAMP_X[0] - 2 * cr < px < APRON_X[1] + 40 + 2 * cr and abs(py) < 40 + 2 * cr:
            continue
        if math.hypot(px - cx, py - cy) < radius + 2 * cr:
            continue
        q = np.hypot(x - px, y - py) / cr
        depth = 0.2 * cr
        z += np.where(
            q < 1.0,
            -depth * (1.0 - q * q) + 0.08 * cr,
            0.08 * cr * np.exp(-(((q - 1.0) / 0.3) ** 2)),
        )
        placed += 1
    return z


def levels() -> np.ndarray:
    """Grey levels (uint8), the landing site and the ramp exact."""
    x, y = grid()
    z = natural(x, y)
    # landing site: flat at z = 0 inside SITE_RADIUS, blending out to SITE_BLEND
    w = _smoothstep((np.hypot(x, y) - SITE_RADIUS) / (SITE_BLEND - SITE_RADIUS))
    z = w * z
    v = np.clip(np.rint((z - Z_MIN) / LEVEL), 0, 255)
    # the ramp and its apron: whole grey levels per pixel, so the surface is an exact plane
    dx = EXTENT / (PIXELS - 1)
    steps = np.clip(np.rint((x - RAMP_X[0]) / dx), 0, None)
    ramp = np.where(x <= RAMP_X[1] + 1e-9, SITE_LEVEL - RAMP_LEVELS_PER_PIXEL * steps, 0.0)
    apron_level = SITE_LEVEL - RAMP_LEVELS_PER_PIXEL * round((RAMP_X[1] - RAMP_X[0]) / dx)
    ramp = np.where(x > RAMP_X[1] + 1e-9, apron_level, ramp)
    inside_x = (x >= RAMP_X[0] - 1e-9) & (x <= APRON_X[1] + 1e-9)
    # across the lane: exact inside the half width, blended to the terrain beyond it
    side = _smoothstep((np.abs(y) - RAMP_HALF_WIDTH) / RAMP_BLEND)
    # along the lane: the apron blends into the terrain beyond its end
    end = _smoothstep((x - APRON_X[1]) / 40.0)
    blend = np.maximum(side, end)
    lane = (
        (x >= RAMP_X[0] - 1e-9)
        & (np.abs(y) <= RAMP_HALF_WIDTH + RAMP_BLEND)
        & (x <= APRON_X[1] + 40.0)
    )
    full_ramp = np.where(inside_x, ramp, apron_level)
    mixed = np.rint((1 - blend) * full_ramp + blend * v)
    v = np.where(lane, mixed, v)
    return v.astype(np.uint8)


def png_bytes(v: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(v, mode="L").save(buffer, format="PNG", optimize=False, compress_level=9)
    return buffer.getvalue()


def description() -> dict:
    dx = EXTENT / (PIXELS - 1)
    apron_level = SITE_LEVEL - RAMP_LEVELS_PER_PIXEL * round((RAMP_X[1] - RAMP_X[0]) / dx)
    return {
        "file": "heightmap.png",
        "pixels": [PIXELS, PIXELS],
        "size_x": EXTENT,
        "size_y": EXTENT,
        "z_min": Z_MIN,
        "z_max": Z_MAX,
        "landing_site": {"center": [0.0, 0.0], "radius": SITE_RADIUS, "z": 0.0},
        "ramp": {
            "x": list(RAMP_X),
            "half_width": RAMP_HALF_WIDTH,
            "slope_deg": math.degrees(math.atan(RAMP_LEVELS_PER_PIXEL * LEVEL / dx)),
            "z_top": 0.0,
            "z_foot": Z_MIN + apron_level * LEVEL,
            "apron_x": list(APRON_X),
        },
        "crater": {
            "center": list(CRATER[:2]),
            "rim_radius": CRATER[2],
            "z_rim": CRATER_RIM,
            "z_floor": Z_MIN,
        },
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    out = parser.parse_args(argv).out
    out.mkdir(parents=True, exist_ok=True)
    (out / "heightmap.png").write_bytes(png_bytes(levels()))
    (out / "heightmap.json").write_text(json.dumps(description(), indent=2) + "\n")


if __name__ == "__main__":
    main()
