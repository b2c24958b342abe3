"""The meshes pass: loading, units, colours, textures, asset naming, errors, decimation."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from urdf2mjcf.errors import MeshError
from urdf2mjcf.ir import (
    Box,
    Collision,
    Link,
    Material,
    MeshData,
    MeshRef,
    Model,
    Pose,
    Robot,
    Visual,
)
from urdf2mjcf.passes import meshes
from urdf2mjcf.passes.meshes import MeshConfig

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
BOX_EXTENTS = np.array([0.1, 0.2, 0.3])
BOX_VOLUME = 0.1 * 0.2 * 0.3


# ---------------------------------------------------------------------------
# helpers: robots built straight from the IR, an independent volume, MuJoCo
# ---------------------------------------------------------------------------


def mesh_ref(path: Path | None, scale=(1.0, 1.0, 1.0), filename: str | None = None) -> MeshRef:
    name = filename or (f"package://pkg/meshes/{path.name}" if path else "package://gone/x.stl")
    return MeshRef(filename=name, path=path, scale=tuple(float(s) for s in scale))


def robot(*links: Link) -> Robot:
    return Robot(name="r", source=Path("/robots/r.urdf"), links=links, joints=())


def visual_link(name: str, ref, material: Material | None = None, origin: Pose | None = None):
    visual = Visual(origin=origin or Pose(), geometry=ref, material=material)
    return Link(name=name, visuals=(visual,))


def collision_link(name: str, ref) -> Link:
    return Link(name=name, collisions=(Collision(origin=Pose(), geometry=ref),))


def run(*links: Link, **cfg) -> Model:
    return meshes.run(Model(robot=robot(*links)), MeshConfig(**cfg))


def only_mesh(model: Model):
    (loaded,) = model.meshes.values()
    return loaded


def signed_volume(mesh: MeshData) -> float:
    """Divergence theorem: positive when the faces wind counter-clockwise seen from outside."""
    tri = mesh.vertices[mesh.faces]
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def extents(mesh: MeshData) -> np.ndarray:
    return mesh.vertices.max(axis=0) - mesh.vertices.min(axis=0)


def visuals_xml(model: Model, tmp_path: Path) -> str:
    """Write the assets; MJCF of one body holding every visual geom, as emit would write it."""
    out = tmp_path / "assets"
    out.mkdir(exist_ok=True)
    for a in (*model.mesh_assets, *model.textures):
        (out / a.file).write_bytes(a.data)
    assets = [f'<mesh name="{a.name}" file="{a.file}" inertia="shell"/>' for a in model.mesh_assets]
    assets += [f'<texture name="{t.name}" type="2d" file="{t.file}"/>' for t in model.textures]
    for m in model.materials:
        tex = f' texture="{m.texture}"' if m.texture else ""
        assets.append(f'<material name="{m.name}" rgba="{" ".join(map(str, m.rgba))}"{tex}/>')
    geoms = []
    for g in (g for gs in model.visual_geoms.values() for g in gs):
        mat = f' material="{g.material}"' if g.material else ""
        geoms.append(
            f'<geom type="mesh" mesh="{g.mesh}" pos="{" ".join(map(str, g.pos))}" '
            f'quat="{" ".join(map(str, g.quat))}"{mat} contype="0" conaffinity="0" group="2"/>'
        )
    xml = f"""<mujoco>
  <compiler meshdir="{out}" texturedir="{out}" inertiafromgeom="false"/>
  <visual><headlight ambient="1 1 1" diffuse="0 0 0" specular="0 0 0"/></visual>
  <asset>{"".join(assets)}</asset>
  <worldbody>
    <camera name="top" pos="0 0 0.3" xyaxes="1 0 0 0 1 0" fovy="20"/>
    <body name="b">{"".join(geoms)}</body>
  </worldbody>
</mujoco>"""
    return xml


def compile_visuals(model: Model, tmp_path: Path) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(visuals_xml(model, tmp_path))


# ---------------------------------------------------------------------------
# formats, units and scale
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["box.stl", "box_ascii.stl", "box.ply"])
def test_box_files_load_with_analytic_extents_and_volume(name):
    loaded = only_mesh(run(collision_link("base", mesh_ref(MESHES / name))))
    np.testing.assert_allclose(extents(loaded.merged), BOX_EXTENTS, rtol=1e-6)
    assert signed_volume(loaded.merged) == pytest.approx(BOX_VOLUME, rel=1e-6)
    assert len(loaded.merged.vertices) == 8  # per-triangle STL vertices merged
    assert len(loaded.merged.faces) == 12


def test_upper_case_extension_is_recognised(tmp_path):
    shutil.copy(MESHES / "box.stl", tmp_path / "BOX.STL")
    loaded = only_mesh(run(collision_link("base", mesh_ref(tmp_path / "BOX.STL"))))
    assert signed_volume(loaded.merged) == pytest.approx(BOX_VOLUME, rel=1e-6)


def test_collada_unit_and_node_transforms_are_applied_and_up_axis_ignored():
    loaded = only_mesh(run(collision_link("base", mesh_ref(MESHES / "colored_box.dae"))))
    v = loaded.merged.vertices
    # centimetres -> metres; node rotates 20 x 10 about z and lifts it 15 cm; Z_UP not applied
    np.testing.assert_allclose(v.min(axis=0), [-0.05, -0.1, 0.0], atol=1e-7)
    np.testing.assert_allclose(v.max(axis=0), [0.05, 0.1, 0.3], atol=1e-7)
    assert signed_volume(loaded.merged) == pytest.approx(BOX_VOLUME, rel=1e-6)


def test_obj_loads_in_metres_with_its_uvs():
    loaded = only_mesh(run(visual_link("base", mesh_ref(MESHES / "textured_quad.obj"))))
    (part,) = loaded.parts
    np.testing.assert_allclose(extents(part.mesh), [0.1, 0.1, 0.0])
    assert part.mesh.uv is not None
    # each corner keeps its texture coordinate: u along +x, v along +y
    np.testing.assert_allclose(part.mesh.uv, (part.mesh.vertices[:, :2] + 0.05) / 0.1, atol=1e-9)


def test_urdf_scale_is_applied():
    model = run(collision_link("base", mesh_ref(MESHES / "box.stl", scale=(2, 1, 0.5))))
    merged = only_mesh(model).merged
    np.testing.assert_allclose(extents(merged), [0.2, 0.2, 0.15], rtol=1e-6)
    assert signed_volume(merged) == pytest.approx(2 * 0.5 * BOX_VOLUME, rel=1e-6)


@pytest.mark.parametrize("scale", [(-1, 1, 1), (1, -1, -1), (-1, -1, -1)])
def test_mirror_scale_keeps_faces_pointing_outwards(scale):
    merged = only_mesh(run(collision_link("base", mesh_ref(MESHES / "u_shape.stl", scale)))).merged
    assert signed_volume(merged) == pytest.approx(1.25e-3, rel=1e-6)


def test_loaded_mesh_records_a_hash_of_file_and_scale():
    a = only_mesh(run(collision_link("a", mesh_ref(MESHES / "box.stl"))))
    b = only_mesh(run(collision_link("a", mesh_ref(MESHES / "box.stl", scale=(2, 2, 2)))))
    assert len(a.sha256) == 64 and a.sha256 != b.sha256


def test_each_file_and_scale_is_loaded_once_in_document_order():
    box, u = MESHES / "box.stl", MESHES / "u_shape.stl"
    link = Link(
        name="a",
        visuals=(Visual(Pose(), mesh_ref(u)), Visual(Pose(), mesh_ref(box))),
        collisions=(Collision(Pose(), mesh_ref(box)), Collision(Pose(), mesh_ref(box, (2, 2, 2)))),
    )
    model = run(link, visual_link("b", mesh_ref(u)))
    assert list(model.meshes) == [
        (u, (1.0, 1.0, 1.0)),
        (box, (1.0, 1.0, 1.0)),
        (box, (2.0, 2.0, 2.0)),
    ]


def test_degenerate_and_repeated_faces_and_unused_vertices_are_removed(tmp_path):
    obj = tmp_path / "messy.obj"
    obj.write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 5 5 5\nv 2 0 0\n"
        "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"  # a tetrahedron
        "f 3 4 2\n"  # the last face again, rotated
        "f 1 2 6\nf 1 1 2\n"  # zero area: collinear, repeated index
    )
    merged = only_mesh(run(collision_link("a", mesh_ref(obj)))).merged
    assert len(merged.faces) == 4 and len(merged.vertices) == 4
    assert signed_volume(merged) == pytest.approx(1 / 6)


# ---------------------------------------------------------------------------
# colours, materials, textures
# ---------------------------------------------------------------------------


def test_collada_materials_become_material_assets_one_geom_each():
    model = run(visual_link("base", mesh_ref(MESHES / "colored_box.dae")))
    geoms = model.visual_geoms["base"]
    assert len(geoms) == 2 and all(g.type == "mesh" and g.rgba is None for g in geoms)
    by_name = {m.name: m for m in model.materials}
    colours = [by_name[g.material].rgba for g in geoms]
    np.testing.assert_allclose(colours, [(0.8, 0.1, 0.1, 1), (0.1, 0.2, 0.9, 1)], atol=1 / 255)
    # sides (8 triangles) in red, top and bottom (4) in blue
    faces = [len(only_mesh(model).parts[i].mesh.faces) for i in range(2)]
    assert faces == [8, 4]


def test_collada_geometry_with_a_broken_material_is_kept_and_takes_the_urdf_colour(tmp_path):
    # pycollada drops a whole instance whose material is missing; assimp (RViz) keeps it
    dae = tmp_path / "broken.dae"
    text = (MESHES / "colored_box.dae").read_text()
    dae.write_text(text.replace('target="#blue"', 'target="#no-such-material"'))
    green = Material(name="green", rgba=(0.0, 1.0, 0.0, 1.0))
    model = run(visual_link("base", mesh_ref(dae), material=green))
    assert signed_volume(only_mesh(model).merged) == pytest.approx(BOX_VOLUME, rel=1e-6)
    by_name = {m.name: m for m in model.materials}
    colours = [by_name[g.material].rgba for g in model.visual_geoms["base"]]
    np.testing.assert_allclose(colours, [(0.8, 0.1, 0.1, 1), green.rgba], atol=1 / 255)
    assert any(n.kind == "warning" and "no-such-material" in n.message for n in model.notes)


def test_mesh_own_material_wins_over_urdf_colour():
    green = Material(name="green", rgba=(0.0, 1.0, 0.0, 1.0))
    model = run(visual_link("base", mesh_ref(MESHES / "colored_box.dae"), material=green))
    assert all(m.rgba != green.rgba for m in model.materials)


def test_urdf_colour_applies_to_a_material_less_mesh():
    orange = Material(name="orange", rgba=(1.0, 0.5, 0.0, 1.0))
    model = run(visual_link("base", mesh_ref(MESHES / "box.stl"), material=orange))
    (geom,) = model.visual_geoms["base"]
    (mat,) = model.materials
    assert geom.material == mat.name and mat.rgba == orange.rgba and geom.rgba is None
    assert mat.name.startswith("orange_")


def test_material_less_mesh_of_material_less_visual_gets_no_colour():
    model = run(visual_link("base", mesh_ref(MESHES / "box.stl")))
    (geom,) = model.visual_geoms["base"]
    assert geom.material is None and geom.rgba is None and model.materials == ()


def test_primitive_visual_becomes_a_primitive_geom_with_the_urdf_colour():
    blue = Material(name="blue", rgba=(0.0, 0.0, 1.0, 1.0))
    origin = Pose(xyz=(0.1, 0.0, 0.0), rpy=(0.0, 0.0, np.pi / 2))
    model = run(visual_link("base", Box(size=(0.2, 0.4, 0.6)), material=blue, origin=origin))
    (geom,) = model.visual_geoms["base"]
    assert geom.type == "box" and geom.size == pytest.approx((0.1, 0.2, 0.3))
    assert geom.pos == pytest.approx((0.1, 0, 0))
    assert geom.quat == pytest.approx((np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)))
    assert model.materials[0].rgba == blue.rgba and geom.material == model.materials[0].name


def test_mesh_geom_sits_at_the_visual_origin():
    origin = Pose(xyz=(0.0, 0.0, 0.5), rpy=(np.pi / 2, 0.0, 0.0))
    model = run(visual_link("base", mesh_ref(MESHES / "box.stl"), origin=origin))
    (geom,) = model.visual_geoms["base"]
    assert geom.pos == (0.0, 0.0, 0.5)
    assert geom.quat == pytest.approx((np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0))


def test_textured_obj_writes_an_obj_asset_and_png_that_mujoco_compiles(tmp_path):
    model = run(visual_link("base", mesh_ref(MESHES / "textured_quad.obj")))
    (asset,) = model.mesh_assets
    (texture,) = model.textures
    (material,) = model.materials
    assert asset.file.endswith(".obj") and b"\nvt " in asset.data
    assert texture.data.startswith(b"\x89PNG") and material.texture == texture.name
    (geom,) = model.visual_geoms["base"]
    assert geom.material == material.name
    m = compile_visuals(model, tmp_path)
    assert m.mesh_texcoordnum[0] == 4


def test_urdf_texture_is_used_by_a_mesh_with_uvs_and_no_material(tmp_path):
    obj = tmp_path / "quad.obj"
    text = (MESHES / "textured_quad.obj").read_text()
    obj.write_text(text.replace("mtllib textured_quad.mtl\n", "").replace("usemtl quadrants\n", ""))
    urdf_mat = Material(name="skin", texture=MESHES / "quadrants.png")
    model = run(visual_link("base", mesh_ref(obj), material=urdf_mat))
    (material,) = model.materials
    assert material.texture == model.textures[0].name and material.rgba == (1, 1, 1, 1)
    assert model.mesh_assets[0].file.endswith(".obj")


_RENDER = """
import sys, mujoco
model = mujoco.MjModel.from_xml_path(sys.argv[1])
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
renderer = mujoco.Renderer(model, 64, 64)
renderer.update_scene(data, camera="top")
img = renderer.render()
for row, col in ((16, 16), (16, 48), (48, 16), (48, 48)):
    print(*img[row, col])
"""


RED, GREEN, BLUE, YELLOW = (255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0)
QUADRANTS = np.array([RED, GREEN, BLUE, YELLOW], dtype=float)
"""The texture's quadrants from top left to bottom right, as the top camera must see them."""


def render_corners(model: Model, tmp_path: Path) -> np.ndarray:
    """Pixels at the centres of the four image quadrants seen by the ``top`` camera.

    The camera looks down -z with +x right and +y up, so the image's top left
    shows the quad's (-x, +y) corner, where the texture's top left belongs.
    """
    (tmp_path / "scene.xml").write_text(visuals_xml(model, tmp_path))
    # MuJoCo picks its OpenGL backend at import, hence a fresh interpreter
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    done = subprocess.run(
        [sys.executable, "-c", _RENDER, str(tmp_path / "scene.xml")],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return np.array([line.split() for line in done.stdout.splitlines()], dtype=float)


@pytest.mark.usefixtures("gl_context")  # skips only where no GL context can be made
def test_obj_texture_appears_the_right_way_up_in_mujoco(tmp_path):
    model = run(visual_link("base", mesh_ref(MESHES / "textured_quad.obj")))
    assert render_corners(model, tmp_path) == pytest.approx(QUADRANTS, abs=40)


_TEXTURED_DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit meter="0.001"/><up_axis>Z_UP</up_axis></asset>
  <library_images><image id="img"><init_from>../textures/quadrants.png</init_from></image>
  </library_images>
  <library_effects><effect id="fx"><profile_COMMON>
    <newparam sid="surf"><surface type="2D"><init_from>img</init_from></surface></newparam>
    <newparam sid="samp"><sampler2D><source>surf</source></sampler2D></newparam>
    <technique sid="common"><lambert>
      <diffuse><texture texture="samp" texcoord="UVMap"/></diffuse>
    </lambert></technique>
  </profile_COMMON></effect></library_effects>
  <library_materials><material id="skin"><instance_effect url="#fx"/></material></library_materials>
  <library_geometries><geometry id="quad"><mesh>
    <source id="pos">
      <float_array id="pos-a" count="12">-50 -50 0 50 -50 0 50 50 0 -50 50 0</float_array>
      <technique_common><accessor source="#pos-a" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <source id="uv"><float_array id="uv-a" count="8">0 0 1 0 1 1 0 1</float_array>
      <technique_common><accessor source="#uv-a" count="4" stride="2">
        <param name="S" type="float"/><param name="T" type="float"/>
      </accessor></technique_common></source>
    <vertices id="vtx"><input semantic="POSITION" source="#pos"/></vertices>
    <triangles material="skin-sym" count="2">
      <input semantic="VERTEX" source="#vtx" offset="0"/>
      <input semantic="TEXCOORD" source="#uv" offset="1" set="0"/>
      <p>0 0 1 1 2 2 0 0 2 2 3 3</p>
    </triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n">
    <instance_geometry url="#quad"><bind_material><technique_common>
      <instance_material symbol="skin-sym" target="#skin">
        <bind_vertex_input semantic="UVMap" input_semantic="TEXCOORD" input_set="0"/>
      </instance_material>
    </technique_common></bind_material></instance_geometry>
  </node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


@pytest.mark.usefixtures("gl_context")  # skips only where no GL context can be made
def test_collada_texture_in_a_sibling_folder_is_found_and_appears_the_right_way_up(tmp_path):
    # the usual ROS layout: meshes/x.dae refers to ../textures/y.png
    (tmp_path / "pkg" / "meshes").mkdir(parents=True)
    (tmp_path / "pkg" / "textures").mkdir()
    shutil.copy(MESHES / "quadrants.png", tmp_path / "pkg" / "textures")
    dae = tmp_path / "pkg" / "meshes" / "quad.dae"
    dae.write_text(_TEXTURED_DAE)
    model = run(visual_link("base", mesh_ref(dae)))
    (texture,) = model.textures
    assert model.materials[0].texture == texture.name
    assert model.mesh_assets[0].file.endswith(".obj")
    np.testing.assert_allclose(extents(only_mesh(model).merged), [0.1, 0.1, 0.0])  # mm
    assert render_corners(model, tmp_path) == pytest.approx(QUADRANTS, abs=40)


# ---------------------------------------------------------------------------
# assets: naming and sharing
# ---------------------------------------------------------------------------


def test_identical_meshes_are_stored_once(tmp_path):
    copy = tmp_path / "elsewhere" / "other_name.stl"
    copy.parent.mkdir()
    shutil.copy(MESHES / "box.stl", copy)
    model = run(
        visual_link("a", mesh_ref(MESHES / "box.stl")),
        visual_link("b", mesh_ref(MESHES / "box.stl")),
        visual_link("c", mesh_ref(copy)),
    )
    assert len(model.mesh_assets) == 1
    names = {g.mesh for gs in model.visual_geoms.values() for g in gs}
    assert names == {model.mesh_assets[0].name}


def test_same_file_name_in_different_folders_gives_different_assets(tmp_path):
    for folder, source in (("a", "box.stl"), ("b", "u_shape.stl")):
        (tmp_path / folder).mkdir()
        shutil.copy(MESHES / source, tmp_path / folder / "link.stl")
    model = run(
        visual_link("a", mesh_ref(tmp_path / "a" / "link.stl")),
        visual_link("b", mesh_ref(tmp_path / "b" / "link.stl")),
    )
    a, b = model.mesh_assets
    assert a.name != b.name and a.file != b.file
    assert a.name.startswith("link_") and b.name.startswith("link_")
    assert [g.mesh for gs in model.visual_geoms.values() for g in gs] == [a.name, b.name]


def test_two_runs_give_byte_identical_assets():
    links = (
        visual_link("a", mesh_ref(MESHES / "colored_box.dae")),
        visual_link("b", mesh_ref(MESHES / "textured_quad.obj")),
        visual_link("c", mesh_ref(MESHES / "u_shape.stl", (-1, 1, 1))),
    )
    first, second = run(*links), run(*links)
    assert first.mesh_assets == second.mesh_assets
    assert first.textures == second.textures and first.materials == second.materials
    assert first.visual_geoms == second.visual_geoms


def test_all_assets_compile_in_mujoco(tmp_path):
    model = run(
        visual_link("a", mesh_ref(MESHES / "colored_box.dae")),
        visual_link("b", mesh_ref(MESHES / "textured_quad.obj")),
        visual_link("c", mesh_ref(MESHES / "box.ply", (1, -1, 1))),
    )
    m = compile_visuals(model, tmp_path)
    assert m.ngeom == 4


# ---------------------------------------------------------------------------
# errors and warnings
# ---------------------------------------------------------------------------


def test_git_lfs_pointer_is_an_error_even_for_a_visual(tmp_path):
    pointer = tmp_path / "arm.stl"
    pointer.write_text(
        "version https://git-lfs.github.com/spec/v1\n"
        "oid sha256:4d7a214614ab2935c943f9e0ff69d22eadbb8f32b1258daaa5e2ca24d17e2393\nsize 12345\n"
    )
    with pytest.raises(MeshError, match="LFS") as err:
        run(visual_link("arm", mesh_ref(pointer)))
    assert "git lfs pull" in str(err.value) and "link 'arm' visual mesh" in str(err.value)


@pytest.mark.parametrize("path", [None, Path("/nonexistent/meshes/arm.stl")])
def test_missing_collision_mesh_is_dropped_with_a_warning_an_error_when_strict(path):
    ref = mesh_ref(path, filename="package://pkg/meshes/arm.stl")
    model = run(collision_link("arm", ref))
    dropped, left = model.notes
    assert dropped.kind == "warning" and "collision dropped" in dropped.message
    assert dropped.element == "link 'arm' collision mesh 'package://pkg/meshes/arm.stl'"
    assert left.element == "link 'arm'" and "no collision geometry left" in left.message
    assert model.robot.link_map["arm"].collisions == ()
    with pytest.raises(MeshError) as err:
        run(collision_link("arm", ref), strict_visual=True)
    assert "link 'arm' collision mesh 'package://pkg/meshes/arm.stl'" in str(err.value)
    assert err.value.file == "/robots/r.urdf"


def test_missing_visual_mesh_is_a_warning_and_the_visual_is_dropped():
    keep = visual_link("base", mesh_ref(MESHES / "box.stl"))
    gone = Link(
        name="arm",
        visuals=(
            Visual(Pose(), mesh_ref(Path("/nonexistent/arm.stl"))),
            Visual(Pose(), Box(size=(1, 1, 1))),
        ),
    )
    model = run(keep, gone)
    (note,) = model.notes
    assert note.kind == "warning" and "link 'arm' visual mesh" in note.element
    assert "dropped" in note.message
    assert [g.type for g in model.visual_geoms["arm"]] == ["box"]


def test_missing_visual_mesh_is_an_error_when_strict():
    with pytest.raises(MeshError, match="link 'arm' visual mesh"):
        run(visual_link("arm", mesh_ref(None)), strict_visual=True)


def test_unsupported_format_names_the_supported_ones(tmp_path):
    ogre = tmp_path / "arm.mesh"
    ogre.write_bytes(b"\x00\x10[MeshSerializer_v1.100]")
    with pytest.raises(MeshError, match=r"unsupported mesh format '\.mesh'; supported: \.stl"):
        run(collision_link("arm", mesh_ref(ogre)), strict_visual=True)
    model = run(visual_link("arm", mesh_ref(ogre)))
    assert model.notes[0].kind == "warning" and "arm" not in model.visual_geoms


@pytest.mark.parametrize(
    "name, content",
    [
        ("garbage.dae", b"this is not xml"),
        ("empty.stl", b""),
        ("points.obj", b"v 0 0 0\nv 1 0 0\n"),
    ],
)
def test_unreadable_or_empty_collision_mesh_is_dropped_an_error_when_strict(
    tmp_path, name, content
):
    (tmp_path / name).write_bytes(content)
    model = run(collision_link("arm", mesh_ref(tmp_path / name)))
    assert "collision dropped" in model.notes[0].message
    assert model.robot.link_map["arm"].collisions == ()
    with pytest.raises(MeshError, match="link 'arm' collision mesh"):
        run(collision_link("arm", mesh_ref(tmp_path / name)), strict_visual=True)


# ---------------------------------------------------------------------------
# decimation and what MuJoCo accepts
# ---------------------------------------------------------------------------


def test_mesh_above_the_face_limit_is_decimated_with_a_note(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.1)  # 1280 faces
    path = tmp_path / "sphere.stl"
    sphere.export(path)
    model = run(
        visual_link("ball", mesh_ref(path)), collision_link("ball", mesh_ref(path)), max_faces=500
    )
    loaded = only_mesh(model)
    assert 0 < len(loaded.merged.faces) <= 500
    assert all(len(p.mesh.faces) <= 500 for p in loaded.parts)
    notes = [n for n in model.notes if n.kind == "decimated"]
    assert notes and "1280" in notes[0].message and "sphere.stl" in notes[0].element
    # still a closed ball of about the same size, and the same result every time
    assert signed_volume(loaded.merged) == pytest.approx(4 / 3 * np.pi * 0.1**3, rel=0.1)
    again = only_mesh(run(visual_link("ball", mesh_ref(path)), max_faces=500))
    np.testing.assert_array_equal(again.merged.faces, loaded.merged.faces)


def test_flat_visual_mesh_compiles_with_shell_inertia(tmp_path):
    # MuJoCo refuses a zero-volume mesh ("mesh volume is too small") even on a
    # massless visual geom unless the mesh asset says inertia="shell"
    model = run(visual_link("base", mesh_ref(MESHES / "textured_quad.obj")))
    assert compile_visuals(model, tmp_path).nmesh == 1
