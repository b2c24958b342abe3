"""MuJoCo primitives fitted to a collision mesh, and how far each fit is from it.

Every fit encloses the mesh (all vertices inside or on it) and is the tightest
of its kind that this module finds: the minimum enclosing sphere, trimesh's
minimum-volume oriented box, and a cylinder and a capsule around the best of a
few candidate axes (the hull's principal axes, the box's axes). An elongated
mesh also gets sets of 2 and 3 capsules or boxes, one per slab along its long
axis.

The deviation uses the collision certificate's definitions
(``urdf2mjcf/certify/collision.py``) so that the pass and the certificate agree:

* ``hausdorff_m``: the one-sided Hausdorff distance from the fits' surfaces
  (every fit's whole surface, as the certificate samples each geom; in a set
  the faces inside a neighbour count too) to the mesh surface, the largest
  over deterministic samples that include the corners, rims and poles where a
  primitive sticks out most; exact over those points.
* ``uncovered_m``: the largest distance by which a mesh vertex lies outside
  every fit (0 for the enclosing fits made here).
* ``volume_ratio``: the union volume of the fits over the volume the mesh
  encloses (as the certificate takes it:
  :func:`~urdf2mjcf.mesh_distance.enclosed_volume`); the volume of the mesh's
  convex hull when the mesh is not watertight (a soup has no inside).

Measured on the collision meshes of example-robot-data: see :data:`TOLERANCE_MM`
and :data:`MAX_VOLUME_RATIO`. Cost: all candidates of a 4,000-6,000-face mesh
take 0.16 s CPU (median of 37; at most 0.5 s), most of it trimesh's
minimum-volume box search and the exact distances.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np

from ...mesh_distance import MeshDistance, enclosed_volume
from .convexity import convex_hull, signed_volume

Kind = Literal["sphere", "capsule", "cylinder", "box"]
KINDS: tuple[Kind, ...] = ("sphere", "capsule", "cylinder", "box")
"""Cheapest contact first. In MuJoCo's collision table the sphere and the capsule
have closed-form functions against every primitive but the cylinder (the
capsule) and make 1 (sphere) or up to 2 (capsule) contacts. A cylinder has
closed forms against planes and spheres only, the rest going through the
general convex solver, which makes one contact. A box has closed forms, but
box-box, the usual pair between boxy links, is the costliest of them and makes
up to 8 contacts (box-plane 4), each a row of the constraint solver: last."""

_COST: dict[str, float] = {"sphere": 1.0, "capsule": 1.5, "cylinder": 2.0, "box": 2.5}
"""Relative contact cost per kind, in the order of :data:`KINDS`."""

TOLERANCE_MM = 5.0
"""Default tolerance (mm) on ``hausdorff_m`` and ``uncovered_m`` for accepting a fit.

Measured with :func:`candidates` on the 381 distinct (mesh file, scale) pairs
referenced by ``<collision>`` elements of example-robot-data (all give
candidates; 130 are elongated and also get sets). At 5 mm and
:data:`MAX_VOLUME_RATIO` 1.75, 26 (6.8%) get a primitive: 16 cylinders, 7
boxes, 2 spheres, 1 capsule; nearly all are meshes that already are
primitives (iCub's simplified collision shapes, solo's and bolt's feet, g1's
thumb boxes). The worst accepted fit sticks out 4.2 mm (romeo's fingertip
capsule, 13% of its 32 mm size, volume 1.54x). Looser limits mostly admit
worse fits of small parts: 7.5 mm gives 10.2% (worst 7.4 mm, 21% of the part's
size), 10 mm 15.7% (worst 9.9 mm, 22%), half of the extra ones box sets; 3 mm
gives 5.2%. A contact 5 mm off is at the limit of what shows in grasping and
foot contacts, so that is the default; the user can ask for more."""
MAX_VOLUME_RATIO = 1.75
"""Default largest union volume of the fits over the mesh's volume. With the 5 mm
tolerance it matters little on example-robot-data (1.5: 25 meshes, 1.75: 26,
2.0: 27): the distance already rejects fat fits; it stops a thin part (a 30 mm
finger) from becoming a primitive of twice its volume, whose extra bulk
still collides."""

SAMPLES = 1000
"""Surface samples per fitted primitive (deterministic grid, corners included)."""
ELONGATION = 2.0
"""Longest extent over the second from which a mesh also gets sets of slabs."""
_REL = 1e-9
"""Relative slack for enclosure (of the mesh's bounding-box diagonal)."""
_QMC = 4096
"""Quasi-random points per fit for the overlap of a set's fits."""


@dataclass(frozen=True)
class Fit:
    type: Kind
    pos: tuple[float, float, float]
    """Centre, in the mesh's own frame (the vertices' frame), metres."""
    quat: tuple[float, float, float, float]
    """Orientation (w, x, y, z) in that frame; a capsule's/cylinder's axis is its local z."""
    size: tuple[float, ...]
    """MuJoCo geom size: sphere (r,), capsule/cylinder (r, half_length), box (hx, hy, hz)."""


@dataclass(frozen=True)
class Deviation:
    hausdorff_m: float
    """One-sided Hausdorff: largest distance from a point of the fits' surfaces to
    the mesh surface (how far the fit sticks out), over deterministic samples."""
    uncovered_m: float
    """Largest distance by which a mesh vertex lies outside every fit (0 when enclosing)."""
    volume_ratio: float
    """Union volume of the fits / the mesh's volume (its convex hull's volume when
    the mesh is not watertight)."""


@dataclass(frozen=True)
class Candidate:
    fits: tuple[Fit, ...]
    """One primitive, or a small set (2-3) for an elongated mesh."""
    deviation: Deviation
    cost: float
    """Sum over fits of a per-kind weight (sphere 1 < capsule < cylinder < box)."""


# -- frames -------------------------------------------------------------------


def _quat(rot: np.ndarray) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a proper rotation matrix, w >= 0 (one sign: deterministic)."""
    from trimesh.transformations import quaternion_from_matrix

    m = np.eye(4)
    m[:3, :3] = rot
    q = np.asarray(quaternion_from_matrix(m), dtype=np.float64)
    q /= np.linalg.norm(q)
    if q[0] < 0:
        q = -q
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


def _rotation(fit: Fit) -> np.ndarray:
    from trimesh.transformations import quaternion_matrix

    return np.asarray(quaternion_matrix(fit.quat), dtype=np.float64)[:3, :3]


def _frame_z(axis: np.ndarray) -> np.ndarray:
    """A rotation whose third column is ``axis`` (right-handed, deterministic)."""
    z = axis / np.linalg.norm(axis)
    helper = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _local(fit: Fit, points: np.ndarray) -> np.ndarray:
    return (points - np.asarray(fit.pos)) @ _rotation(fit)


def _world(fit: Fit, local: np.ndarray) -> np.ndarray:
    return local @ _rotation(fit).T + np.asarray(fit.pos)


# -- fits ---------------------------------------------------------------------


def _sphere(points: np.ndarray) -> Fit:
    """The minimum enclosing sphere. trimesh's search grows fast with the number of
    points, so it runs on a core set: the extreme points, plus those the sphere
    misses, until it misses none (then it is the minimum sphere of all points)."""
    from trimesh.nsphere import minimum_nsphere

    core = np.unique(np.argmax((points - points.mean(axis=0)) @ _fibonacci(64).T, axis=0))
    centre, r = np.zeros(3), 0.0
    for _ in range(20):
        centre, _r = minimum_nsphere(points[core])
        centre = np.asarray(centre, dtype=np.float64)
        dist = np.linalg.norm(points - centre, axis=1)
        r = float(dist.max())  # enclose exactly
        missed = np.nonzero(dist > float(_r) * (1 + 1e-9))[0]
        if not len(missed):
            break
        far = missed[np.argsort(-dist[missed], kind="stable")[:32]]
        core = np.union1d(core, far)
    return Fit("sphere", _vec(centre), (1.0, 0.0, 0.0, 0.0), (r,))


def _circle(flat: np.ndarray) -> tuple[np.ndarray, float]:
    """Minimum enclosing circle of 2-D points (centre, radius): Welzl's algorithm on
    the corners of their 2-D hull, in a fixed shuffled order (deterministic); the
    radius is re-measured on every point, so it encloses them exactly."""
    from scipy.spatial import ConvexHull, QhullError

    try:  # only the 2-D hull's corners matter, and they are few
        corners = flat[np.sort(ConvexHull(flat).vertices)]
    except (QhullError, ValueError):
        corners = flat
    order = np.random.default_rng(0).permutation(len(corners))
    pts = [(float(x), float(y)) for x, y in corners[order]]
    eps = 1e-12 * (float(np.abs(corners).max()) or 1.0)
    cx, cy, r = pts[0][0], pts[0][1], 0.0
    for i in range(1, len(pts)):
        if math.hypot(pts[i][0] - cx, pts[i][1] - cy) <= r + eps:
            continue
        cx, cy, r = pts[i][0], pts[i][1], 0.0
        for j in range(i):
            if math.hypot(pts[j][0] - cx, pts[j][1] - cy) <= r + eps:
                continue
            cx, cy = 0.5 * (pts[i][0] + pts[j][0]), 0.5 * (pts[i][1] + pts[j][1])
            r = math.hypot(pts[i][0] - cx, pts[i][1] - cy)
            for k in range(j):
                if math.hypot(pts[k][0] - cx, pts[k][1] - cy) > r + eps:
                    cx, cy, r = _circumcircle(pts[i], pts[j], pts[k])
    c = np.array([cx, cy])
    return c, float(np.linalg.norm(flat - c, axis=1).max())


def _circumcircle(
    a: tuple[float, float], b: tuple[float, float], q: tuple[float, float]
) -> tuple[float, float, float]:
    """Circle through three points (centre x, y, radius); for (nearly) collinear
    ones, the diametral circle of the farthest pair."""
    bx, by = b[0] - a[0], b[1] - a[1]
    cx, cy = q[0] - a[0], q[1] - a[1]
    d = 2.0 * (bx * cy - by * cx)
    if abs(d) <= 1e-14 * max(bx * bx + by * by, cx * cx + cy * cy):
        u, v = max([(a, b), (a, q), (b, q)], key=lambda uv: math.dist(uv[0], uv[1]))
        mx, my = 0.5 * (u[0] + v[0]), 0.5 * (u[1] + v[1])
        return mx, my, math.hypot(u[0] - mx, u[1] - my)
    ux = (cy * (bx * bx + by * by) - by * (cx * cx + cy * cy)) / d
    uy = (bx * (cx * cx + cy * cy) - cx * (bx * bx + by * by)) / d
    return a[0] + ux, a[1] + uy, math.hypot(ux, uy)


_OBB_POINTS = 150
"""Hull points above which the box is oriented on extreme points only (speed)."""


def _extreme(points: np.ndarray, count: int = _OBB_POINTS) -> np.ndarray:
    """At most about ``count`` of the points, the farthest along evenly spread
    directions: a hull close to theirs, on which trimesh's minimum-volume box
    search (cost grows with the hull's faces) runs fast. The box is re-measured
    on every point, so it still encloses them."""
    if len(points) <= count:
        return points
    centred = points - points.mean(axis=0)
    idx = np.unique(np.argmax(centred @ _fibonacci(count).T, axis=0))
    return points[idx]


def _round_fits(points: np.ndarray, axis: np.ndarray) -> tuple[Fit, Fit]:
    """The cylinder and the smallest-volume capsule around ``axis`` (through the
    minimum enclosing circle of the points' projection) that enclose the points.

    Capsule: for a radius r >= the largest distance to the axis, a point at height
    t and distance rho needs the segment to reach t -/+ sqrt(r^2 - rho^2), which
    gives the shortest segment; the volume over r is minimised on a grid, then by
    a golden-section search (deterministic)."""
    rot = _frame_z(axis)
    loc = points @ rot
    c2, r0 = _circle(loc[:, :2])
    t = loc[:, 2]
    lo_t, hi_t = float(t.min()), float(t.max())
    q = _quat(rot)
    cyl_centre = rot @ np.array([c2[0], c2[1], 0.5 * (lo_t + hi_t)])
    cylinder = Fit("cylinder", _vec(cyl_centre), q, (r0, 0.5 * (hi_t - lo_t)))

    rho2 = ((loc[:, :2] - c2) ** 2).sum(axis=1)
    r_max = float(np.sqrt(rho2 + (t - 0.5 * (lo_t + hi_t)) ** 2).max())

    def segment(r: float) -> tuple[float, float]:
        s = np.sqrt(np.maximum(r * r - rho2, 0.0))
        return float((t - s).max()), float((t + s).min())

    def volume(r: float) -> float:
        b, a = segment(r)
        return math.pi * r * r * max(b - a, 0.0) + 4.0 / 3.0 * math.pi * r**3

    grid = np.linspace(r0, max(r_max, r0), 17)
    vols = [volume(float(r)) for r in grid]
    k = int(np.argmin(vols))
    lo, hi = float(grid[max(k - 1, 0)]), float(grid[min(k + 1, len(grid) - 1)])
    g = (math.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = volume(x1), volume(x2)
    for _ in range(30):
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = volume(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = volume(x2)
    r = min([(vols[k], float(grid[k])), (f1, x1), (f2, x2)])[1]
    b, a = segment(r)
    mid, half = 0.5 * (a + b), max(0.5 * (b - a), 0.0)
    cap_centre = rot @ np.array([c2[0], c2[1], mid])
    return cylinder, Fit("capsule", _vec(cap_centre), q, (r, half))


def _box(points: np.ndarray, to_origin: np.ndarray) -> Fit:
    """The box of trimesh's minimum-volume oriented bounds, re-measured so that it
    encloses the points exactly."""
    rot = np.asarray(to_origin, dtype=np.float64)[:3, :3].T.copy()
    if np.linalg.det(rot) < 0:
        rot[:, 2] = -rot[:, 2]
    loc = points @ rot
    lo, hi = loc.min(axis=0), loc.max(axis=0)
    centre = rot @ (0.5 * (lo + hi))
    return Fit("box", _vec(centre), _quat(rot), tuple(float(h) for h in 0.5 * (hi - lo)))


def _fits(
    points: np.ndarray, faces: np.ndarray, *, single: bool, to_origin: np.ndarray | None = None
) -> dict[str, Fit]:
    """The enclosing fits of a convex hull (its vertices and faces), per kind; the
    sphere only for a ``single`` fit (sets are of capsules and boxes).

    Cylinder and capsule axes tried: the principal axes of the hull's solid and
    the minimum-volume box's axes; the smallest volume wins. (trimesh's
    ``minimum_cylinder`` costs ~0.17 s on a 5,000-face mesh, more than all the
    rest together, so it is not among them.)"""
    import trimesh
    from trimesh.bounds import oriented_bounds

    if to_origin is None:
        to_origin = np.asarray(oriented_bounds(_extreme(points))[0], dtype=np.float64)
    hull = trimesh.Trimesh(points, faces, process=False)
    axes = list(np.asarray(hull.principal_inertia_vectors, dtype=np.float64))
    axes.extend(to_origin[:3, :3])
    axes = [a / np.linalg.norm(a) for a in axes if np.all(np.isfinite(a)) and np.linalg.norm(a) > 0]
    rounds = [_round_fits(points, a) for a in axes]
    out = {"sphere": _sphere(points)} if single else {}
    return out | {
        "capsule": _smallest([c for _, c in rounds]),
        "cylinder": _smallest([c for c, _ in rounds]),
        "box": _box(points, to_origin),
    }


def _smallest(fits: list[Fit]) -> Fit:
    return min(fits, key=lambda f: (_volume(f), f.size, f.pos, f.quat))


def _vec(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


# -- shapes: volume, signed distance, surface samples --------------------------


def _volume(fit: Fit) -> float:
    s = fit.size
    if fit.type == "sphere":
        return 4.0 / 3.0 * math.pi * s[0] ** 3
    if fit.type == "capsule":
        return math.pi * s[0] ** 2 * 2.0 * s[1] + 4.0 / 3.0 * math.pi * s[0] ** 3
    if fit.type == "cylinder":
        return math.pi * s[0] ** 2 * 2.0 * s[1]
    return 8.0 * s[0] * s[1] * s[2]


def _sdf(fit: Fit, points: np.ndarray) -> np.ndarray:
    """Signed Euclidean distance to the primitive (negative inside)."""
    p = _local(fit, points)
    s = fit.size
    if fit.type == "sphere":
        return np.linalg.norm(p, axis=1) - s[0]
    if fit.type == "capsule":
        q = p.copy()
        q[:, 2] -= np.clip(q[:, 2], -s[1], s[1])
        return np.linalg.norm(q, axis=1) - s[0]
    if fit.type == "cylinder":
        d = np.column_stack([np.linalg.norm(p[:, :2], axis=1) - s[0], np.abs(p[:, 2]) - s[1]])
    else:
        d = np.abs(p) - np.asarray(s)
    return np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)


def _fibonacci(n: int) -> np.ndarray:
    """n nearly evenly spread unit vectors, the poles included."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    z[0], z[-1] = 1.0, -1.0
    phi = math.pi * (3.0 - math.sqrt(5.0)) * i
    rr = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    return np.column_stack([rr * np.cos(phi), rr * np.sin(phi), z])


def _disc(r: float, n: int) -> np.ndarray:
    """About n points on a disc of radius r, rim and centre included (z = 0)."""
    rings = max(1, int(round(math.sqrt(n / math.pi))))
    pts = [np.zeros((1, 3))]
    for k in range(1, rings + 1):
        m = max(6, int(round(2 * math.pi * k)))
        a = 2 * math.pi * np.arange(m) / m
        rad = r * k / rings
        pts.append(np.column_stack([rad * np.cos(a), rad * np.sin(a), np.zeros(m)]))
    return np.vstack(pts)


def _surface(fit: Fit, n: int = SAMPLES) -> np.ndarray:
    """About n points on the primitive's surface (edges, rims, poles included)."""
    s = fit.size
    if fit.type == "sphere":
        loc = s[0] * _fibonacci(n)
    elif fit.type in ("capsule", "cylinder"):
        r, h = s
        area_side = 2 * math.pi * r * 2 * h
        area_ends = 4 * math.pi * r * r if fit.type == "capsule" else 2 * math.pi * r * r
        n_side = int(n * area_side / max(area_side + area_ends, 1e-300))
        around = max(12, int(round(math.sqrt(n_side * 2 * math.pi * r / max(2 * h, 1e-12)))))
        around = min(around, max(12, n_side // 2))
        along = max(2, n_side // around)
        a = 2 * math.pi * np.arange(around) / around
        z = np.linspace(-h, h, along)
        side = np.column_stack(
            [np.tile(r * np.cos(a), along), np.tile(r * np.sin(a), along), np.repeat(z, around)]
        )
        n_end = max(8, (n - len(side)) // 2)
        if fit.type == "capsule":
            cap = r * _fibonacci(2 * n_end)
            top, bottom = cap[cap[:, 2] >= 0], cap[cap[:, 2] <= 0]
            ends = [top + [0, 0, h], bottom - [0, 0, h]]
        else:
            d = _disc(r, n_end)
            ends = [d + [0, 0, h], d - [0, 0, h]]
        loc = np.vstack([side, *ends])
    else:
        hb = np.asarray(s, dtype=np.float64)
        faces = []
        area = np.array([hb[1] * hb[2], hb[0] * hb[2], hb[0] * hb[1]])
        for axis in range(3):
            u, v = [i for i in range(3) if i != axis]
            share = n * area[axis] / max(2 * area.sum(), 1e-300)
            ratio = hb[u] / max(hb[v], 1e-300)
            nu = max(2, int(round(math.sqrt(share * ratio))))
            nv = max(2, int(round(share / nu)))
            gu, gv = np.meshgrid(np.linspace(-hb[u], hb[u], nu), np.linspace(-hb[v], hb[v], nv))
            for sign in (-1.0, 1.0):
                f = np.zeros((gu.size, 3))
                f[:, u], f[:, v], f[:, axis] = gu.ravel(), gv.ravel(), sign * hb[axis]
                faces.append(f)
        loc = np.vstack(faces)
    return _world(fit, loc)


@lru_cache(maxsize=4)
def _halton(n: int, dim: int = 3) -> np.ndarray:
    """The first n points of the Halton sequence in [0, 1)^dim (deterministic)."""
    out = np.zeros((n, dim))
    for d, base in enumerate((2, 3, 5)[:dim]):
        i = np.arange(1, n + 1)
        f, x = 1.0, np.zeros(n)
        while np.any(i > 0):
            f /= base
            x += f * (i % base)
            i //= base
        out[:, d] = x
    out.setflags(write=False)  # shared by the cache
    return out


def _union_volume(fits: Sequence[Fit]) -> float:
    """Sum of the analytic volumes less the overlaps, the overlaps by quasi-Monte
    Carlo: of the points spread inside fit i, the share inside an earlier fit. The
    overlaps of consecutive slabs are small, so their sampling error hardly shows."""
    total = 0.0
    unit = _halton(_QMC)
    for i, fit in enumerate(fits):
        vol = _volume(fit)
        if i == 0 or vol <= 0:
            total += vol
            continue
        ext = _local_extent(fit)
        pts = _world(fit, (2.0 * unit - 1.0) * ext)
        pts = pts[_sdf(fit, pts) <= 0]
        if not len(pts):
            total += vol
            continue
        inside_earlier = np.zeros(len(pts), dtype=bool)
        for other in fits[:i]:
            inside_earlier |= _sdf(other, pts) <= 0
        total += vol * (1.0 - float(inside_earlier.mean()))
    return total


def _local_extent(fit: Fit) -> np.ndarray:
    s = fit.size
    if fit.type == "sphere":
        return np.full(3, s[0])
    if fit.type == "capsule":
        return np.array([s[0], s[0], s[0] + s[1]])
    if fit.type == "cylinder":
        return np.array([s[0], s[0], s[1]])
    return np.asarray(s, dtype=np.float64)


# -- distance to the mesh surface ---------------------------------------------


@dataclass(frozen=True, eq=False)
class _Mesh:
    vertices: np.ndarray
    faces: np.ndarray
    volume: float
    distance: MeshDistance


def _prepare(vertices: np.ndarray, faces: np.ndarray) -> _Mesh | None:
    """The mesh's distance structure and volume, or None for degenerate input."""
    import trimesh

    try:
        v = np.asarray(vertices, dtype=np.float64)
        f = np.asarray(faces, dtype=np.int64)
    except (TypeError, ValueError):
        return None
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or f.ndim != 2 or f.shape[1] != 3:
        return None
    if not len(f) or not np.all(np.isfinite(v)) or f.min() < 0 or f.max() >= len(v):
        return None
    hull = convex_hull(v)
    if hull is None:
        return None
    mesh = trimesh.Trimesh(v, f, process=True)
    if not len(mesh.faces):
        return None
    tri = np.asarray(mesh.triangles, dtype=np.float64)
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not area.sum() > 0:
        return None
    volume = enclosed_volume(mesh) or 0.0  # a part wound inside out cancels nothing
    if not volume > 0:
        volume = abs(signed_volume(hull.vertices, hull.faces))
    if not volume > 0:
        return None
    distance = MeshDistance(tri, np.random.default_rng(0))  # fixed seed: deterministic fits
    return _Mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), volume, distance)


def _deviation(fits: Sequence[Fit], mesh: _Mesh) -> Deviation:
    samples = np.vstack([_surface(f) for f in fits])
    hausdorff = mesh.distance.largest(samples)
    inside = np.full(len(mesh.vertices), np.inf)
    for f in fits:
        inside = np.minimum(inside, _sdf(f, mesh.vertices))
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    # Round-off of an enclosing fit's own arithmetic is not an uncovered vertex.
    uncovered = float(inside.max())
    uncovered = uncovered if uncovered > _REL * diag * 10 else 0.0
    return Deviation(hausdorff, uncovered, _union_volume(fits) / mesh.volume)


# -- the API ------------------------------------------------------------------


def deviation(fits: Sequence[Fit], vertices: np.ndarray, faces: np.ndarray) -> Deviation:
    """The deviation of any set of fits from the mesh (used by the report for
    whatever the user forced). All NaN for a degenerate mesh (flat, too few
    vertices, non-finite numbers, no volume) or no fits: nothing to measure, and
    NaN passes no tolerance."""
    mesh = _prepare(vertices, faces)
    if mesh is None or not len(fits):
        return Deviation(math.nan, math.nan, math.nan)
    return _deviation(fits, mesh)


def _slabs(
    mesh: _Mesh, count: int, to_origin: np.ndarray, extents: np.ndarray
) -> list[np.ndarray] | None:
    """Points whose hulls cover the mesh cut into ``count`` equal slabs along its
    longest box axis, or None when it is not elongated: the vertices within each
    slab and the points where edges cross its two planes."""
    order = np.argsort(-np.asarray(extents), kind="stable")
    if extents[order[0]] < ELONGATION * extents[order[1]]:
        return None
    axis = np.asarray(to_origin)[order[0], :3]
    t = mesh.vertices @ axis
    lo, hi = float(t.min()), float(t.max())
    cuts = lo + (hi - lo) * np.arange(count + 1) / count
    cuts[0], cuts[-1] = -np.inf, np.inf  # lo + (hi - lo) may round below hi
    edges = np.unique(np.sort(mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    ta, tb = t[edges[:, 0]], t[edges[:, 1]]
    crossings = []
    for c in cuts[1:-1]:
        e = (np.minimum(ta, tb) < c) & (np.maximum(ta, tb) > c)
        w = ((c - ta[e]) / (tb[e] - ta[e]))[:, None]
        a, b = mesh.vertices[edges[e, 0]], mesh.vertices[edges[e, 1]]
        crossings.append(a + w * (b - a))
    out = []
    for k in range(count):
        inside = mesh.vertices[(t >= cuts[k]) & (t <= cuts[k + 1])]
        parts = [inside]
        if k > 0:
            parts.append(crossings[k - 1])
        if k < count - 1:
            parts.append(crossings[k])
        out.append(np.vstack(parts))
    return out


def _sets(mesh: _Mesh, to_origin: np.ndarray, extents: np.ndarray) -> list[tuple[Fit, ...]]:
    out: list[tuple[Fit, ...]] = []
    for count in (2, 3):
        slabs = _slabs(mesh, count, to_origin, extents)
        if slabs is None:
            return out
        hulls = [convex_hull(s) for s in slabs]
        if any(h is None for h in hulls):
            continue
        capsules, boxes = [], []
        for h in hulls:
            assert h is not None
            fits = _fits(h.vertices, h.faces, single=False)
            capsules.append(fits["capsule"])
            boxes.append(fits["box"])
        out.extend([tuple(capsules), tuple(boxes)])
    return out


def _usable(fit: Fit) -> bool:
    """Finite, with positive sizes MuJoCo accepts; a capsule of (nearly) no length is
    left out: it is the sphere, which is cheaper."""
    if not all(math.isfinite(x) for x in fit.size + fit.pos + fit.quat):
        return False
    if fit.type == "capsule" and fit.size[1] <= 1e-6 * fit.size[0]:
        return False
    return all(x > 0 for x in fit.size)


def _cost(fits: Sequence[Fit]) -> float:
    return float(sum(_COST[f.type] for f in fits))


def candidates(vertices: np.ndarray, faces: np.ndarray, *, sets: bool = True) -> list[Candidate]:
    """Every fit of the mesh: the best enclosing sphere, capsule, cylinder and box
    (each oriented to the mesh: principal axes / minimum-volume where trimesh gives
    it), and, with ``sets``, for an elongated mesh (longest extent over the second
    at least :data:`ELONGATION`) a set of 2 and of 3 capsules/boxes covering
    consecutive slabs along its long axis. Sorted by (cost, hausdorff).
    Deterministic (same input: same output, bit for bit). Degenerate input (flat,
    fewer than 4 vertices, non-finite numbers, no volume): []."""
    from scipy.spatial import QhullError
    from trimesh.bounds import oriented_bounds

    mesh = _prepare(vertices, faces)
    if mesh is None:
        return []
    hull = convex_hull(mesh.vertices)
    if hull is None:
        return []
    try:
        to_origin, extents = oriented_bounds(_extreme(hull.vertices))
        to_origin = np.asarray(to_origin, dtype=np.float64)
        singles = _fits(hull.vertices, hull.faces, single=True, to_origin=to_origin)
        groups: list[tuple[Fit, ...]] = [(singles[k],) for k in KINDS]
        if sets:
            groups.extend(_sets(mesh, to_origin, np.asarray(extents, dtype=np.float64)))
    except (QhullError, ValueError, np.linalg.LinAlgError, FloatingPointError):
        return []
    out = []
    for fits in groups:
        if not all(_usable(f) for f in fits):
            continue
        out.append(Candidate(fits, _deviation(fits, mesh), _cost(fits)))
    return sorted(out, key=lambda c: (c.cost, c.deviation.hausdorff_m, len(c.fits)))


def choose(
    cands: Sequence[Candidate], tolerance_m: float, max_volume_ratio: float
) -> Candidate | None:
    """The cheapest candidate with hausdorff_m <= tolerance_m and volume_ratio <=
    max_volume_ratio and uncovered_m <= tolerance_m; None when none fits."""
    ok = [
        c
        for c in cands
        if c.deviation.hausdorff_m <= tolerance_m
        and c.deviation.volume_ratio <= max_volume_ratio
        and c.deviation.uncovered_m <= tolerance_m
    ]
    return min(ok, key=lambda c: (c.cost, c.deviation.hausdorff_m), default=None)


def best(cands: Sequence[Candidate]) -> Candidate:
    """For the ``primitive`` strategy (the user wants primitives whatever the
    deviation): the single primitive with the smallest hausdorff, unless a set has
    a hausdorff at most half of it, then that set (the set with the smallest).
    Raises ValueError when ``cands`` is empty."""
    key = lambda c: (c.deviation.hausdorff_m, c.cost)  # noqa: E731
    singles = [c for c in cands if len(c.fits) == 1]
    groups = [c for c in cands if len(c.fits) > 1]
    if not singles and not groups:
        raise ValueError("no candidates")
    single = min(singles, key=key, default=None)
    group = min(groups, key=key, default=None)
    if single is None:
        assert group is not None
        return group
    if group is not None and group.deviation.hausdorff_m <= 0.5 * single.deviation.hausdorff_m:
        return group
    return single
