"""Turn a digital elevation model into a MuJoCo height field for the MIRA3D world.

    python meshes/lunar/dem_to_heightmap.py DEM --pixel-size METRES [--out FILE] [--crop X0 Y0 W H]

DEM is an image Pillow reads: a GeoTIFF exported as 32-bit float ('F') or 16-bit
('I;16') TIFF, a 16-bit or 8-bit PNG, ... in metres of elevation (``--scale`` converts
other units), north up. ``--pixel-size`` is the ground distance between pixels (GeoTIFF
georeferencing is not read: take it from ``gdalinfo``). ``--crop`` cuts a window (pixels).

The output is one of:

* ``.png`` (default): 8-bit greyscale, darkest = lowest, as make_heightmap.py writes;
  fine for kilometre-scale terrain (the height range in 255 steps);
* ``.bin``: MuJoCo's binary height field (int32 rows, int32 columns, float32 heights,
  south row first): full precision, for fine patches and gentle slopes.

It prints the ``make-facility`` settings that place the terrain at its real extent
and heights: elevation ``--zero Z`` (default: the median elevation) at the world's
z = 0, the terrain's centre at x = y = 0.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image


def load(path: Path, scale: float, crop: list[int] | None) -> np.ndarray:
    """Elevations (m), north row first."""
    image = Image.open(path)
    z = np.asarray(image, dtype=np.float64)
    if z.ndim == 3:  # an RGB(A) picture of a DEM: its grey value
        z = z[..., :3].mean(axis=2)
    if crop:
        x0, y0, w, h = crop
        z = z[y0 : y0 + h, x0 : x0 + w]
    if z.shape[0] < 2 or z.shape[1] < 2 or not np.isfinite(z).all():
        raise SystemExit(f"error: {path}: needs at least 2 x 2 finite elevations")
    return z * scale


def write(z: np.ndarray, out: Path) -> None:
    lo, hi = float(z.min()), float(z.max())
    if hi <= lo:
        raise SystemExit("error: the elevations are all the same: nothing to make a terrain of")
    if out.suffix.lower() == ".png":
        v = np.rint((z - lo) / (hi - lo) * 255).astype(np.uint8)
        Image.fromarray(v, mode="L").save(out, format="PNG", compress_level=9)
    elif out.suffix.lower() == ".bin":
        with out.open("wb") as f:
            np.array(z.shape, np.int32).tofile(f)
            z[::-1].astype(np.float32).tofile(f)  # MuJoCo's row 0 is the south edge
    else:
        raise SystemExit(f"error: {out}: write .png or .bin")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dem", type=Path)
    parser.add_argument("--pixel-size", type=float, required=True, help="metres between pixels")
    parser.add_argument("--out", type=Path, default=None, help="output .png or .bin")
    parser.add_argument("--scale", type=float, default=1.0, help="metres per DEM unit")
    parser.add_argument("--zero", type=float, default=None, help="elevation put at z = 0")
    parser.add_argument("--crop", type=int, nargs=4, metavar=("X0", "Y0", "W", "H"))
    a = parser.parse_args(argv)
    z = load(a.dem, a.scale, a.crop)
    out = a.out or a.dem.with_suffix(".png")
    write(z, out)
    rows, cols = z.shape
    zero = float(np.median(z)) if a.zero is None else a.zero
    print(f"wrote {out} ({cols} x {rows} px)")
    print(
        f"--set terrain_file={out.resolve()} "
        f"--set terrain_size_x={(cols - 1) * a.pixel_size!r} "
        f"--set terrain_size_y={(rows - 1) * a.pixel_size!r} "
        f"--set terrain_z_min={float(z.min()) - zero!r} "
        f"--set terrain_z_max={float(z.max()) - zero!r}"
    )


if __name__ == "__main__":
    main()
