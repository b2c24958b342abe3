"""The recipe's ``collision:`` key: what the facility's collision meshes become, for the
scene and for the components compiled on their own. A bad value is one error line
naming the recipe and the key; a built facility's geoms are what the key asks for, as
MuJoCo compiles scene.xml, and each component's file has the same shapes as the scene."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
import trimesh

from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]
RECIPES = sorted((ROOT / "recipes").glob("imetro*.yaml"))
PRIMITIVE = {mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_CYLINDER}
PRIMITIVE |= {mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_SPHERE}

# An arm of three links with collision meshes: a box-shaped mesh (a box fits it
# exactly), a wedge (convex; no primitive within the default 5 mm: its hull) and a
# plate (box-shaped; the recipe asks for its hull).
ARM = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="arm_link" params="name mesh">
    <link name="${name}">
      <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
      <visual><geometry><mesh filename="MESHES/${mesh}.stl"/></geometry></visual>
      <collision><geometry><mesh filename="MESHES/${mesh}.stl"/></geometry></collision>
    </link>
  </xacro:macro>
  <xacro:macro name="arm" params="prefix parent *origin">
    <joint name="${prefix}mount" type="fixed">
      <parent link="${parent}"/><child link="${prefix}base"/><xacro:insert_block name="origin"/>
    </joint>
    <xacro:arm_link name="${prefix}base" mesh="block"/>
    <joint name="${prefix}hinge" type="revolute">
      <parent link="${prefix}base"/><child link="${prefix}wedge"/><origin xyz="0 0 0.3"/>
      <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="10" velocity="1"/>
    </joint>
    <xacro:arm_link name="${prefix}wedge" mesh="wedge"/>
    <joint name="${prefix}slide" type="prismatic">
      <parent link="${prefix}wedge"/><child link="${prefix}plate"/><origin xyz="0 0 0.3"/>
      <axis xyz="1 0 0"/><limit lower="0" upper="0.1" effort="10" velocity="1"/>
    </joint>
    <xacro:arm_link name="${prefix}plate" mesh="plate"/>
  </xacro:macro>
</robot>
"""

WORLD = """<?xml version="1.0"?>
<robot name="cell" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="arm_x" default="0"/><xacro:arg name="arm_y" default="0"/>
  <xacro:arg name="arm_z" default="0"/><xacro:arg name="arm_yaw" default="0"/>
  <xacro:include filename="arm.xacro"/>
  <link name="world"/>
  <xacro:arm prefix="arm_" parent="world">
    <origin xyz="$(arg arm_x) $(arg arm_y) $(arg arm_z)" rpy="0 0 $(arg arm_yaw)"/>
  </xacro:arm>
</robot>
"""

ARM_ALONE = """<?xml version="1.0"?>
<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="arm.xacro"/>
  <link name="world"/>
  <xacro:arm prefix="" parent="world"><origin xyz="0 0 0.1"/></xacro:arm>
</robot>
"""

RECIPE = """name: cell
xacro: cell.urdf.xacro
components:
  arm: {asset: arm, standalone: arm.urdf.xacro, prefix: arm_}
placements:
  arm: {xyz: [0.5, 0, 0.1], yaw: 0}
collision:
  default: auto
  links: {arm_plate: hull}
"""


def _cell(folder: Path, recipe: str = RECIPE) -> Path:
    """A facility of the user's own in ``folder``; its recipe's path."""
    folder.mkdir(parents=True, exist_ok=True)
    corners = [[0, 0, 0], [0.2, 0, 0], [0, 0.2, 0], [0, 0, 0.2], [0.2, 0, 0.2], [0, 0.2, 0.2]]
    wedge = trimesh.Trimesh(corners).convex_hull  # a triangular prism
    meshes = {
        "block": trimesh.creation.box([0.2, 0.1, 0.3]),
        "wedge": wedge,
        "plate": trimesh.creation.box([0.3, 0.2, 0.02]),
    }
    for name, mesh in meshes.items():
        mesh.export(folder / f"{name}.stl")
    (folder / "arm.xacro").write_text(ARM.replace("MESHES", str(folder)))
    (folder / "cell.urdf.xacro").write_text(WORLD)
    (folder / "arm.urdf.xacro").write_text(ARM_ALONE)
    (folder / "cell.yaml").write_text(recipe)
    return folder / "cell.yaml"


def _shapes(m: mujoco.MjModel, names: dict[str, str]) -> dict[str, tuple]:
    """Link -> (geom type, size) of its collision geom ``names[link]``."""
    out = {}
    for link, geom in names.items():
        g = m.geom(geom)
        out[link] = (mujoco.mjtGeom(g.type[0]), tuple(round(float(x), 6) for x in g.size))
    return out


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cell")
    recipe = load_recipe(_cell(folder / "src"))
    return build_facility(recipe, folder / "out", root=ROOT)


def test_the_recipe_shapes_are_the_geoms_mujoco_compiles(cell):
    scene = mujoco.MjModel.from_xml_path(str(cell.scene))
    links = {n: f"arm_{n}_collision" for n in ("base", "wedge", "plate")}
    shapes = _shapes(scene, links)
    assert shapes["base"][0] == mujoco.mjtGeom.mjGEOM_BOX  # auto: the box fits the block
    assert sorted(shapes["base"][1]) == pytest.approx([0.05, 0.1, 0.15], abs=1e-4)
    assert shapes["wedge"][0] == mujoco.mjtGeom.mjGEOM_MESH  # auto: no primitive fits
    assert shapes["plate"][0] == mujoco.mjtGeom.mjGEOM_MESH  # collision.links: its hull
    # the report counts what became a primitive, with its deviation
    primitive = cell.conversion.primitive
    assert len(primitive) == 1 and primitive[0].message.startswith("box (Hausdorff 0.0 mm")


def test_a_component_file_has_the_shapes_of_the_scene(cell):
    """The component is compiled on its own with its links' own names (without the
    prefix): the recipe's entry for ``arm_plate`` applies to its ``plate``."""
    scene = mujoco.MjModel.from_xml_path(str(cell.scene))
    alone = mujoco.MjModel.from_xml_path(str(cell.components["arm"]))
    names = ("base", "wedge", "plate")
    in_scene = _shapes(scene, {n: f"arm_{n}_collision" for n in names})
    assert _shapes(alone, {n: f"{n}_collision" for n in names}) == in_scene


def _make(recipe: Path, out: Path, *args: str) -> subprocess.CompletedProcess:
    code = "from urdf2mjcf.cli import make_facility_main; make_facility_main()"
    command = [sys.executable, "-c", code, str(recipe), "--root", str(ROOT), "-o", str(out)]
    return subprocess.run(
        [*command, "-q", *args], capture_output=True, text=True, cwd=recipe.parent, timeout=600
    )


def test_a_link_the_facility_lacks_is_one_error_line_naming_recipe_and_key(tmp_path):
    recipe = _cell(tmp_path / "src", RECIPE.replace("arm_plate", "arm_elbow"))
    out = tmp_path / "out"
    proc = _make(recipe, out, "--no-components")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert "cell.yaml" in lines[0] and "collision.links.arm_elbow" in lines[0]
    assert not out.exists()


BAD = [
    ("collision: {default: capsule}", "collision.default", "'capsule' is not one of"),
    ("collision: {links: {arm_base: sphere}}", "collision.links.arm_base", "not one of"),
    ("collision: {links: [arm_base]}", "collision.links", "is not a mapping"),
    ("collision: {tolerance: 5}", "collision.tolerance", "unknown key; valid: default, links"),
    ("collision: auto", "collision", "is not a mapping"),
]


@pytest.mark.parametrize(("section", "key", "message"), BAD)
def test_a_bad_collision_section_names_the_recipe_and_the_key(tmp_path, section, key, message):
    text = RECIPE.split("collision:")[0] + section + "\n"
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        load_recipe(path)
    shown = str(err.value)
    assert "bad.yaml" in shown and f"{key}:" in shown and message in shown, shown
    assert f"(line {len(text.splitlines())})" in shown  # the section's line


def test_set_edits_the_collision_section_and_is_checked(tmp_path):
    path = _cell(tmp_path)
    recipe = load_recipe(path, {"collision.default": "hull", "collision.links.arm_base": "auto"})
    assert recipe.collision == {"default": "hull", "links": {"arm_plate": "hull", "arm_base": "auto"}}
    with pytest.raises(InputError, match="collision.default.*'cone' is not one of"):
        load_recipe(path, {"collision.default": "cone"})
    with pytest.raises(InputError, match="'collision' is a section"):
        load_recipe(path, {"collision": "auto"})


def test_component_entries_follow_the_prefix():
    recipe = load_recipe(RECIPES[0], {"collision.links.trainer_lid": "hull"})
    assert recipe.link_collision({"lid", "deck"}, "trainer_") == {"lid": "hull"}
    assert recipe.link_collision({"trainer_lid"}, "trainer_") == {"trainer_lid": "hull"}
    assert recipe.link_collision({"lid"}, "hatch_") == {}


@pytest.mark.parametrize("path", RECIPES, ids=lambda p: p.stem)
def test_the_imetro_recipes_ask_for_fitted_primitives(path):
    assert load_recipe(path).collision == {"default": "auto"}


def test_the_imetro_facility_collides_through_primitives_only(tmp_path):
    """Every collision geom of the default facility (robot, mockups, CTB: contype or
    conaffinity set) is a primitive as MuJoCo compiles scene.xml: its descriptions give
    boxes and cylinders, which every collision shape keeps, and no collision mesh."""
    report = build_facility(
        load_recipe(RECIPES[RECIPES.index(ROOT / "recipes" / "imetro.yaml")]),
        tmp_path / "imetro",
        root=ROOT,
        components=False,
    )
    m = mujoco.MjModel.from_xml_path(str(report.scene))
    colliding = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]
    robot = [g for g in colliding if m.geom(g).name.startswith(("finger_", "wrist_", "forearm"))]
    stated = " ".join((ROOT / "docs" / "facility.md").read_text().split())
    (count,) = re.findall(r"(\d+) colliding geoms in the default facility", stated)
    assert len(colliding) == int(count) and len(robot) >= 6
    kinds = {mujoco.mjtGeom(m.geom_type[g]) for g in colliding}
    assert kinds <= PRIMITIVE, kinds
    # nothing was fitted, hulled or decomposed: no collision mesh to start from
    assert not any(report.conversion.of_kind(k) for k in ("primitive", "hull", "decomposed"))
