"""How far a mesh is from its convex hull: the test that decides hull or decomposition.

The measure is the **hull gap**: the mean distance from points spread evenly
over the surface of the convex hull to the surface of the mesh, divided by
the diagonal of the mesh's bounding box. It is 0 for a convex mesh and grows
with the depth and extent of the pockets the hull bridges.

It needs only surfaces, not a volume, so it works the same for watertight
meshes, meshes with holes or cracks, triangle soups, assemblies of
overlapping bodies and meshes with inverted faces, which make up a third to
a half of the meshes in real robot descriptions. Unlike the volume ratio (mesh
volume / hull volume) it does not call a hollow housing or a shell concave:
their hidden inner space makes no difference to what can touch them.

Measured on the 374 distinct collision meshes of example-robot-data (249
watertight): ``hull gap > 0.02`` and ``volume ratio < 0.6`` agree on 228 of
the 249 watertight meshes. Where they disagree, the gap calls long bent links
(L-shaped elbows, dog-leg forearms, volume ratio 0.63-0.76) concave and thin
straight links with a thicker end (volume ratio 0.48-0.58) convex, and it keeps
hollow bodies whole (hyq's upper leg: volume ratio 0.20, gap 0.017).
Half of the meshes measure below 0.01 and 75% below 0.02; motor brackets,
U-shaped forks and gripper jaws measure 0.024-0.034. The cost is about
20-80 ms a mesh.

A hull that passes the gap must also pass the certificate's own figures
(:class:`HullFigures`, by :mod:`urdf2mjcf.mesh_distance`'s rule and
tolerances): the hull's volume over the volume the mesh encloses, and how far
the hull's surface sticks out of the mesh's (the one-sided Hausdorff
distance). A thin shell passes the gap, since its hull's surface lies on the
shell, but not the volume: the tubes of a telescoping arm measure a hull 9-40
times their volume, which the nested tubes reach into; they are decomposed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...ir import MeshData
from ...mesh_distance import (
    SAMPLES,
    SEED,
    VOLUME_RATIO,
    MeshDistance,
    distance_tolerance,
    enclosed_volume,
    sample_triangles,
)

if TYPE_CHECKING:
    import trimesh

HULL_SAMPLES = 3000
"""Points spread over the hull surface (about; every hull triangle gets one)."""
MESH_SAMPLES = 20000
"""Points spread over the mesh surface to find candidate nearest triangles."""
CANDIDATES = 8
"""Nearest mesh samples whose triangles are measured exactly for each hull point."""
FLAT_VOLUME = 1e-9
"""A hull whose volume is below this fraction of diagonal**3 counts as flat."""


@dataclass(frozen=True, eq=False)
class HullFit:
    hull: MeshData | None
    """The convex hull, outward-facing; None when the mesh is flat or degenerate."""
    gap: float
    """Mean hull-to-mesh surface distance / bounding-box diagonal (0 when flat)."""
    diagonal: float
    """Bounding-box diagonal of the mesh, metres."""


@dataclass(frozen=True)
class HullFigures:
    """A convex hull measured against its mesh as the certificate measures a link."""

    volume_ratio: float | None
    """Hull volume / the volume the mesh encloses; None when the mesh is open."""
    hausdorff_m: float
    """Largest distance from the hull's surface to the mesh's, over
    :data:`~urdf2mjcf.mesh_distance.SAMPLES` seeded points of the hull."""
    diagonal_m: float
    """Bounding-box diagonal of the mesh: what the distance tolerance scales with."""

    @property
    def hollow(self) -> bool:
        """The hull encloses more than the largest volume ratio: a tube, an open shell."""
        return self.volume_ratio is not None and self.volume_ratio > VOLUME_RATIO[1]

    def failure(self) -> str | None:
        """Why the certificate would fail this hull (None: it would pass)."""
        limit = distance_tolerance(self.diagonal_m)
        if self.hollow:
            return f"hull volume {self.volume_ratio:.3g} x the mesh's: a hollow part"
        if self.volume_ratio is not None and self.volume_ratio < VOLUME_RATIO[0]:
            return f"hull volume {self.volume_ratio:.3g} x the mesh's"
        if self.hausdorff_m > limit:
            return (
                f"hull sticks out {self.hausdorff_m * 1e3:.1f} mm from the mesh "
                f"(tolerance {limit * 1e3:.1f} mm)"
            )
        return None


def hull_figures(mesh: trimesh.Trimesh, hull: MeshData) -> HullFigures:
    """:class:`HullFigures` of ``hull`` against ``mesh`` (deterministic: seeded)."""
    rng = np.random.default_rng(SEED)
    distance = MeshDistance(np.asarray(mesh.triangles, dtype=np.float64), rng)
    points = sample_triangles(hull.vertices[hull.faces], SAMPLES, rng)
    volume = enclosed_volume(mesh)
    hull_volume = abs(signed_volume(hull.vertices, hull.faces))
    ratio = hull_volume / volume if volume is not None and volume > 0 else None
    diagonal = float(np.linalg.norm(mesh.extents)) if len(mesh.vertices) else 0.0
    return HullFigures(
        volume_ratio=None if ratio is None else float(ratio),
        hausdorff_m=float(distance.largest(points)),
        diagonal_m=diagonal,
    )


def as_trimesh(mesh: MeshData) -> trimesh.Trimesh:
    """A processed trimesh (duplicate vertices merged), deterministic for given arrays."""
    import trimesh

    return trimesh.Trimesh(
        vertices=np.asarray(mesh.vertices, dtype=np.float64),
        faces=np.asarray(mesh.faces, dtype=np.int64),
        process=True,
    )


def convex_hull(vertices: np.ndarray) -> MeshData | None:
    """Outward-facing convex hull of points, or None when they span no volume."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(vertices, dtype=np.float64)
    if len(pts) < 4:
        return None
    extent = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    if extent == 0.0:
        return None
    try:
        qhull = ConvexHull(pts)
    except (QhullError, ValueError):
        return None
    used = np.unique(qhull.simplices)
    index = np.zeros(len(pts), dtype=np.int64)
    index[used] = np.arange(len(used))
    hull_vertices = pts[used]
    faces = index[qhull.simplices].astype(np.int64)
    # qhull winds simplices at random: turn each to agree with its outward plane normal
    a, b, c = (hull_vertices[faces[:, i]] for i in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), qhull.equations[:, :3]) < 0
    faces[inward] = faces[inward][:, ::-1]
    if abs(signed_volume(hull_vertices, faces)) <= FLAT_VOLUME * extent**3:
        return None
    return MeshData(vertices=hull_vertices, faces=np.ascontiguousarray(faces))


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Enclosed volume, positive when the faces wind counter-clockwise seen from outside."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def hull_fit(mesh: trimesh.Trimesh) -> HullFit:
    """Hull of a trimesh and its :attr:`HullFit.gap` (deterministic: fixed seeds)."""
    import trimesh
    from scipy.spatial import cKDTree

    diagonal = float(np.linalg.norm(mesh.extents)) if len(mesh.vertices) else 0.0
    hull = convex_hull(mesh.vertices)
    if hull is None or len(mesh.faces) == 0:
        return HullFit(hull=None, gap=0.0, diagonal=diagonal)
    on_hull, weight = _stratified_points(hull, HULL_SAMPLES)
    on_mesh, face_of = trimesh.sample.sample_surface(mesh, MESH_SAMPLES, seed=1)
    k = min(CANDIDATES, len(on_mesh))
    _, nearest = cKDTree(on_mesh).query(on_hull, k=k)
    nearest = np.asarray(nearest).reshape(len(on_hull), k)
    triangles = mesh.triangles[face_of[nearest]].reshape(-1, 3, 3)
    points = np.repeat(on_hull, k, axis=0)
    closest = trimesh.triangles.closest_point(triangles, points)
    dist = np.linalg.norm(closest - points, axis=1).reshape(len(on_hull), k).min(axis=1)
    gap = float(np.dot(dist, weight) / weight.sum()) / diagonal
    return HullFit(hull=hull, gap=gap, diagonal=diagonal)


_PLASTIC = 1.32471795724474602596
"""The plastic number: generator of the R2 low-discrepancy sequence."""


def _stratified_points(mesh: MeshData, count: int) -> tuple[np.ndarray, np.ndarray]:
    """About ``count`` points spread evenly over a surface, and the area each stands for.

    Each triangle gets points in proportion to its area (at least one), laid
    out by the R2 low-discrepancy sequence: far less noisy than random
    sampling, so a mesh and its mirror image measure the same to ~0.5%.
    """
    tri = mesh.vertices[mesh.faces]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    per_face = np.maximum(1, np.round(count * area / area.sum()).astype(np.int64))
    k = np.arange(per_face.max()) + 0.5
    uv = np.stack([(k / _PLASTIC) % 1.0, (k / _PLASTIC**2) % 1.0], axis=1)
    outside = uv.sum(axis=1) > 1.0
    uv[outside] = 1.0 - uv[outside]  # fold the unit square onto the triangle
    face = np.repeat(np.arange(len(tri)), per_face)
    j = np.arange(len(face)) - np.repeat(np.cumsum(per_face) - per_face, per_face)
    points = tri[face, 0] + uv[j, :1] * e1[face] + uv[j, 1:] * e2[face]
    return points, (area / per_face)[face]


def flat_box(vertices: np.ndarray, min_thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """Smallest box around flat (or collinear) points.

    Returns its (4, 4) pose in the mesh frame and its (3,) full sizes.

    The box's z axis is the plane normal; in the plane it is the minimum-area
    rectangle. Every size is at least ``min_thickness`` so MuJoCo gets a solid.
    """
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(vertices, dtype=np.float64)
    centre = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - centre, full_matrices=True)
    axes = vt.copy()  # rows: in-plane, in-plane, normal
    if np.linalg.det(axes) < 0:
        axes[2] *= -1.0
    flat = (pts - centre) @ axes[:2].T
    try:
        ring = flat[ConvexHull(flat).vertices]
    except (QhullError, ValueError):  # collinear or a single point
        ring = flat
    best = (np.inf, np.eye(2))
    for i in range(len(ring)):
        edge = ring[(i + 1) % len(ring)] - ring[i]
        length = float(np.hypot(*edge))
        if length == 0.0:
            continue
        u = edge / length
        rot = np.array([u, [-u[1], u[0]]])
        proj = ring @ rot.T
        area = float(np.prod(proj.max(axis=0) - proj.min(axis=0)))
        if area < best[0] - 1e-15:
            best = (area, rot)
    rot2 = best[1]
    frame = np.eye(3)
    frame[:2] = rot2 @ axes[:2]
    frame[2] = axes[2]
    local = (pts - centre) @ frame.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    pose = np.eye(4)
    pose[:3, :3] = frame.T
    pose[:3, 3] = centre + frame.T @ (0.5 * (lo + hi))
    sizes = np.maximum(hi - lo, min_thickness)
    return pose, sizes
