"""The wheel as a user gets it: built from the sources, installed into a fresh
virtual environment, its commands run from an empty folder (no checkout)."""

from __future__ import annotations

import json
import os
import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import mujoco
import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
# What a wheel is built from: the packaging files, the package and its data.
SOURCES = ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md")
TREES = ("urdf2mjcf", "facility", "meshes", "recipes")

# A user's own world: their xacro beside their recipe, with our shelf in it (found
# through our packages) and their own crate, a mesh of theirs beside the xacro.
USER_XACRO = """<?xml version="1.0"?>
<robot name="my_lab" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:include filename="$(find shelf)/urdf/shelf.xacro"/>
  <xacro:material_colors/>
  <xacro:arg name="shelf_x" default="0"/>
  <xacro:arg name="shelf_y" default="0"/>
  <xacro:arg name="shelf_yaw" default="0"/>
  <link name="world"/>
  <xacro:shelf prefix="shelf_" parent="world">
    <origin xyz="$(arg shelf_x) $(arg shelf_y) 0" rpy="0 0 $(arg shelf_yaw)"/>
  </xacro:shelf>
  <link name="crate">
    <inertial><mass value="2"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="meshes/crate.stl"/></geometry></visual>
    <collision><geometry><box size="0.3 0.2 0.1"/></geometry></collision>
  </link>
  <joint name="crate_mount" type="fixed">
    <parent link="world"/><child link="crate"/><origin xyz="0 0 0.05"/>
  </joint>
</robot>
"""
USER_RECIPE = """name: my-lab
xacro: my_lab.urdf.xacro
components:
  shelf: {asset: shelf, standalone: facility/mockups/shelf/urdf/shelf.urdf.xacro, prefix: shelf_}
placements:
  shelf: {xyz: [1.5, -0.5, 0], yaw: 0.5}
"""


def _run(cmd: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A fresh venv with the wheel installed; our own dependencies are borrowed."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        shutil.copy2(REPO / name, src / name)
    for name in TREES:
        shutil.copytree(
            REPO / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc")
        )
    dist = tmp / "dist"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation"]
        + ["--no-index", "-w", str(dist), str(src)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stdout + build.stderr
    (wheel,) = dist.glob("mjcf_forge-*.whl")

    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    purelib = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    # Our dependencies (mujoco, xacro, ...) without reinstalling them: the path comes after
    # the venv's own site-packages, so the wheel's urdf2mjcf is imported, not the checkout's.
    borrowed = [p for p in site.getsitepackages() if Path(p).is_dir()]
    (Path(purelib) / "_borrowed_deps.pth").write_text("\n".join(borrowed) + "\n")
    install = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install"]
        # --ignore-installed: the borrowed site-packages may hold mjcf-forge itself (a
        # non-editable `pip install .`); pip must still put the wheel into the new venv.
        + ["--no-deps", "--no-index", "--ignore-installed", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert install.returncode == 0, install.stdout + install.stderr
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    home = tmp / "empty"
    home.mkdir()
    return {"wheel": wheel, "venv": venv, "python": python, "env": env, "cwd": home}


def test_the_wheel_carries_the_data_but_not_the_mesh_scripts(installed):
    names = zipfile.ZipFile(installed["wheel"]).namelist()
    data = [n for n in names if n.startswith("urdf2mjcf/_data/")]
    for needed in (
        "urdf2mjcf/_data/recipes/imetro.yaml",
        "urdf2mjcf/_data/recipes/demo/imetro.yaml",
        "urdf2mjcf/_data/facility/worlds/imetro_world/urdf/imetro_facility.urdf.xacro",
        "urdf2mjcf/_data/meshes/hatch/hatch_door.stl",
        "urdf2mjcf/_data/meshes/lunar/heightmap.png",
    ):
        assert needed in data
    assert not [n for n in data if n.endswith((".py", ".md"))]
    # Every file a checkout's build reads ships: the same relative paths, nothing else.
    on_disk = {
        str(p.relative_to(REPO))
        for top in ("facility", "meshes", "recipes")
        for p in (REPO / top).rglob("*")
        if p.is_file() and p.suffix in {".xacro", ".xml", ".yaml", ".stl", ".png", ".json"}
    }
    assert {n.removeprefix("urdf2mjcf/_data/") for n in data} == on_disk


def test_make_facility_and_the_demo_from_an_empty_folder(installed):
    cwd, env, venv = installed["cwd"], installed["env"], installed["venv"].resolve()
    where = subprocess.run(
        [str(installed["python"]), "-c", "import urdf2mjcf; print(urdf2mjcf.__file__)"],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert Path(where).resolve().is_relative_to(venv), where

    proc = _run([str(venv / "bin" / "make-facility"), "-v", "-o", "out"], cwd, env)
    assert proc.returncode == 0, proc.stderr
    # The data came from the installed package (the log names the root it used).
    roots = [line for line in proc.stderr.splitlines() if "facility root:" in line]
    assert roots and str(venv) in roots[0] and roots[0].rstrip().endswith("urdf2mjcf/_data")
    model = mujoco.MjModel.from_xml_path(str(cwd / "out" / "scene.xml"))
    manifest = json.loads((cwd / "out" / "facility.json").read_text())
    assert manifest["recipe"] == "imetro" and manifest["recipe_file"] == "recipes/imetro.yaml"
    assert model.nu == manifest["counts"]["actuators"] > 0
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "hatch_4060_door_joint") >= 0
    assert (cwd / "out" / "components" / "imetro_robot" / "imetro_robot.xml").is_file()
    data_root = Path(roots[0].split("facility root:")[1].strip())
    assert not (data_root / "build").exists()  # nothing written into the installation

    demo = [str(venv / "bin" / "facility-demo")]
    helped = _run([*demo, "--help"], cwd, env)
    assert helped.returncode == 0 and "Usage: facility-demo" in helped.stdout
    # The demo's waypoints (recipes/demo/imetro.yaml) come from the wheel too.
    played = _run([*demo, "out"], cwd, env)
    assert played.returncode == 0, played.stdout + played.stderr
    assert "SUCCESS" in played.stdout


def test_a_shipped_recipe_by_its_relative_name(installed):
    cwd, env, venv = installed["cwd"], installed["env"], installed["venv"]
    recipe = "recipes/imetro-no-robot.yaml"
    assert not (cwd / recipe).exists()
    proc = _run(
        [str(venv / "bin" / "make-facility"), recipe, "--no-components", "-o", "norobot"], cwd, env
    )
    assert proc.returncode == 0, proc.stderr
    model = mujoco.MjModel.from_xml_path(str(cwd / "norobot" / "scene.xml"))
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "rail") < 0  # no robot
    assert json.loads((cwd / "norobot" / "facility.json").read_text())["recipe"] == "imetro-no-robot"


def test_a_user_recipe_in_its_own_folder_uses_our_components(installed, tmp_path):
    import trimesh

    env, venv = installed["env"], installed["venv"]
    lab = tmp_path / "lab"
    (lab / "meshes").mkdir(parents=True)
    trimesh.creation.box((0.3, 0.2, 0.1)).export(lab / "meshes" / "crate.stl")
    (lab / "my_lab.urdf.xacro").write_text(USER_XACRO)
    (lab / "my_lab.yaml").write_text(USER_RECIPE)
    user_files = {p: p.read_bytes() for p in lab.rglob("*") if p.is_file()}
    run_in = tmp_path / "elsewhere"
    run_in.mkdir()

    proc = _run(
        [str(venv / "bin" / "make-facility"), str(lab / "my_lab.yaml"), "-o", "built"], run_in, env
    )
    assert proc.returncode == 0, proc.stderr
    out = run_in / "built"
    model = mujoco.MjModel.from_xml_path(str(out / "scene.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    # Our shelf where the user's recipe placed it (its xacro args), their crate beside it.
    shelf = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "shelf_shelf")
    assert shelf >= 0 and data.xpos[shelf] == pytest.approx([1.5, -0.5, 0.0], abs=1e-9)
    crate = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "crate")
    (mesh,) = [
        int(model.geom_dataid[g])
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == crate and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
    ]
    start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    verts = model.mesh_vert[start : start + count]
    # MuJoCo stores a mesh in its principal frame: compare the extents, not their order.
    extents = sorted(verts.max(axis=0) - verts.min(axis=0))
    assert extents == pytest.approx([0.1, 0.2, 0.3], abs=1e-6)
    # The shelf also compiled on its own, from our standalone description.
    assert (out / "components" / "shelf" / "shelf.xml").is_file()
    manifest = json.loads((out / "facility.json").read_text())
    assert manifest["recipe"] == "my-lab" and "shelf" in manifest["components"]
    assert {p: p.read_bytes() for p in lab.rglob("*") if p.is_file()} == user_files
