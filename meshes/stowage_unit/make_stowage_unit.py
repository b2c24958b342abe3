#!/usr/bin/env python3
"""Generate the visual meshes of the stowage unit mockup with manifold3d CSG.

Run from anywhere::

    python meshes/stowage_unit/make_stowage_unit.py [--out OUTPUT_DIR]

(default: the folder of this script). Writes binary STL files with an all-zero
header and a canonical vertex and face order, so every run gives the same
bytes. Dimensions are in metres, each mesh in the frame of the link that uses
it (see facility/mockups/stowage_unit/README.md); they must agree with the
collision boxes of facility/mockups/stowage_unit/urdf/stowage_unit.xacro,
which tests/facility/test_stowage_unit.py checks.

Meshes (visual only; collision is boxes in the xacro):

* ``base_frame.stl``: the aluminium frame, 1.27 x 0.90 x 0.47, union of its
  19 members of 40 mm square tube: openings for two drawers in the front
  face and for two cabinet doors on each side.
* ``tower_shell.stl``: the plywood tower on the rear of the deck, open to the
  front, with one shelf: outer box minus inner box, plus the shelf.
* ``seat_bin.stl``: the stowage bin under the lid: an open-top box, outer box
  minus inner box (inside 0.60 x 0.55 x 0.32).
* ``drawer_tray.stl``: a drawer tray, an open-top box (both drawers).
* ``recess_cup.stl``: the cup of the recessed latch, a cylinder minus a
  cylinder, axis along z, open towards +z.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import manifold3d as mf
import numpy as np

from urdf2mjcf.assets import stl_bytes
from urdf2mjcf.ir import MeshData

# ---------------------------------------------------------------- dimensions
# Base frame (link <prefix>stowage_unit, unit frame U: origin on the floor at
# the rear edge, x forward to the bench front, z up).
FRAME_L, FRAME_W, FRAME_H, TUBE = 1.27, 0.90, 0.47, 0.04
SIDE_POSTS_X = (0.40, 0.80)  # x of the rear face of the side posts (door openings between)
PARTITION_X = 0.80  # transverse rails between the door and drawer compartments

# Tower (link <prefix>tower, frame at U (0, 0, 0.477)).
TOWER_D, TOWER_W, TOWER_H, PLY = 0.38, 0.90, 1.123, 0.018
SHELF_Z, SHELF_D = 0.55, 0.37

# Seat bin (link <prefix>seat_bin, frame at the centre of the inner floor).
BIN_IN_X, BIN_IN_Y, BIN_IN_Z, BIN_WALL = 0.60, 0.55, 0.32, 0.010

# Drawer tray (link <prefix>drawer_*, frame at the front face of the base frame,
# bottom of the opening): x in [-0.40, 0.002], y in +-0.185, z in [0.02, 0.32].
TRAY_X0, TRAY_X1, TRAY_W, TRAY_Z0, TRAY_Z1, TRAY_WALL = -0.40, 0.002, 0.37, 0.02, 0.32, 0.006

# Recessed latch cup (visual of the door carrying the recessed latch).
CUP_R_OUT, CUP_R_IN, CUP_DEPTH, CUP_BOTTOM, CUP_SEGMENTS = 0.045, 0.038, 0.016, 0.002, 48


def box(x0: float, x1: float, y0: float, y1: float, z0: float, z1: float) -> mf.Manifold:
    """An axis-aligned box from its bounds."""
    return mf.Manifold.cube([x1 - x0, y1 - y0, z1 - z0]).translate([x0, y0, z0])


def frame_members() -> list[tuple[float, float, float, float, float, float]]:
    """The 19 non-overlapping members of the base frame as (x0, x1, y0, y1, z0, z1)."""
    L, hw, H, s = FRAME_L, FRAME_W / 2, FRAME_H, TUBE
    members = []
    for x0 in (0.0, L - s):  # corner posts, full height
        for y0 in (-hw, hw - s):
            members.append((x0, x0 + s, y0, y0 + s, 0.0, H))
    for y0 in (-hw, hw - s):  # long rails, bottom and top
        for z0 in (0.0, H - s):
            members.append((s, L - s, y0, y0 + s, z0, z0 + s))
    for x0 in (0.0, L - s, PARTITION_X):  # transverse rails: rear, front, partition
        for z0 in (0.0, H - s):
            members.append((x0, x0 + s, -hw + s, hw - s, z0, z0 + s))
    for x0 in SIDE_POSTS_X:  # side posts between the cabinet doors
        for y0 in (-hw, hw - s):
            members.append((x0, x0 + s, y0, y0 + s, s, H - s))
    members.append((L - s, L, -s / 2, s / 2, s, H - s))  # front mullion between the drawers
    return members


def base_frame() -> mf.Manifold:
    return mf.Manifold.batch_boolean([box(*m) for m in frame_members()], mf.OpType.Add)


def tower_shell() -> mf.Manifold:
    outer = box(0.0, TOWER_D, -TOWER_W / 2, TOWER_W / 2, 0.0, TOWER_H)
    inner = box(PLY, TOWER_D + 0.01, -TOWER_W / 2 + PLY, TOWER_W / 2 - PLY, -0.01, TOWER_H - PLY)
    shelf = box(PLY, SHELF_D, -TOWER_W / 2 + PLY, TOWER_W / 2 - PLY, SHELF_Z, SHELF_Z + PLY)
    return (outer - inner) + shelf


def open_box(x0, x1, y0, y1, z0, z1, wall: float, floor: float) -> mf.Manifold:
    """An open-top box: the outer box minus the inner one (walls and floor)."""
    outer = box(x0, x1, y0, y1, z0, z1)
    inner = box(x0 + wall, x1 - wall, y0 + wall, y1 - wall, z0 + floor, z1 + 0.01)
    return outer - inner


def seat_bin() -> mf.Manifold:
    hx, hy, t = BIN_IN_X / 2, BIN_IN_Y / 2, BIN_WALL
    return open_box(-hx - t, hx + t, -hy - t, hy + t, -t, BIN_IN_Z, t, t)


def drawer_tray() -> mf.Manifold:
    hw = TRAY_W / 2
    return open_box(TRAY_X0, TRAY_X1, -hw, hw, TRAY_Z0, TRAY_Z1, TRAY_WALL, TRAY_WALL)


def recess_cup() -> mf.Manifold:
    outer = mf.Manifold.cylinder(CUP_DEPTH, CUP_R_OUT, CUP_R_OUT, CUP_SEGMENTS)
    inner = mf.Manifold.cylinder(CUP_DEPTH, CUP_R_IN, CUP_R_IN, CUP_SEGMENTS).translate(
        [0.0, 0.0, CUP_BOTTOM]
    )
    return outer - inner


MESHES = {
    "base_frame.stl": base_frame,
    "tower_shell.stl": tower_shell,
    "seat_bin.stl": seat_bin,
    "drawer_tray.stl": drawer_tray,
    "recess_cup.stl": recess_cup,
}


def canonical(solid: mf.Manifold) -> MeshData:
    """The solid's triangles with vertices and faces in a canonical order.

    Vertices are rounded to float32 (what STL stores), sorted lexicographically
    (x, then y, then z); each face starts at its smallest index (winding kept);
    faces are sorted. The result depends on the geometry alone, not on the
    order manifold3d happened to produce.
    """
    mesh = solid.to_mesh()
    verts = np.asarray(mesh.vert_properties, dtype=np.float32)[:, :3]
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    # merge vertices that coincide after rounding, then sort them
    uniq, inverse = np.unique(verts, axis=0, return_inverse=True)
    faces = inverse.reshape(-1)[faces]
    order = np.lexsort((uniq[:, 2], uniq[:, 1], uniq[:, 0]))
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    verts, faces = uniq[order], rank[faces]
    f0, f1, f2 = faces.T
    faces = faces[(f0 != f1) & (f1 != f2) & (f0 != f2)]
    shift = np.argmin(faces, axis=1)
    idx = (shift[:, None] + np.arange(3)[None, :]) % 3
    faces = np.take_along_axis(faces, idx, axis=1)
    faces = faces[np.lexsort((faces[:, 2], faces[:, 1], faces[:, 0]))]
    return MeshData(vertices=verts.astype(np.float64), faces=faces)


def build() -> dict[str, bytes]:
    """File name -> STL bytes of every mesh."""
    out = {}
    for name, make in MESHES.items():
        solid = make()
        if solid.status() != mf.Error.NoError or solid.is_empty():
            raise RuntimeError(f"{name}: manifold3d failed: {solid.status()}")
        out[name] = stl_bytes(canonical(solid))
    return out


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", nargs="?", type=Path, help="output folder (default: this folder)")
    parser.add_argument("--out", dest="out_opt", type=Path, help="output folder (same as OUT)")
    args = parser.parse_args(argv[1:])
    outdir = args.out_opt or args.out or Path(__file__).resolve().parent
    outdir.mkdir(parents=True, exist_ok=True)
    for name, data in build().items():
        (outdir / name).write_bytes(data)
        print(f"{outdir / name}: {(len(data) - 84) // 50} triangles")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
