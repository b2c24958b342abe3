"""Distances from points to a triangle surface, exact where the largest counts.

Shared by the primitive fits (how far a fitted box or capsule lies from its mesh)
and the certificate (how far the collision geometry lies from the description's).
"""

from __future__ import annotations

import numpy as np

MAX_PAIRS = 1 << 20
"""Point-triangle pairs per exact batch (a memory bound)."""


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
