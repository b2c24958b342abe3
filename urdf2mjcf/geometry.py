"""URDF primitives as MuJoCo geoms, shared by the visual and collision passes."""

from __future__ import annotations

from typing import Literal

from .ir import RGBA, Box, Capsule, Cylinder, Geom, Geometry, Plane, Pose, Quat, Sphere
from .transforms import canonical_quat, pose_quat, quat_mul, vec3

PLANE_GRID = 0.05
"""Grid spacing drawn on a plane, metres (MuJoCo needs one)."""


def _z_to(normal: tuple[float, float, float]) -> Quat:
    """The shortest rotation taking +z onto the unit vector ``normal``."""
    nx, ny, nz = normal
    if nz <= -1.0 + 1e-12:
        return (0.0, 1.0, 0.0, 0.0)
    return canonical_quat((1.0 + nz, -ny, nx, 0.0))


def primitive_geom(
    role: Literal["visual", "collision"],
    origin: Pose,
    geometry: Geometry,
    *,
    rgba: RGBA | None = None,
    material: str | None = None,
    name: str | None = None,
) -> Geom:
    """A URDF box, cylinder, sphere, capsule or plane placed at ``origin`` in its link.

    URDF gives full sizes, MuJoCo half sizes; both put cylinders and capsules
    along the local z axis.
    """
    if isinstance(geometry, Box):
        gtype, size = "box", tuple(0.5 * s for s in geometry.size)
    elif isinstance(geometry, Cylinder):
        gtype, size = "cylinder", (geometry.radius, 0.5 * geometry.length)
    elif isinstance(geometry, Sphere):
        gtype, size = "sphere", (geometry.radius,)
    elif isinstance(geometry, Capsule):
        gtype, size = "capsule", (geometry.radius, 0.5 * geometry.length)
    elif isinstance(geometry, Plane):
        gtype, size = "plane", (*(0.5 * s for s in geometry.size), PLANE_GRID)
    else:
        raise TypeError(f"not a primitive: {geometry!r}")
    quat = pose_quat(origin)
    if isinstance(geometry, Plane) and geometry.normal != (0.0, 0.0, 1.0):
        quat = canonical_quat(quat_mul(quat, _z_to(geometry.normal)))  # MuJoCo planes face +z
    return Geom(
        role=role,
        type=gtype,  # type: ignore[arg-type]
        pos=vec3(origin.xyz),
        quat=quat,
        size=tuple(float(s) for s in size),
        rgba=rgba,
        material=material,
        name=name,
    )
