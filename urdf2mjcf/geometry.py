"""URDF primitives as MuJoCo geoms, shared by the visual and collision passes."""

from __future__ import annotations

from typing import Literal

from .ir import RGBA, Box, Capsule, Cylinder, Geom, Geometry, Pose, Sphere
from .transforms import quat_from_rpy, vec3


def primitive_geom(
    role: Literal["visual", "collision"],
    origin: Pose,
    geometry: Geometry,
    *,
    rgba: RGBA | None = None,
    material: str | None = None,
    name: str | None = None,
) -> Geom:
    """A URDF box, cylinder, sphere or capsule placed at ``origin`` in its link.

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
    else:
        raise TypeError(f"not a primitive: {geometry!r}")
    return Geom(
        role=role,
        type=gtype,  # type: ignore[arg-type]
        pos=vec3(origin.xyz),
        quat=quat_from_rpy(origin.rpy),
        size=tuple(float(s) for s in size),
        rgba=rgba,
        material=material,
        name=name,
    )
