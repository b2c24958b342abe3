"""Mass properties of uniform-density solids: analytic primitives and triangle meshes.

Every function returns a :class:`MassProperties` in the frame its input is given in,
or None when the solid has no volume. Primitive sizes follow MuJoCo: box half extents,
cylinder and capsule (radius, half length) along the local z axis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import trimesh


@dataclass(frozen=True, eq=False)
class MassProperties:
    mass: float
    """kg, > 0."""
    com: np.ndarray
    """(3,) centre of mass, metres."""
    inertia: np.ndarray
    """(3, 3) kg m^2, about ``com``, in the axes of the frame it is given in."""

    def transformed(self, t: np.ndarray) -> MassProperties:
        """The same solid placed by the (4, 4) transform ``t``."""
        r = t[:3, :3]
        return MassProperties(self.mass, r @ self.com + t[:3, 3], r @ self.inertia @ r.T)


def combine(parts: Sequence[MassProperties]) -> MassProperties | None:
    """Several solids as one rigid body (parallel axis theorem); overlaps count twice."""
    if not parts:
        return None
    mass = sum(p.mass for p in parts)
    com = np.sum([p.mass * p.com for p in parts], axis=0) / mass
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.com - com
        inertia += p.inertia + p.mass * (d @ d * np.eye(3) - np.outer(d, d))
    return MassProperties(mass, com, inertia)


def _at_origin(mass: float, diagonal: Sequence[float]) -> MassProperties | None:
    if not mass > 0:
        return None
    return MassProperties(mass, np.zeros(3), np.diag(np.asarray(diagonal, dtype=float)))


def box(half: Sequence[float], density: float) -> MassProperties | None:
    a, b, c = half
    m = density * 8.0 * a * b * c
    k = m / 3
    return _at_origin(m, (k * (b * b + c * c), k * (a * a + c * c), k * (a * a + b * b)))


def sphere(r: float, density: float) -> MassProperties | None:
    m = density * 4.0 / 3.0 * math.pi * r**3
    return _at_origin(m, (0.4 * m * r * r,) * 3)


def cylinder(r: float, h: float, density: float) -> MassProperties | None:
    """Solid cylinder of radius ``r`` and half length ``h`` along z."""
    m = density * math.pi * r * r * 2.0 * h
    t = m * (r * r / 4 + h * h / 3)
    return _at_origin(m, (t, t, 0.5 * m * r * r))


def capsule(r: float, h: float, density: float) -> MassProperties | None:
    """Cylinder of half length ``h`` along z capped by two hemispheres of radius ``r``.

    Each hemisphere (mass ms/2) has its centre of mass 3r/8 beyond the cylinder end
    and a transverse moment (2/5 - 9/64) (ms/2) r^2 about it; shifted to the capsule
    centre, the two caps give ms (2/5 r^2 + h^2 + 3/4 h r).
    """
    mc = density * math.pi * r * r * 2.0 * h
    ms = density * 4.0 / 3.0 * math.pi * r**3
    t = mc * (r * r / 4 + h * h / 3) + ms * (0.4 * r * r + h * h + 0.75 * h * r)
    return _at_origin(mc + ms, (t, t, 0.5 * mc * r * r + 0.4 * ms * r * r))


def primitive(gtype: str, size: Sequence[float], density: float) -> MassProperties | None:
    """A MuJoCo box, sphere, cylinder or capsule centred at the origin."""
    if gtype == "box":
        return box(size[:3], density)
    if gtype == "sphere":
        return sphere(size[0], density)
    if gtype == "cylinder":
        return cylinder(size[0], size[1], density)
    if gtype == "capsule":
        return capsule(size[0], size[1], density)
    raise ValueError(f"not a primitive geom type: {gtype!r}")


def _closed(mesh: trimesh.Trimesh, density: float) -> MassProperties | None:
    """Mass properties of a closed, consistently wound ``trimesh.Trimesh``."""
    with np.errstate(divide="ignore", invalid="ignore"):  # zero volume divides by zero
        props = mesh.mass_properties
        if not props.volume > 0:
            return None
        return MassProperties(
            density * props.volume,
            np.asarray(props.center_mass, dtype=float),
            density * np.asarray(props.inertia, dtype=float),
        )


def convex_hull(vertices: np.ndarray, density: float) -> MassProperties | None:
    """The solid convex hull of a point set (None when the points span no volume)."""
    import trimesh
    from scipy.spatial import QhullError

    try:
        hull = trimesh.convex.convex_hull(np.asarray(vertices, dtype=float))
    except (QhullError, ValueError):
        return None
    return _closed(hull, density)


def mesh_solid(
    vertices: np.ndarray, faces: np.ndarray, density: float
) -> tuple[MassProperties | None, str]:
    """The solid a triangle mesh encloses, and how it was obtained.

    Tried in order, the method names what worked: ``"closed"`` (the mesh is
    watertight after merging duplicate vertices; an inside-out mesh is turned
    round), ``"manifold3d"`` (manifold3d merges open edges into a manifold),
    ``"filling holes"`` (trimesh fills single-triangle and quad holes) and
    ``"convex hull"`` (the last resort, which overestimates concave parts).
    """
    import manifold3d
    import trimesh

    tm = trimesh.Trimesh(np.asarray(vertices, dtype=float), np.asarray(faces), process=True)
    if tm.is_watertight and tm.is_winding_consistent:
        if tm.volume < 0:
            tm.invert()
        props = _closed(tm, density)
        if props is not None:
            return props, "closed"

    m64 = manifold3d.Mesh64(
        vert_properties=np.ascontiguousarray(tm.vertices, dtype=np.float64),
        tri_verts=np.ascontiguousarray(tm.faces, dtype=np.uint64),
    )
    m64.merge()
    solid = manifold3d.Manifold(m64)
    if solid.status() == manifold3d.Error.NoError and solid.volume() > 0:
        out = solid.to_mesh64()
        props = _closed(trimesh.Trimesh(out.vert_properties[:, :3], out.tri_verts), density)
        if props is not None:
            return props, "manifold3d"

    filled = tm.copy()
    trimesh.repair.fill_holes(filled)
    if filled.is_volume:
        props = _closed(filled, density)
        if props is not None:
            return props, "filling holes"

    return convex_hull(tm.vertices, density), "convex hull"
