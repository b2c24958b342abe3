"""Solids as descriptions give them, URDF's primitives and triangle meshes, placed in
one frame: their surfaces sampled, distances to them, and how deep two overlap.

Shared by the certificate (its collision figures, and whether an overlap at home is
the description's) and the contacts pass (whether a contact at home is one the
conversion added), so that the two judge an overlap by the same measure.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .mesh_distance import SEED, MeshDistance, sample_triangles

if TYPE_CHECKING:
    import trimesh

OVERLAP_SAMPLES = 500
"""Surface points per solid when measuring how deep two solids overlap."""
PENETRATION_M = 0.01
"""Two bodies' collision geoms deeper in each other than this at home are an overlap:
soft contacts settle within millimetres, and a hull bridging a joint's clearance
reaches a few millimetres on real arms. The certificate flags such an overlap where
the description's shapes do not have it; the contacts pass excludes those it made."""


@dataclass
class Primitive:
    """A box, sphere, cylinder, capsule or ellipsoid in MuJoCo's terms (half sizes)."""

    kind: str
    size: np.ndarray
    pose: np.ndarray  # 4x4, link <- shape

    def local(self, points: np.ndarray) -> np.ndarray:
        inv = np.linalg.inv(self.pose)
        return points @ inv[:3, :3].T + inv[:3, 3]

    def sdf(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (negative inside); exact but for the ellipsoid."""
        p = self.local(points)
        s = self.size
        if self.kind == "sphere":
            return np.linalg.norm(p, axis=1) - s[0]
        if self.kind == "box":
            q = np.abs(p) - s[:3]
            return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
        if self.kind == "cylinder":
            q = np.stack([np.linalg.norm(p[:, :2], axis=1) - s[0], np.abs(p[:, 2]) - s[1]], 1)
            return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
        if self.kind == "capsule":
            axis = np.zeros_like(p)
            axis[:, 2] = np.clip(p[:, 2], -s[1], s[1])
            return np.linalg.norm(p - axis, axis=1) - s[0]
        if self.kind == "ellipsoid":  # scaled sphere distance: a bound, good near the surface
            return (np.linalg.norm(p / s[:3], axis=1) - 1.0) * s[:3].min()
        raise AssertionError(self.kind)

    def area_volume(self) -> tuple[float, float]:
        s = self.size
        if self.kind == "sphere":
            return 4 * np.pi * s[0] ** 2, 4 / 3 * np.pi * s[0] ** 3
        if self.kind == "box":
            x, y, z = 2 * s[:3]
            return 2 * (x * y + y * z + x * z), x * y * z
        if self.kind == "cylinder":
            r, h = s[0], s[1]
            return 2 * np.pi * r * 2 * h + 2 * np.pi * r**2, np.pi * r**2 * 2 * h
        if self.kind == "capsule":
            r, h = s[0], s[1]
            return 4 * np.pi * r * h + 4 * np.pi * r**2, np.pi * r**2 * 2 * h + 4 / 3 * np.pi * r**3
        a, b, c = s[:3]  # ellipsoid: Knud Thomsen's area formula
        p = 1.6075
        area = 4 * np.pi * (((a * b) ** p + (a * c) ** p + (b * c) ** p) / 3) ** (1 / p)
        return area, 4 / 3 * np.pi * a * b * c

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` points uniform by area on the exact surface (the ellipsoid's: nearly)."""
        s = self.size
        if self.kind in ("sphere", "ellipsoid"):
            u = rng.normal(size=(n, 3))
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            p = u * (s[:3] if self.kind == "ellipsoid" else s[0])
        elif self.kind == "box":
            h = s[:3]
            areas = np.array([h[1] * h[2], h[0] * h[2], h[0] * h[1]])
            axis = rng.choice(3, size=n, p=areas / areas.sum())
            p = rng.uniform(-1, 1, size=(n, 3)) * h
            side = rng.choice([-1.0, 1.0], size=n)
            p[np.arange(n), axis] = side * h[axis]
        else:  # cylinder, capsule: side or ends
            r, h = s[0], s[1]
            cap = 2 * np.pi * r**2 if self.kind == "cylinder" else 4 * np.pi * r**2
            side_area = 4 * np.pi * r * h
            on_side = rng.uniform(size=n) < side_area / (side_area + cap)
            p = np.empty((n, 3))
            t = rng.uniform(0, 2 * np.pi, size=n)
            p[:, 0], p[:, 1] = r * np.cos(t), r * np.sin(t)
            p[:, 2] = rng.uniform(-h, h, size=n)
            ends = ~on_side
            k = int(ends.sum())
            sign = rng.choice([-1.0, 1.0], size=k)
            if self.kind == "cylinder":
                rad = r * np.sqrt(rng.uniform(size=k))
                t2 = rng.uniform(0, 2 * np.pi, size=k)
                p[ends] = np.stack([rad * np.cos(t2), rad * np.sin(t2), sign * h], 1)
            else:
                u = rng.normal(size=(k, 3))
                u /= np.linalg.norm(u, axis=1, keepdims=True)
                u[:, 2] = np.abs(u[:, 2]) * sign
                p[ends] = u * r + np.outer(sign, [0, 0, h])
        return p @ self.pose[:3, :3].T + self.pose[:3, 3]

    def cloud(self) -> np.ndarray:
        """Points whose hull is the shape, within 0.2 % of its size (for unions)."""
        import trimesh

        s = self.size
        if self.kind == "box":
            mesh = trimesh.creation.box(extents=2 * s[:3])
        elif self.kind in ("sphere", "ellipsoid"):
            mesh = trimesh.creation.icosphere(subdivisions=3)
            mesh.apply_scale(s[:3] if self.kind == "ellipsoid" else s[0])
        elif self.kind == "cylinder":
            mesh = trimesh.creation.cylinder(radius=s[0], height=2 * s[1], sections=48)
        else:
            mesh = trimesh.creation.capsule(height=2 * s[1], radius=s[0], count=[24, 24])
        v = np.asarray(mesh.vertices)
        return v @ self.pose[:3, :3].T + self.pose[:3, 3]


@dataclass
class Hull:
    """A convex polytope (a mesh geom as MuJoCo collides with it)."""

    points: np.ndarray
    faces: np.ndarray = field(init=False)
    planes: np.ndarray = field(init=False)  # (k, 4): unit normal, offset; n.p <= d inside
    volume: float = field(init=False)
    area: float = field(init=False)

    def __post_init__(self) -> None:
        from scipy.spatial import ConvexHull

        h = ConvexHull(self.points)
        self.faces = h.simplices
        # qhull splits each face into triangles: one plane per face is enough
        planes = np.column_stack([h.equations[:, :3], -h.equations[:, 3]])
        self.planes = np.unique(np.round(planes, 9), axis=0)
        self.volume = float(h.volume)
        self.area = float(h.area)

    def sdf(self, points: np.ndarray) -> np.ndarray:
        """Largest face-plane distance: exact inside, a lower bound outside."""
        return (points @ self.planes[:, :3].T - self.planes[:, 3]).max(axis=1)

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return sample_triangles(self.points[self.faces], n, rng)


SourcePart = Primitive | MeshDistance
"""What a distance is measured to: a primitive exactly, a mesh by :class:`MeshDistance`."""


def largest_distance(parts: Sequence[SourcePart], points: np.ndarray) -> float:
    """Largest distance from ``points`` to the union of the parts' surfaces (exact
    over the points: refined in decreasing order of an upper bound)."""
    bounds = np.full(len(points), np.inf)
    for part in parts:
        d = np.abs(part.sdf(points)) if isinstance(part, Primitive) else part.upper(points)
        bounds = np.minimum(bounds, d)
    order = np.argsort(-bounds, kind="stable")
    best = 0.0
    for lo in range(0, len(order), 32):
        idx = order[lo : lo + 32]
        if bounds[idx[0]] <= best + 1e-9:  # nothing left can be farther
            break
        exact = bounds[idx].copy()
        for part in parts:
            if isinstance(part, MeshDistance):
                exact = np.minimum(exact, part.exact(points[idx], exact))
        best = max(best, float(exact.max()))
    return best


def sample_union(shapes: Sequence[Any], n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points spread by area over the surfaces of ``shapes`` (primitives, and
    anything else with an ``area`` and a ``sample(n, rng)``)."""
    areas = np.array([s.area_volume()[0] if isinstance(s, Primitive) else s.area for s in shapes])
    if not areas.sum() > 0:
        raise ValueError("collision shapes without surface")
    counts = np.floor(n * areas / areas.sum()).astype(int)
    counts[np.argmax(areas)] += n - counts.sum()
    return np.vstack([s.sample(int(c), rng) for s, c in zip(shapes, counts, strict=True) if c])


@dataclass
class Placed:
    """One link's solids placed in a common frame, with what measuring depths into them
    needs (built once per link: several pairs share a link)."""

    prims: list[Primitive]
    meshes: list[trimesh.Trimesh]
    distances: list[MeshDistance] = field(default_factory=list)

    @classmethod
    def of(
        cls, prims: Sequence[Primitive], meshes: Sequence[trimesh.Trimesh], pose: np.ndarray
    ) -> Placed:
        """The link's ``prims`` and ``meshes`` (in the link frame), placed by ``pose``."""
        moved = []
        for mesh in meshes:
            mesh = mesh.copy()
            mesh.apply_transform(pose)
            moved.append(mesh)
        placed = [Primitive(p.kind, p.size, pose @ p.pose) for p in prims]
        rng = np.random.default_rng(SEED)
        return cls(placed, moved, [MeshDistance(x.triangles, rng) for x in moved])

    def bounds(self) -> np.ndarray | None:
        clouds = [p.cloud() for p in self.prims] + [np.asarray(x.vertices) for x in self.meshes]
        if not clouds:
            return None
        pts = np.vstack(clouds)
        return np.array([pts.min(axis=0), pts.max(axis=0)])

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        pts = [sample_union(self.prims, n, rng)] if self.prims else []
        pts += [sample_triangles(np.asarray(x.triangles), n, rng) for x in self.meshes]
        return np.vstack(pts)

    def depth(self, points: np.ndarray) -> float:
        """Largest depth of ``points`` inside the shape (0 when none is inside): primitives
        exactly; meshes by trimesh's ray containment test and the distance to their
        surface (the largest exactly, as the collision figures' distances)."""
        depth = 0.0
        for p in self.prims:
            depth = max(depth, float(np.max(-p.sdf(points), initial=0.0)))
        for mesh, dist in zip(self.meshes, self.distances, strict=True):
            inside = contains(mesh, points)
            if inside.any():
                depth = max(depth, largest_distance([dist], points[inside]))
        return depth


RAY_DIRECTIONS = (
    np.array([0.4395064455, 0.617598629942, 0.652231566745]),  # trimesh's own first ray
    np.array([-0.5773502692, 0.5773502692, 0.7071067812]),
    np.array([0.7071067812, -0.3826834324, 0.5947527]),
)
"""Fixed ray directions of :func:`contains` (normalised where used)."""


def contains(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Which ``points`` lie inside ``mesh``, by ray parity as trimesh's ``contains``, but
    deterministic: trimesh casts a *random* ray for a point whose two rays disagree (one
    grazing an edge), so the same model could be judged differently run to run (iCub's
    hip against its thigh: 20 mm deep in one run, excluded in the next). Here each point
    is cast both ways along fixed directions in turn until the two agree (or one meets
    nothing: outside); a point no direction settles takes the first direction's parity."""
    from trimesh import bounds

    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(points), dtype=bool)
    todo = np.flatnonzero(bounds.contains(mesh.bounds, points))
    first: np.ndarray | None = None
    for direction in RAY_DIRECTIONS:
        if not len(todo):
            break
        d = np.tile(direction / np.linalg.norm(direction), (len(todo), 1))
        pts = points[todo]
        _loc, index_ray, _tri = mesh.ray.intersects_location(
            np.vstack((pts, pts)), np.vstack((d, -d)), multiple_hits=True
        )
        hits = np.bincount(index_ray, minlength=2 * len(todo)).reshape(2, -1)
        odd = hits % 2 == 1
        settled = (odd[0] == odd[1]) | (hits == 0).any(axis=0)
        if first is None:
            first = np.zeros(len(points), dtype=bool)
            first[todo] = odd[0]
        out[todo[settled]] = odd[0][settled] & odd[1][settled]
        todo = todo[~settled]
    if len(todo) and first is not None:
        out[todo] = first[todo]
    return out


TOUCHING_M = 5e-4
"""Sampled points no deeper than this inside a solid count as touching it, not in it."""
SEPARATION_STEPS = 6
"""Bisections of the separating distance along a direction (to 1/64 of the range)."""


def overlap_depth(
    a: Placed,
    b: Placed,
    samples: int = OVERLAP_SAMPLES,
    along: np.ndarray | None = None,
    limit: float | None = None,
    near: tuple[Primitive | Hull, Primitive | Hull] | None = None,
) -> float:
    """How deep two placed solids overlap (m): the deepest of either surface's sampled
    points inside the other; 0 when their bounding boxes are apart.

    With ``along`` (a direction that separates ``b`` from ``a``: MuJoCo's contact normal
    from ``a``'s geom to ``b``'s), ``limit`` and ``near`` (those two convex geoms, in the
    same frame), also how far ``b`` must move along it before no sampled point of
    either, within its geom, lies inside the other within that one's geom (bisected,
    up to ``limit``), whichever is larger. That is what MuJoCo's penetration depth of
    the two geoms measures, and what the deepest point undercuts where one solid
    pierces a thin other: a finger through a 10 mm plate lies at most 5 mm inside it,
    however far it reaches beyond it. Kept within the two geoms, the test is about the
    contact's own place: a link in its neighbour's clevis, moved along the normal,
    would reach the clevis's other cheek, which is no part of this overlap."""
    ba, bb = a.bounds(), b.bounds()
    if ba is None or bb is None or (ba[0] > bb[1]).any() or (bb[0] > ba[1]).any():
        return 0.0
    rng = np.random.default_rng(SEED)
    on_a, on_b = a.sample(samples, rng), b.sample(samples, rng)
    depth = max(b.depth(on_a), a.depth(on_b))
    if along is None or limit is None or near is None or depth <= TOUCHING_M:
        return depth
    n = np.asarray(along, dtype=np.float64)
    n = n / np.linalg.norm(n)
    geom_a, geom_b = near
    local_a = on_a[geom_a.sdf(on_a) <= TOUCHING_M]
    local_b = on_b[geom_b.sdf(on_b) <= TOUCHING_M]

    def overlapping(t: float) -> bool:
        moved_b = local_b + t * n  # b's points near the contact, moved, within a's geom
        moved_b = moved_b[geom_a.sdf(moved_b) < 0]
        back_a = local_a - t * n  # and a's, seen from b moved: within b's geom
        back_a = back_a[geom_b.sdf(back_a) < 0]
        inside = [a.depth(moved_b)] if len(moved_b) else []
        inside += [b.depth(back_a)] if len(back_a) else []
        return max(inside, default=0.0) > TOUCHING_M

    lo, hi = depth, max(limit, depth)
    if not overlapping(lo):
        return depth
    if overlapping(hi):
        return hi
    for _ in range(SEPARATION_STEPS):
        mid = 0.5 * (lo + hi)
        if overlapping(mid):
            lo = mid
        else:
            hi = mid
    return hi


def geom_solid(m: Any, d: Any, g: int, frame: np.ndarray | None = None) -> Primitive | Hull | None:
    """MuJoCo geom ``g`` as it collides (a mesh: its vertices' hull) where ``d`` puts it,
    in ``frame`` (4x4 world <- frame; None: the world); None for a plane, height field
    or SDF."""
    import mujoco

    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = np.asarray(d.geom_xmat[g]).reshape(3, 3), d.geom_xpos[g]
    if frame is not None:
        pose = np.linalg.inv(frame) @ pose
    kind = int(m.geom_type[g])
    types = mujoco.mjtGeom
    if kind == types.mjGEOM_MESH:
        mid = int(m.geom_dataid[g])
        adr, num = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
        v = np.asarray(m.mesh_vert[adr : adr + num], dtype=np.float64)
        try:
            return Hull(v @ pose[:3, :3].T + pose[:3, 3])
        except Exception:  # qhull: a flat or degenerate mesh
            return None
    names = {
        types.mjGEOM_SPHERE: "sphere",
        types.mjGEOM_CAPSULE: "capsule",
        types.mjGEOM_ELLIPSOID: "ellipsoid",
        types.mjGEOM_CYLINDER: "cylinder",
        types.mjGEOM_BOX: "box",
    }
    if kind in names:
        return Primitive(names[kind], np.array(m.geom_size[g], dtype=np.float64), pose)
    return None
