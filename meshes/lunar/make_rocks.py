"""Generate the rock meshes of the MIRA3D lunar world.

    python meshes/lunar/make_rocks.py [--out DIR]     (default: this folder)

``rock_0.stl`` ... ``rock_4.stl``: five convex boulders, each the convex hull
(manifold3d) of 48 seeded random points on a squashed, dented ellipsoid.
Every rock is 1 m across its largest horizontal dimension's scale (points
within a 0.5 m radius of its origin, 0.6 m tall at most), with its origin at
its centre: the world xacro scales a rock by its size in metres and sinks it
into the ground by a third of its height. Convex on purpose: the compiler
uses a convex mesh as its own collision shape (no decomposition).

Output is deterministic: one seeded generator, binary STL with a zeroed
header (urdf2mjcf.assets.stl_bytes).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from manifold3d import Manifold

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # meshes/csg.py
from csg import write_meshes  # noqa: E402

ROCKS = 5
POINTS = 48
SEED = 15  # Apollo 15


def rock(index: int) -> Manifold:
    rng = np.random.default_rng([SEED, index])
    # directions spread over the sphere, radii dented by up to 25 %
    d = rng.normal(size=(POINTS, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    radii = 1.0 - 0.25 * rng.random(POINTS)
    axes = np.array([0.5, rng.uniform(0.32, 0.5), rng.uniform(0.2, 0.3)])
    points = d * radii[:, None] * axes
    return Manifold.hull_points(points.tolist())


MESHES = {f"rock_{i}.stl": (lambda i=i: rock(i)) for i in range(ROCKS)}


def main(argv: list[str] | None = None) -> None:
    write_meshes(MESHES, Path(__file__).resolve().parent, argv, __doc__)


if __name__ == "__main__":
    main()
