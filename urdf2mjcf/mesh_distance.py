"""The figures a collision shape is judged by against its mesh, shared by the collision
pass and the certificate so that both decide by one rule.

* distances from points to a triangle surface, exact where the largest counts
  (:class:`MeshDistance`): how far a fitted primitive, a convex hull or the
  model's collision geometry sticks out of the description's surface (the
  one-sided Hausdorff distance over :data:`SAMPLES` seeded surface points);
* the volume a mesh encloses (:func:`enclosed_volume`), whatever the winding of
  its parts: a part wound inside out, or an inner shell wound outward, would
  otherwise cancel volume that is there;
* the tolerances both apply (:data:`HAUSDORFF_MM`, :data:`HAUSDORFF_REL`,
  :data:`VOLUME_RATIO`): the collision pass decomposes a mesh whose convex
  hull the certificate would fail, and the certificate's defaults are these.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import trimesh

MAX_PAIRS = 1 << 20
"""Point-triangle pairs per exact batch (a memory bound)."""

HAUSDORFF_MM = 10.0
"""Distance tolerance floor (mm), both directions: small links' hulls bridge recesses
of a few millimetres."""
HAUSDORFF_REL = 0.25
"""Distance tolerance as a fraction of the shape's size (bounding-box diagonal).
The conversion's hulls stick out by at most 0.18 of it on example-robot-data
(romeo's torso: 99 mm of 560 mm; 418 links of 26 robots measured)."""
VOLUME_RATIO = (0.5, 5.0)
"""Allowed (low, high) collision volume / enclosed source volume. Hulls and
decompositions of solid parts enclose 1.0-3.0 times their mesh; a hull 5 times
its mesh fills a hollow part (a tube, an open shell) that other parts reach into;
half the volume is geometry lost."""
SAMPLES = 1000
"""Surface points a collision shape is sampled at (seeded: deterministic)."""
SEED = 0


def distance_tolerance(
    size_m: float, hausdorff_mm: float = HAUSDORFF_MM, hausdorff_rel: float = HAUSDORFF_REL
) -> float:
    """The distance tolerance (m) of a shape ``size_m`` across (bounding-box diagonal)."""
    return max(hausdorff_mm * 1e-3, hausdorff_rel * size_m)


def sample_triangles(tri: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform by area on the triangles ``tri`` (k x 3 x 3)."""
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if area.sum() <= 0:
        return tri[:, 0][:n]
    idx = rng.choice(len(tri), size=n, p=area / area.sum())
    u, v = rng.uniform(size=n), rng.uniform(size=n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tri[idx]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])


def solid_parts(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh] | None:
    """The closed parts of ``mesh`` (its connected pieces), each wound consistently and
    outward (positive volume); None when a piece is open (its inside is undefined)."""
    import trimesh

    if not len(mesh.faces) or not mesh.is_watertight:
        return None
    pieces = mesh.split(only_watertight=False) if mesh.body_count > 1 else [mesh.copy()]
    out = []
    for piece in pieces:
        if not piece.is_watertight:
            return None
        if not piece.is_winding_consistent:
            trimesh.repair.fix_winding(piece)
        if piece.volume < 0:
            piece.invert()
        if piece.volume > 0:
            out.append(piece)
    return out


def enclosed_volume(mesh: trimesh.Trimesh) -> float | None:
    """The volume ``mesh`` encloses (m^3 for metres): the union of its closed parts,
    each taken outward (:func:`solid_parts`), by manifold3d when there are several (an
    inner shell then adds nothing, as a cavity no other part can reach); None when a
    part is open or manifold3d cannot read one."""
    parts = solid_parts(mesh)
    if parts is None:
        return None
    if len(parts) == 1:
        return float(parts[0].volume)
    solids = [to_manifold(p) for p in parts]
    if any(s is None for s in solids):
        return None
    return union_volume(solids)  # type: ignore[arg-type]


def to_manifold(part: trimesh.Trimesh) -> Any:
    """A closed, outward-wound mesh as a ``manifold3d.Manifold``; None when manifold3d
    does not take it for a solid."""
    import manifold3d

    solid = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.asarray(part.vertices, np.float32),
            tri_verts=np.asarray(part.faces, np.uint32),
        )
    )
    return None if solid.status() != manifold3d.Error.NoError or solid.is_empty() else solid


def union_volume(solids: list[Any]) -> float:
    """Volume of the union of ``manifold3d.Manifold`` solids."""
    import manifold3d

    if not solids:
        return 0.0
    return float(manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add).volume())


class MeshDistance:
    """Distances from points to the triangles ``tri`` (n x 3 x 3).

    ``upper``: the exact distance to the triangles of the few surface samples (face
    centres and points spread by area, drawn from ``rng``) nearest to each point,
    found by a k-d tree: never below the true distance, and equal to it wherever
    the nearest triangle is among them, which is nearly everywhere. ``exact``: the
    distance to every triangle whose bounding box the upper bound reaches.
    :meth:`largest` refines points in decreasing order of their upper bound until
    no remaining bound exceeds the largest exact distance, so the maximum it
    returns is exact over the points given.
    """

    def __init__(self, tri: np.ndarray, rng: np.random.Generator) -> None:
        from scipy.spatial import cKDTree

        self.tri = np.asarray(tri, dtype=np.float64)
        n = len(self.tri)
        faces = np.arange(n) if n <= 10000 else rng.choice(n, 10000, replace=False)
        area = np.linalg.norm(
            np.cross(self.tri[:, 1] - self.tri[:, 0], self.tri[:, 2] - self.tri[:, 0]), axis=1
        )
        spread = rng.choice(n, 2000, p=area / area.sum()) if area.sum() > 0 else faces[:0]
        self.face = np.concatenate([faces, spread])
        uv = rng.uniform(size=(len(spread), 2))
        flip = uv.sum(axis=1) > 1
        uv[flip] = 1 - uv[flip]
        t = self.tri[spread]
        on = t[:, 0] + uv[:, :1] * (t[:, 1] - t[:, 0]) + uv[:, 1:] * (t[:, 2] - t[:, 0])
        self.tree = cKDTree(np.vstack([self.tri[faces].mean(axis=1), on]))
        self._boxes: tuple[np.ndarray, np.ndarray] | None = None

    def upper(self, points: np.ndarray) -> np.ndarray:
        from trimesh.triangles import closest_point

        k = min(4, len(self.face))
        idx = np.asarray(self.tree.query(points, k=k)[1]).reshape(len(points), k)
        fi = self.face[idx].ravel()
        pts = np.repeat(points, k, axis=0)
        d = np.linalg.norm(closest_point(self.tri[fi], pts) - pts, axis=1)
        return d.reshape(len(points), k).min(axis=1)

    def exact(self, points: np.ndarray, bound: np.ndarray) -> np.ndarray:
        from trimesh.triangles import closest_point

        if self._boxes is None:
            self._boxes = (self.tri.min(axis=1), self.tri.max(axis=1))
        lo, hi = self._boxes
        out = bound.astype(np.float64).copy()
        step = max(1, MAX_PAIRS // max(1, len(self.tri)))
        for start in range(0, len(points), step):
            p = points[start : start + step]
            # Only triangles whose bounding box the bound reaches can be nearer.
            gap = np.maximum(np.maximum(lo[None] - p[:, None], p[:, None] - hi[None]), 0.0)
            near = (gap**2).sum(axis=2) <= (out[start : start + step, None] ** 2) + 1e-18
            pi, fi = np.nonzero(near)
            if not len(pi):
                continue
            d = np.linalg.norm(closest_point(self.tri[fi], p[pi]) - p[pi], axis=1)
            best = np.full(len(p), np.inf)
            np.minimum.at(best, pi, d)
            out[start : start + step] = np.minimum(out[start : start + step], best)
        return out

    def largest(self, points: np.ndarray) -> float:
        """The largest distance from ``points`` to the surface, exact over the points."""
        bounds = self.upper(points)
        order = np.argsort(-bounds, kind="stable")
        best = 0.0
        step = 8  # the first few points nearly always hold the maximum
        for lo in range(0, len(order), step):
            idx = order[lo : lo + step]
            step = min(64, 2 * step)
            if bounds[idx[0]] <= best:  # nothing left can be farther
                break
            best = max(best, float(self.exact(points[idx], bounds[idx]).max()))
        return best
