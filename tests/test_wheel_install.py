"""The wheel as a user gets it: built from the sources, installed into a fresh
virtual environment, its commands run from an empty folder (no checkout).

``pip install mjcf-forge`` must convert robots without the demo's stack (the ``sim``
extra). There is no network here, so a truly bare install cannot download its core
dependencies: the second venv borrows ours like the first, and a finder installed at
its start-up (a ``.pth`` file) makes the sim stack, Ray and Gymnasium unimportable,
as they are where those extras were never installed.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import mujoco
import pytest
from packaging.requirements import Requirement

from urdf2mjcf.extras import EXTRAS

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


# The sim extra as pyproject.toml names it, and what the other extras bring that a
# converter must never import.
SIM = {"mink", "ompl", "toppra", "opencv-python-headless", "matplotlib"}
NOT_CORE = SIM | {"ray", "gymnasium", "eclipse-zenoh"}
REFUSED = ("mink", "ompl", "toppra", "cv2", "matplotlib", "ray", "gymnasium", "zenoh")
"""Import names refused in the venv without extras (cv2: opencv-python-headless)."""
REFUSE_FINDER = """import sys
from importlib.machinery import PathFinder

REFUSED = frozenset(NAMES)


class WithoutExtras(PathFinder):
    # sys.path's finder, blind to these: found nowhere, as where they are not installed
    @classmethod
    def find_spec(cls, name, path=None, target=None):
        if name.partition(".")[0] in REFUSED:
            return None
        return super().find_spec(name, path, target)


sys.meta_path[:] = [WithoutExtras if f is PathFinder else f for f in sys.meta_path]
""".replace("NAMES", repr(REFUSED))
NEEDS_SIM = "needs the sim extra: pip install 'mjcf-forge[sim]'"
# A user's own small robot: two links, one revolute joint.
ARM_URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision>
  </link>
  <link name="upper">
    <inertial><origin xyz="0 0 0.2"/><mass value="0.5"/><inertia ixx="0.005" iyy="0.005" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.03" length="0.4"/></geometry></collision>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.05"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>
  </joint>
</robot>
"""


def _run(cmd: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel, built offline from a copy of the sources."""
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
    (built,) = dist.glob("mjcf_forge-*.whl")
    return built


def _venv(tmp: Path, wheel: Path, refuse_extras: bool = False) -> dict:
    """A fresh venv with the wheel installed; our own dependencies are borrowed. With
    ``refuse_extras``, the sim stack, Ray and Gymnasium cannot be imported in it."""
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
    if refuse_extras:
        (Path(purelib) / "_refuse_extras.py").write_text(REFUSE_FINDER)
        (Path(purelib) / "_refuse_extras.pth").write_text("import _refuse_extras\n")
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


@pytest.fixture(scope="module")
def installed(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The wheel with every extra's packages at hand."""
    return _venv(tmp_path_factory.mktemp("full"), wheel)


@pytest.fixture(scope="module")
def without_extras(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The wheel as ``pip install mjcf-forge`` leaves it: no extra's packages."""
    return _venv(tmp_path_factory.mktemp("bare"), wheel, refuse_extras=True)


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


def _requires(wheel: Path) -> list[Requirement]:
    names = zipfile.ZipFile(wheel).namelist()
    (metadata,) = [n for n in names if n.endswith(".dist-info/METADATA")]
    text = zipfile.ZipFile(wheel).read(metadata).decode()
    prefix = "Requires-Dist: "
    return [
        Requirement(line[len(prefix) :]) for line in text.splitlines() if line.startswith(prefix)
    ]


def _in_extra(req: Requirement) -> str | None:
    """The extra a requirement belongs to (None: a core dependency)."""
    found = re.search(r"""extra\s*==\s*["']([^"']+)["']""", str(req.marker or ""))
    return found.group(1) if found else None


def test_the_core_dependencies_leave_the_demo_stack_to_the_sim_extra(wheel):
    requires = _requires(wheel)
    core = {r.name.lower() for r in requires if _in_extra(r) is None}
    assert {"mujoco", "xacro", "trimesh", "yourdfpy", "click"} <= core
    assert not core & NOT_CORE, sorted(core & NOT_CORE)
    by_extra: dict[str, set[str]] = {}
    for r in requires:
        extra = _in_extra(r)
        if extra is not None:
            by_extra.setdefault(extra, set()).add(str(Requirement(f"{r.name}{r.specifier}")))
    assert {Requirement(s).name for s in by_extra["sim"]} == SIM
    # `pip install '.[test]'` (.ci/run) must still run the demo's tests: test holds all of sim.
    assert by_extra["sim"] <= by_extra["test"], sorted(by_extra["sim"] - by_extra["test"])
    for extra in ("ray", "ros", "gym", "verify", "ros2"):
        assert by_extra[extra]
    # The check the commands make (urdf2mjcf.extras) knows each module the extra installs.
    from importlib.metadata import packages_distributions

    provided = packages_distributions()
    dists = {m: {d.lower() for d in provided.get(m, [])} & SIM for m in EXTRAS["sim"]}
    assert all(dists.values()), dists
    assert set().union(*dists.values()) == SIM, dists


def test_importing_the_compiler_imports_no_extra(installed):
    # In the venv where they are importable: only the demo's commands may load them.
    code = (
        "import sys, urdf2mjcf, urdf2mjcf.api, urdf2mjcf.cli, urdf2mjcf.batch, "
        "urdf2mjcf.certify.command, urdf2mjcf.extras; "
        f"print([m for m in {REFUSED!r} if m in sys.modules])"
    )
    proc = _run([str(installed["python"]), "-c", code], installed["cwd"], installed["env"])
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
    seen = _run(
        [str(installed["python"]), "-c", "import cv2, mink; print('ok')"],
        installed["cwd"],
        installed["env"],
    )
    assert seen.stdout.strip() == "ok", seen.stderr  # the check above could have found them


def _one_error(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert proc.stdout == ""
    return lines[0]


def _files(folder: Path) -> dict[str, bytes | None]:
    return {str(p): p.read_bytes() if p.is_file() else None for p in folder.rglob("*")}


def test_converting_needs_no_extra(without_extras, tmp_path):
    env, venv = without_extras["env"], without_extras["venv"]
    python, bin_ = str(without_extras["python"]), venv / "bin"
    for name in REFUSED:  # the venv really lacks them
        gone = _run([python, "-c", f"import {name}"], tmp_path, env)
        assert gone.returncode == 1 and "ModuleNotFoundError" in gone.stderr, (name, gone.stderr)

    (tmp_path / "arm.urdf").write_text(ARM_URDF)
    helped = _run([str(bin_ / "urdf2mjcf"), "--help"], tmp_path, env)
    assert helped.returncode == 0 and "Usage: urdf2mjcf" in helped.stdout, helped.stderr
    proc = _run([str(bin_ / "urdf2mjcf"), "arm.urdf", "-o", "out/arm.xml"], tmp_path, env)
    assert proc.returncode == 0, proc.stderr
    assert "certificate:" in proc.stdout + proc.stderr  # the certificate ran too
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "arm.xml"))
    assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "shoulder") >= 0
    assert (tmp_path / "out" / "scene.xml").is_file()

    verified = _run([str(bin_ / "urdf2mjcf"), "verify", "arm.urdf", "out/arm.xml"], tmp_path, env)
    assert verified.returncode == 0, verified.stdout + verified.stderr
    batch = _run([str(bin_ / "urdf2mjcf"), "batch", "arm.urdf", "-o", "many", "-q"], tmp_path, env)
    assert batch.returncode == 0, batch.stdout + batch.stderr
    assert json.loads((tmp_path / "many" / "batch.json").read_text())["robots"][0]["ok"]
    assert (tmp_path / "many" / "arm" / "arm.xml").is_file()


def test_the_demo_without_the_sim_extra_is_one_error_and_writes_nothing(without_extras, tmp_path):
    env, bin_ = without_extras["env"], without_extras["venv"] / "bin"
    missing = "(missing: mink, ompl, toppra, cv2, matplotlib)"
    (tmp_path / "built").mkdir()
    before = _files(tmp_path)

    helped = _run([str(bin_ / "facility-demo"), "--help"], tmp_path, env)
    assert helped.returncode == 0 and "Usage: facility-demo" in helped.stdout, helped.stderr
    demo = _run([str(bin_ / "facility-demo"), "built", "--report", "r.json"], tmp_path, env)
    assert _one_error(demo) == f"error: facility-demo {NEEDS_SIM} {missing}"
    both = _run([str(bin_ / "make-facility"), "--demo", "-o", "out"], tmp_path, env)
    assert _one_error(both) == f"error: make-facility --demo {NEEDS_SIM} {missing}"
    # The iMETRO recipes place AprilTags, drawn with OpenCV: refused before building.
    tags = _run([str(bin_ / "make-facility"), "-o", "out"], tmp_path, env)
    assert _one_error(tags) == (
        f"error: drawing the recipe's AprilTags (fiducials) {NEEDS_SIM} (missing: cv2)"
    )
    assert _files(tmp_path) == before


def test_a_facility_without_tags_and_its_rover_need_no_extra(without_extras, tmp_path):
    env, bin_ = without_extras["env"], without_extras["venv"] / "bin"
    recipe = "recipes/mira3d-floor.yaml"
    built = _run(
        [str(bin_ / "make-facility"), recipe, "--no-components", "-o", "floor"], tmp_path, env
    )
    assert built.returncode == 0, built.stderr
    assert json.loads((tmp_path / "floor" / "facility.json").read_text())["fiducials"] == []
    drive = _run(
        [str(bin_ / "rover-drive"), "floor", "--distance", "0.3", "--settle", "0"]
        + ["--report", "drive.json"],
        tmp_path,
        env,
    )
    assert drive.returncode == 0, drive.stdout + drive.stderr
    assert (tmp_path / "drive.json").is_file()
