"""Write the small mesh files under ``tests/data/meshes/``; deterministic.

Run from anywhere: ``python tests/data/make_meshes.py``. The outputs are
checked in; rerunning must reproduce them byte for byte.

* ``box.stl`` (binary), ``box_ascii.stl``, ``box.ply``: a 0.1 x 0.2 x 0.3 m
  box centred at the origin.
* ``u_shape.stl``: a watertight, clearly non-convex U bracket, 0.2 m wide and
  0.2 m tall, 0.05 m deep; volume 1.25e-3 m^3, convex hull volume 2e-3 m^3.
* ``colored_box.dae``: the same box in centimetres (``<unit meter="0.01">``),
  declared ``Z_UP``, defined as 20 x 10 x 30 under a node rotated 90 degrees
  about z and translated 15 cm up, so that in metres it spans
  x [-0.05, 0.05], y [-0.1, 0.1], z [0, 0.3]. Side faces use material
  ``red`` (diffuse 0.8 0.1 0.1), top and bottom ``blue`` (0.1 0.2 0.9).
* ``textured_quad.obj`` + ``.mtl`` + ``quadrants.png``: a 0.1 m square in the
  z = 0 plane facing +z, u along +x, v along +y; the 8 x 8 texture is red
  top-left, green top-right, blue bottom-left, yellow bottom-right.
"""

from __future__ import annotations

import io
import struct
from pathlib import Path

import manifold3d
import numpy as np
import trimesh
from PIL import Image

OUT = Path(__file__).resolve().parent / "meshes"


def box_mesh() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=(0.1, 0.2, 0.3))


def binary_stl(vertices: np.ndarray, faces: np.ndarray, header: bytes) -> bytes:
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    out = [header.ljust(80, b" "), struct.pack("<I", len(faces))]
    for normal, t in zip(n, tri, strict=True):
        out.append(struct.pack("<12fH", *normal, *t.ravel(), 0))
    return b"".join(out)


def ascii_stl(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    lines = ["solid box"]
    for a, b, c in faces:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices[[a, b, c]]]
        lines += ["    endloop", "  endfacet"]
    lines.append("endsolid box")
    return ("\n".join(lines) + "\n").encode()


def ply(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    header = (
        "ply\nformat ascii 1.0\n"
        f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = [f"{x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    body += [f"3 {a} {b} {c}" for a, b, c in faces]
    return (header + "\n".join(body) + "\n").encode()


def u_shape() -> trimesh.Trimesh:
    base = manifold3d.Manifold.cube((0.2, 0.05, 0.05)).translate((-0.1, -0.025, 0.0))
    left = manifold3d.Manifold.cube((0.05, 0.05, 0.2)).translate((-0.1, -0.025, 0.0))
    right = manifold3d.Manifold.cube((0.05, 0.05, 0.2)).translate((0.05, -0.025, 0.0))
    m = (base + left + right).to_mesh()
    return trimesh.Trimesh(np.asarray(m.vert_properties)[:, :3], np.asarray(m.tri_verts))


_DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset>
    <unit name="centimeter" meter="0.01"/>
    <up_axis>Z_UP</up_axis>
  </asset>
  <library_effects>
    <effect id="red-fx"><profile_COMMON><technique sid="common"><phong>
      <diffuse><color>0.8 0.1 0.1 1</color></diffuse>
    </phong></technique></profile_COMMON></effect>
    <effect id="blue-fx"><profile_COMMON><technique sid="common"><phong>
      <diffuse><color>0.1 0.2 0.9 1</color></diffuse>
    </phong></technique></profile_COMMON></effect>
  </library_effects>
  <library_materials>
    <material id="red" name="red"><instance_effect url="#red-fx"/></material>
    <material id="blue" name="blue"><instance_effect url="#blue-fx"/></material>
  </library_materials>
  <library_geometries>
    <geometry id="box-mesh" name="box">
      <mesh>
        <source id="box-pos">
          <float_array id="box-pos-array" count="{nv}">{positions}</float_array>
          <technique_common>
            <accessor source="#box-pos-array" count="{n}" stride="3">
              <param name="X" type="float"/>
              <param name="Y" type="float"/>
              <param name="Z" type="float"/>
            </accessor>
          </technique_common>
        </source>
        <vertices id="box-vtx"><input semantic="POSITION" source="#box-pos"/></vertices>
        <triangles material="red-sym" count="{n_side}">
          <input semantic="VERTEX" source="#box-vtx" offset="0"/>
          <p>{side}</p>
        </triangles>
        <triangles material="blue-sym" count="{n_cap}">
          <input semantic="VERTEX" source="#box-vtx" offset="0"/>
          <p>{cap}</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene">
      <node id="lift" name="lift">
        <translate>0 0 15</translate>
        <node id="turn" name="turn">
          <rotate>0 0 1 90</rotate>
          <instance_geometry url="#box-mesh">
            <bind_material><technique_common>
              <instance_material symbol="red-sym" target="#red"/>
              <instance_material symbol="blue-sym" target="#blue"/>
            </technique_common></bind_material>
          </instance_geometry>
        </node>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""


def colored_box_dae() -> bytes:
    box = trimesh.creation.box(extents=(20.0, 10.0, 30.0))  # centimetres, before the node rotation
    normals = box.face_normals
    cap = np.abs(normals[:, 2]) > 0.5
    fmt = " ".join
    return _DAE.format(
        nv=3 * len(box.vertices),
        n=len(box.vertices),
        positions=fmt(f"{x:g}" for x in box.vertices.ravel()),
        n_side=int((~cap).sum()),
        side=fmt(str(i) for i in box.faces[~cap].ravel()),
        n_cap=int(cap.sum()),
        cap=fmt(str(i) for i in box.faces[cap].ravel()),
    ).encode()


def quadrants_png() -> bytes:
    img = Image.new("RGB", (8, 8))
    colours = {(0, 0): (255, 0, 0), (1, 0): (0, 255, 0), (0, 1): (0, 0, 255), (1, 1): (255, 255, 0)}
    for x in range(8):
        for y in range(8):  # y = 0 is the top row of the image
            img.putpixel((x, y), colours[(x // 4, y // 4)])
    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=False, compress_level=9)
    return buf.getvalue()


_OBJ = """# a textured 0.1 m square facing +z
mtllib textured_quad.mtl
v -0.05 -0.05 0
v 0.05 -0.05 0
v 0.05 0.05 0
v -0.05 0.05 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl quadrants
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/4/1
"""

_MTL = """newmtl quadrants
Ka 1 1 1
Kd 1 1 1
map_Kd quadrants.png
"""


def main() -> None:
    OUT.mkdir(exist_ok=True)
    box = box_mesh()
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    u = u_shape()
    files = {
        "box.stl": binary_stl(v, f, b"box"),
        "box_ascii.stl": ascii_stl(v, f),
        "box.ply": ply(v, f),
        "u_shape.stl": binary_stl(np.asarray(u.vertices), np.asarray(u.faces), b"u_shape"),
        "colored_box.dae": colored_box_dae(),
        "quadrants.png": quadrants_png(),
        "textured_quad.obj": _OBJ.encode(),
        "textured_quad.mtl": _MTL.encode(),
    }
    for name, data in files.items():
        (OUT / name).write_bytes(data)


if __name__ == "__main__":
    main()
