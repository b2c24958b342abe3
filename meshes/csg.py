"""Constructive solid geometry helpers for the scripts that make our meshes.

Solids are manifold3d ``Manifold``s built from intervals (``box((x0, x1),
(y0, y1), (z0, z1))``); files are binary STL written by
:func:`urdf2mjcf.assets.stl_bytes`, so a script gives the same bytes on
every run.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
from manifold3d import Manifold

from urdf2mjcf.assets import stl_bytes
from urdf2mjcf.ir import MeshData

Interval = tuple[float, float]
SEGMENTS = 64
"""Facets of every round part."""


def box(x: Interval, y: Interval, z: Interval) -> Manifold:
    return Manifold.cube((x[1] - x[0], y[1] - y[0], z[1] - z[0])).translate((x[0], y[0], z[0]))


def cylinder_z(
    radius: float, z: Interval, xy: tuple[float, float] = (0.0, 0.0), segments: int = SEGMENTS
) -> Manifold:
    return Manifold.cylinder(z[1] - z[0], radius, radius, segments).translate((xy[0], xy[1], z[0]))


def cylinder_x(radius: float, x: Interval, yz: tuple[float, float]) -> Manifold:
    # a z cylinder turned onto +x (rotation about y by 90 degrees: z -> x)
    return (
        Manifold.cylinder(x[1] - x[0], radius, radius, SEGMENTS)
        .rotate((0.0, 90.0, 0.0))
        .translate((x[0], yz[0], yz[1]))
    )


def cylinder_y(radius: float, y: Interval, xz: tuple[float, float]) -> Manifold:
    # a z cylinder turned onto +y (rotation about x by -90 degrees: z -> y)
    return (
        Manifold.cylinder(y[1] - y[0], radius, radius, SEGMENTS)
        .rotate((-90.0, 0.0, 0.0))
        .translate((xz[0], y[0], xz[1]))
    )


def mesh_bytes(solid: Manifold) -> bytes:
    """Binary STL of a solid, in manifold3d's own vertex and triangle order."""
    mesh = solid.to_mesh()
    vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    return stl_bytes(MeshData(vertices, faces))


def write_meshes(
    meshes: Mapping[str, Callable[[], Manifold]],
    default_out: Path,
    argv: list[str] | None,
    doc: str,
) -> None:
    """The command line of a mesh script: ``[--out DIR]``, every mesh written there."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--out", type=Path, default=default_out)
    out = parser.parse_args(argv).out
    out.mkdir(parents=True, exist_ok=True)
    for name, make in meshes.items():
        (out / name).write_bytes(mesh_bytes(make()))
