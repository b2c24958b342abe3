"""A user's own facility: a recipe, a component table and a description in a folder
of their own, built by ``make-facility`` without touching the package. The builder
knows no component by name: our shelf and the user's crate (a free body with its own
jitter ranges) are placed, compiled on their own and listed in facility.json alike."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest

ROOT = Path(__file__).resolve().parents[2]

WORLD = """<?xml version="1.0"?>
<robot name="my_lab" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="shelf" default="true"/>
  <xacro:arg name="shelf_x" default="0"/><xacro:arg name="shelf_y" default="0"/>
  <xacro:arg name="shelf_z" default="0"/><xacro:arg name="shelf_yaw" default="0"/>
  <xacro:arg name="crate_x" default="0"/><xacro:arg name="crate_y" default="0"/>
  <xacro:arg name="crate_z" default="0"/><xacro:arg name="crate_yaw" default="0"/>
  <xacro:arg name="timestep" default="0.002"/>
  <xacro:macro name="placed" params="name">
    <origin xyz="${xacro.arg(name + '_x')} ${xacro.arg(name + '_y')} ${xacro.arg(name + '_z')}"
            rpy="0 0 ${xacro.arg(name + '_yaw')}"/>
  </xacro:macro>
  <mujoco><option timestep="$(arg timestep)"/></mujoco>
  <link name="world"/>
  <xacro:if value="$(arg shelf)">
    <xacro:include filename="$(find shelf)/urdf/shelf.xacro"/>
    <xacro:material_colors/>
    <xacro:shelf prefix="shelf_" parent="world"><xacro:placed name="shelf"/></xacro:shelf>
  </xacro:if>
  <xacro:include filename="crate.xacro"/>
  <xacro:crate prefix="crate_" parent="world"><xacro:placed name="crate"/></xacro:crate>
</robot>
"""

CRATE = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="crate" params="prefix parent *origin">
    <joint name="${prefix}crate_joint" type="floating">
      <parent link="${parent}"/><child link="${prefix}crate"/><xacro:insert_block name="origin"/>
    </joint>
    <link name="${prefix}crate">
      <inertial><mass value="2"/><inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial>
      <visual><geometry><box size="0.3 0.2 0.2"/></geometry></visual>
      <collision><geometry><box size="0.3 0.2 0.2"/></geometry></collision>
    </link>
  </xacro:macro>
</robot>
"""

CRATE_ALONE = """<?xml version="1.0"?>
<robot name="crate" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="crate.xacro"/>
  <link name="world"/>
  <xacro:crate prefix="" parent="world"><origin xyz="0 0 0.1"/></xacro:crate>
</robot>
"""

TABLE = """# my lab's components
shelf:
  asset: shelf
  standalone: facility/mockups/shelf/urdf/shelf.urdf.xacro   # ours, under the root
  flag: shelf
  prefix: shelf_
crate:
  asset: crate
  standalone: crate.urdf.xacro                              # mine, beside the recipe
  prefix: crate_
  free: true
"""

RECIPE = """name: my-lab
xacro: my_lab.urdf.xacro
components: my_components.yaml
flags: {shelf: true}
placements:
  shelf: {xyz: [1.5, -0.5, 0], yaw: 0.5}
  crate: {xyz: [-1.0, 0.75, 0.1], yaw: 1.0}
jitter:
  default: {position: 0.02, yaw: 0.01}
  crate: {position: 0.3, yaw: 0.5}
  shelf: false
simulation: {timestep: 0.004}
"""


def _lab(folder: Path, recipe: str = RECIPE, table: str = TABLE) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "my_lab.urdf.xacro").write_text(WORLD)
    (folder / "crate.xacro").write_text(CRATE)
    (folder / "crate.urdf.xacro").write_text(CRATE_ALONE)
    (folder / "my_components.yaml").write_text(table)
    (folder / "my_lab.yaml").write_text(recipe)
    return folder / "my_lab.yaml"


def _make(recipe: Path, out: Path, *args: str) -> subprocess.CompletedProcess:
    code = "from urdf2mjcf.cli import make_facility_main; make_facility_main()"
    command = [sys.executable, "-c", code, str(recipe), "--root", str(ROOT), "-o", str(out)]
    return subprocess.run(
        [*command, "-q", *args], capture_output=True, text=True, cwd=recipe.parent, timeout=600
    )


def _yaw(m: mujoco.MjModel, body: str) -> float:
    w, _, _, z = m.body(body).quat
    return 2 * math.atan2(z, w)


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    return _lab(tmp_path_factory.mktemp("lab"))


def test_own_facility_is_placed_compiled_and_listed(lab, tmp_path):
    out = tmp_path / "out"
    proc = _make(lab, out)
    assert proc.returncode == 0, proc.stderr
    m = mujoco.MjModel.from_xml_path(str(out / "scene.xml"))
    assert m.body("shelf_shelf").pos == pytest.approx([1.5, -0.5, 0])
    assert _yaw(m, "shelf_shelf") == pytest.approx(0.5)
    assert m.body("crate_crate").pos == pytest.approx([-1.0, 0.75, 0.1])
    assert m.joint("crate_crate_joint").type == mujoco.mjtJoint.mjJNT_FREE
    assert m.opt.timestep == pytest.approx(0.004)

    manifest = json.loads((out / "facility.json").read_text())
    comps = manifest["components"]
    assert set(comps) == {"shelf", "crate"}
    assert comps["crate"]["free"] is True and "free" not in comps["shelf"]
    assert comps["crate"]["joints"] == ["crate_crate_joint"]
    assert comps["shelf"]["pose"] == {"xyz": [1.5, -0.5, 0.0], "yaw": 0.5}
    assert manifest["component_mjcf"] == {
        "crate": "components/crate/crate.xml",
        "shelf": "components/shelf/shelf.xml",
    }
    for path in manifest["component_mjcf"].values():
        mujoco.MjModel.from_xml_path(str(out / path))


def test_own_facility_jitters_each_component_by_its_own_ranges(lab, tmp_path):
    proc = _make(lab, tmp_path / "a", "--seed", "3", "--no-components")
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads((tmp_path / "a" / "facility.json").read_text())
    assert set(manifest["offsets"]) == {"crate"}, "shelf: false never moves"
    delta = manifest["offsets"]["crate"]
    assert max(abs(delta["dx"]), abs(delta["dy"])) <= 0.3 and abs(delta["dyaw"]) <= 0.5
    assert max(abs(delta["dx"]), abs(delta["dy"])) > 0.02, "the crate's own range, not default"
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "a" / "scene.xml"))
    assert m.body("crate_crate").pos == pytest.approx([-1.0 + delta["dx"], 0.75 + delta["dy"], 0.1])
    assert m.body("shelf_shelf").pos == pytest.approx([1.5, -0.5, 0])


def test_own_facility_flag_leaves_a_component_out(lab, tmp_path):
    proc = _make(lab, tmp_path / "b", "--set", "shelf=false", "--no-components")
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads((tmp_path / "b" / "facility.json").read_text())
    assert set(manifest["components"]) == {"crate"}


@pytest.mark.parametrize(
    "recipe, table, needles",
    [
        # a placement of a component the table does not hold: the recipe's line
        (
            RECIPE.replace("  crate: {xyz", "  boat: {xyz"),
            TABLE,
            ("my_lab.yaml", "placements.boat: unknown component", "(line 7)", "unknown component", "crate, shelf"),
        ),
        # a bad entry in the component table: that file, its key and line
        (
            RECIPE,
            TABLE.replace("  free: true", "  free: maybe"),
            ("my_components.yaml", "crate.free: ", "(line 11)", "true or false"),
        ),
        # jitter of a component that does not exist
        (
            RECIPE.replace("  shelf: false", "  shelve: false"),
            TABLE,
            ("my_lab.yaml", "jitter.shelve: unknown key", "(line 11)", "unknown key", "default, shelf, crate"),
        ),
    ],
    ids=["unknown_placement", "bad_table_entry", "unknown_jitter_component"],
)
def test_own_facility_bad_input_names_file_key_and_line(tmp_path, recipe, table, needles):
    path = _lab(tmp_path / "lab", recipe, table)
    proc = _make(path, tmp_path / "out")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), proc.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert not (tmp_path / "out").exists()
