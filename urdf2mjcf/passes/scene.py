"""Scene: a ``scene.xml`` that includes the robot and adds floor, light and sky.

The floor goes through the lowest point of the robot's collision geometry in
its home pose (never above the world origin): URDF root links often sit at
the pelvis or base centre, and a floor at z = 0 would start a humanoid with
its legs deep in the ground. A fixed-base robot then hangs just above the
floor; a floating one stands on it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from lxml import etree

from ..errors import ValidationError
from ..fmt import set_attrs
from ..mjcf.compile import HomeCompiles, compile_home
from ..mjcf.document import Document, mjcf_bytes


def lowest_point(result: Document, compiles: HomeCompiles | None = None) -> float | None:
    """World z of the lowest collision geometry at the home keyframe (None: no geoms).
    ``compiles``: the conversion's last compile, reused where it has the same shape."""
    import mujoco

    m, d = compile_home(
        result.root, result.files, shape_only=True, collision_only=True, compiles=compiles
    )
    mujoco.mj_kinematics(m, d)
    colliding = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]
    if not colliding:  # only visual geoms to go by: they were left out of that compile
        m, d = compile_home(result.root, result.files)
        mujoco.mj_kinematics(m, d)
    geoms = colliding or list(range(m.ngeom))
    if not geoms:
        return None
    return min(_geom_bottom(m, d, g) for g in geoms)


def _geom_bottom(m: Any, d: Any, g: int) -> float:
    import mujoco

    z = float(d.geom_xpos[g][2])
    r = d.geom_xmat[g].reshape(3, 3)
    size = m.geom_size[g]
    t = m.geom_type[g]
    if t == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = m.geom_dataid[g]
        start, count = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
        verts = m.mesh_vert[start : start + count]
        return z + float((verts @ r[2]).min())
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return z - size[0]
    if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return z - size[0] - abs(r[2, 2]) * size[1]
    if t == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return z - abs(r[2, 2]) * size[1] - size[0] * math.sqrt(max(0.0, 1 - r[2, 2] ** 2))
    if t in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        return z - float(np.abs(r[2]) @ size)
    return z  # planes and height fields have no bottom to speak of


def scene_xml(robot_file: str, model_name: str, floor_z: float = 0.0) -> bytes:
    """The scene document as written; ``floor_z`` is the height of the floor plane."""
    return mjcf_bytes(scene_root(robot_file, model_name, floor_z))


def scene_root(robot_file: str, model_name: str, floor_z: float = 0.0) -> etree._Element:
    """The scene document in memory; ``floor_z`` is the height of the floor plane."""
    mj = etree.Element("mujoco", model=f"{model_name} scene")
    set_attrs(etree.SubElement(mj, "include"), file=robot_file)
    set_attrs(etree.SubElement(mj, "statistic"), center=(0, 0, max(floor_z + 0.5, 0.3)), extent=1.5)
    visual = etree.SubElement(mj, "visual")
    set_attrs(
        etree.SubElement(visual, "headlight"),
        diffuse=(0.6, 0.6, 0.6),
        ambient=(0.3, 0.3, 0.3),
        specular=(0, 0, 0),
    )
    set_attrs(etree.SubElement(visual, "rgba"), haze=(0.15, 0.25, 0.35, 1))
    set_attrs(etree.SubElement(visual, "global"), azimuth=120, elevation=-20)
    asset = etree.SubElement(mj, "asset")
    set_attrs(
        etree.SubElement(asset, "texture"),
        name="scene_skybox",
        type="skybox",
        builtin="gradient",
        rgb1=(0.3, 0.5, 0.7),
        rgb2=(0, 0, 0),
        # a smooth gradient needs no more; at 512 x 3072 MuJoCo spent 25 ms building
        # it, more than compiling a small robot
        width=256,
        height=1536,
    )
    set_attrs(
        etree.SubElement(asset, "texture"),
        name="scene_groundplane",
        type="2d",
        builtin="checker",
        mark="edge",
        rgb1=(0.2, 0.3, 0.4),
        rgb2=(0.1, 0.2, 0.3),
        markrgb=(0.8, 0.8, 0.8),
        width=300,
        height=300,
    )
    set_attrs(
        etree.SubElement(asset, "material"),
        name="scene_groundplane",
        texture="scene_groundplane",
        texuniform="true",
        texrepeat=(5, 5),
        reflectance=0.2,
    )
    worldbody = etree.SubElement(mj, "worldbody")
    set_attrs(
        etree.SubElement(worldbody, "light"),
        pos=(0, 0, floor_z + 3.5),
        dir=(0, 0, -1),
        directional="true",
    )
    set_attrs(
        etree.SubElement(worldbody, "geom"),
        name="floor",
        pos=(0, 0, floor_z) if floor_z else None,
        size=(0, 0, 0.05),
        type="plane",
        material="scene_groundplane",
    )
    return mj


def run(
    result: Document, robot_file: str, model_name: str, compiles: HomeCompiles | None = None
) -> etree._Element:
    """The scene document around the robot document ``result`` (written as ``robot_file``)."""
    try:
        lowest = lowest_point(result, compiles)
    except ValueError as exc:  # MuJoCo's (a model too large to allocate): bad input
        message = " ".join(str(exc).split())
        raise ValidationError(f"MuJoCo rejected the model: {message}", file=robot_file) from None
    floor_z = min(0.0, lowest) if lowest is not None else 0.0
    return scene_root(robot_file, model_name, floor_z)
