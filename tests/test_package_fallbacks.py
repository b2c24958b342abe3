"""Package fallbacks for descriptions laid out the way people actually ship them.

Each case builds a small tree in tmp_path, converts it with the real command
line, and checks that the mesh MuJoCo compiles is the file we meant (same
vertex count as MuJoCo gives the original file) and that the guess is reported
as exactly one ``warning:`` line naming it.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
import trimesh

from urdf2mjcf.errors import PackageNotFoundError
from urdf2mjcf.packages import PackageResolver

INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)


def _mesh(path: Path) -> Path:
    """An icosphere: 42 distinct vertices, unlike any primitive the converter makes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.icosphere(subdivisions=1, radius=0.05).export(path)
    return path


def _package_xml(folder: Path, name: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "package.xml").write_text(
        f"<package format='3'><name>{name}</name><version>1.0.0</version></package>"
    )


def _urdf(path: Path, *uris: str) -> Path:
    """One link per URI, each with that mesh as its visual, chained by revolute joints."""
    links, joints = [], []
    for i, uri in enumerate(uris):
        links.append(
            f'<link name="l{i}">{INERTIAL}'
            f'<visual><geometry><mesh filename="{uri}"/></geometry></visual></link>'
        )
        if i:
            joints.append(
                f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/>'
                f'<child link="l{i}"/><axis xyz="0 0 1"/>'
                '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
            )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'<robot name="arm">{"".join(links)}{"".join(joints)}</robot>')
    return path


def _convert(src: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", str(src), "-o", str(out), "--no-ros-env", *extra],
        capture_output=True,
        text=True,
        timeout=300,
    )


def _reference_vertices(mesh_file: Path) -> int:
    """Vertices MuJoCo's compiler gives the original file, loaded on its own."""
    spec = f"""<mujoco><asset><mesh name="m" file="{mesh_file}"/></asset>
      <worldbody><body><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"""
    return int(mujoco.MjModel.from_xml_string(spec).mesh_vertnum[0])


def _assert_uses(out: Path, mesh_file: Path, n_links: int) -> None:
    model = mujoco.MjModel.from_xml_path(str(out))
    visual = [
        model.geom_dataid[g]
        for g in range(model.ngeom)
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
    ]
    assert len(visual) == n_links
    assert {int(model.mesh_vertnum[m]) for m in visual} == {_reference_vertices(mesh_file)}


def _warnings(proc: subprocess.CompletedProcess, needle: str) -> list[str]:
    return [ln for ln in proc.stderr.splitlines() if ln.startswith("warning:") and needle in ln]


def test_renamed_package_resolves_inside_the_urdfs_own_package(tmp_path):
    # ROS-Industrial: the URDF says abb_irb140_support, the files ship in abb_irb140_description
    pkg = tmp_path / "abb_irb140_description"
    _package_xml(pkg, "abb_irb140_description")
    mesh = _mesh(pkg / "meshes" / "irb140" / "visual" / "link_1.stl")
    uri = "package://abb_irb140_support/meshes/irb140/visual/link_1.stl"
    src = _urdf(pkg / "urdf" / "irb140.urdf", uri, uri, uri)
    out = tmp_path / "out" / "irb140.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 3)
    lines = _warnings(proc, "abb_irb140_support")
    assert len(lines) == 1, proc.stderr  # once per substitution, not once per mesh
    assert "abb_irb140_description" in lines[0] and str(pkg) in lines[0]
    # --strict: the same guess is one error line, exit 2, nothing written
    strict_out = tmp_path / "strict" / "irb140.xml"
    proc = _convert(src, strict_out, "--strict")
    assert proc.returncode == 2, proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(errors) == 1 and errors[0].startswith("error:"), proc.stderr
    assert "abb_irb140_support" in errors[0] and "--strict" in errors[0]
    assert not strict_out.parent.exists()


def test_renamed_package_without_package_xml_tries_each_ancestor(tmp_path):
    root = tmp_path / "downloads" / "my_arm"
    mesh = _mesh(root / "meshes" / "base.stl")
    src = _urdf(root / "urdf" / "robots" / "arm.urdf", "package://arm_description/meshes/base.stl")
    out = tmp_path / "out" / "arm.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    lines = _warnings(proc, "arm_description")
    assert len(lines) == 1 and str(root) in lines[0], proc.stderr


@pytest.mark.parametrize("urdf_dir", ["robot", "robot/urdf"], ids=["beside_urdf", "beside_parent"])
def test_package_named_meshes_is_the_meshes_folder(tmp_path, urdf_dir):
    mesh = _mesh(tmp_path / "robot" / "meshes" / "torso" / "base_link.stl")
    src = _urdf(tmp_path / urdf_dir / "robot.urdf", "package://meshes/torso/base_link.stl")
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    lines = _warnings(proc, "package 'meshes'")
    assert len(lines) == 1 and str(tmp_path / "robot" / "meshes") in lines[0], proc.stderr


@pytest.mark.parametrize("with_package_xml", [False, True], ids=["bare_folder", "package_xml"])
def test_sibling_folder_of_an_ancestor_is_the_package(tmp_path, with_package_xml):
    # a colcon-style src/ with the meshes in their own folder, not on any package path
    src_dir = tmp_path / "ws" / "src"
    _package_xml(src_dir / "robot_description", "robot_description")
    if with_package_xml:
        _package_xml(src_dir / "robot_meshes", "robot_meshes")
    mesh = _mesh(src_dir / "robot_meshes" / "meshes" / "arm.stl")
    src = _urdf(
        src_dir / "robot_description" / "urdf" / "robot.urdf",
        "package://robot_meshes/meshes/arm.stl",
    )
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    lines = _warnings(proc, "robot_meshes")
    assert len(lines) == 1 and str(src_dir / "robot_meshes") in lines[0], proc.stderr


def test_package_prefix_cut_off_finds_the_folder_below_the_own_package(tmp_path):
    # package://visual/x.dae where the real URI was package://pkg/meshes/<model>/visual/x.dae
    pkg = tmp_path / "abb_irb2400_support"
    mesh = _mesh(pkg / "meshes" / "irb2400" / "visual" / "base_link.stl")
    src = _urdf(pkg / "urdf" / "irb2400.urdf", "package://visual/base_link.stl")
    out = tmp_path / "out" / "irb2400.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    assert len(_warnings(proc, str(mesh.parent))) == 1, proc.stderr


def test_explicit_package_beats_every_fallback_and_warns_nothing(tmp_path):
    pkg = tmp_path / "abb_irb140_description"
    _package_xml(pkg, "abb_irb140_description")
    _mesh(pkg / "meshes" / "link.stl")
    real = tmp_path / "elsewhere" / "support"
    real_mesh = real / "meshes" / "link.stl"
    real_mesh.parent.mkdir(parents=True)
    trimesh.creation.box((0.1, 0.1, 0.1)).export(real_mesh)  # 8 vertices, not 42
    src = _urdf(pkg / "urdf" / "irb140.urdf", "package://abb_irb140_support/meshes/link.stl")
    out = tmp_path / "out" / "irb140.xml"
    proc = _convert(src, out, "--package", f"abb_irb140_support={real}")
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, real_mesh, 1)
    assert not _warnings(proc, "abb_irb140_support"), proc.stderr


def test_mesh_that_exists_nowhere_is_one_error_line(tmp_path):
    pkg = tmp_path / "robot_description"
    _package_xml(pkg, "robot_description")
    _mesh(pkg / "meshes" / "other.stl")
    uri = "package://robot_support/meshes/gone.stl"
    src = _urdf(pkg / "urdf" / "robot.urdf", uri)
    out = tmp_path / "out" / "robot.xml"
    # without --strict: a warning, the mesh dropped (test_convert_what_others_convert.py)
    proc = _convert(src, out, "--strict")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert str(src) in lines[0] and "link 'l0'" in lines[0] and uri in lines[0]
    assert "robot_support" in lines[0] and "meshes/gone.stl" in lines[0]
    assert not out.parent.exists()


def test_xacro_find_uses_a_sibling_folder(tmp_path):
    src_dir = tmp_path / "src"
    parts = src_dir / "arm_parts"
    (parts / "urdf").mkdir(parents=True)
    mesh = _mesh(parts / "meshes" / "part.stl")
    (parts / "urdf" / "part.xacro").write_text(
        '<robot xmlns:xacro="http://www.ros.org/wiki/xacro">'
        f'<link name="l0">{INERTIAL}<visual><geometry>'
        '<mesh filename="$(find arm_parts)/meshes/part.stl"/></geometry></visual></link></robot>'
    )
    src = src_dir / "arm_description" / "arm.urdf.xacro"
    src.parent.mkdir(parents=True)
    src.write_text(
        '<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:include filename="$(find arm_parts)/urdf/part.xacro"/></robot>'
    )
    out = tmp_path / "out" / "arm.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    lines = _warnings(proc, "arm_parts")
    assert len(lines) == 1 and "$(find arm_parts)" in lines[0], proc.stderr


@pytest.mark.parametrize(
    "uri",
    ["file://meshes/part.stl", "file:meshes/part.stl", "package://./meshes/part.stl"],
)
def test_relative_file_and_dot_package_uris_are_relative_to_the_urdf(tmp_path, uri):
    mesh = _mesh(tmp_path / "robot" / "meshes" / "part.stl")
    src = _urdf(tmp_path / "robot" / "robot.urdf", uri)
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)


def test_absolute_path_written_as_package_uri(tmp_path):
    mesh = _mesh(tmp_path / "meshes" / "part.stl")
    r = PackageResolver(source=tmp_path / "robot" / "robot.urdf", use_environment=False)
    assert r.resolve(f"package://{mesh}") == mesh
    assert r.notes == []


def test_strict_resolver_refuses_a_guess(tmp_path):
    pkg = tmp_path / "abb_irb140_description"
    _package_xml(pkg, "abb_irb140_description")
    _mesh(pkg / "meshes" / "link.stl")
    uri = "package://abb_irb140_support/meshes/link.stl"
    lenient = PackageResolver(source=pkg / "urdf" / "x.urdf", use_environment=False)
    assert lenient.resolve(uri) == pkg.resolve() / "meshes" / "link.stl"
    strict = PackageResolver(source=pkg / "urdf" / "x.urdf", use_environment=False, strict=True)
    with pytest.raises(PackageNotFoundError, match="abb_irb140_support.*--strict"):
        strict.resolve(uri)


def test_many_references_scan_the_tree_once(tmp_path, monkeypatch):
    from urdf2mjcf import packages

    pkg = tmp_path / "support"
    for i in range(50):
        _mesh(pkg / "meshes" / f"m{i % 5}" / "visual" / f"link_{i}.stl")
    calls = []
    real = packages._index_tree
    monkeypatch.setattr(packages, "_index_tree", lambda root: calls.append(root) or real(root))
    r = PackageResolver(source=pkg / "urdf" / "x.urdf", use_environment=False)
    for _ in range(10):  # 500 references, 50 files
        for i in range(50):
            assert r.resolve(f"package://visual/link_{i}.stl").is_file()
    assert calls == [pkg.resolve()]
    assert len(r.notes) == 5  # one per folder actually used


# -- a mesh not at the referenced path: the one file of that name nearby ----------


def _collision_urdf(path: Path, *uris: str) -> Path:
    """One link per URI, that mesh its only (collision) geometry, chained by joints."""
    text = _urdf(path, *uris).read_text()
    path.write_text(text.replace("<visual>", "<collision>").replace("</visual>", "</collision>"))
    return path


def _errors(proc: subprocess.CompletedProcess) -> list[str]:
    return [ln for ln in proc.stderr.splitlines() if ln.strip()]


def test_relative_mesh_missing_uses_the_one_file_of_that_name(tmp_path):
    # pybullet's kuka_iiwa/model_for_sdf.urdf: meshes/coarse/link_0.stl, shipped as meshes/link_0.stl
    robot = tmp_path / "kuka_iiwa"
    mesh = _mesh(robot / "meshes" / "link_0.stl")
    trimesh.creation.box((0.1, 0.1, 0.1)).export(robot / "meshes" / "link_0.obj")  # other ext
    src = _collision_urdf(robot / "model.urdf", "meshes/coarse/link_0.stl")
    out = tmp_path / "out" / "model.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    lines = _warnings(proc, "meshes/coarse/link_0.stl")
    assert len(lines) == 1 and str(mesh) in lines[0], proc.stderr
    assert len(_warnings(proc, "")) == 1, proc.stderr
    strict_out = tmp_path / "strict" / "model.xml"
    proc = _convert(src, strict_out, "--strict")
    assert proc.returncode == 2, proc.stderr
    errors = _errors(proc)
    assert len(errors) == 1 and errors[0].startswith("error:"), proc.stderr
    assert "meshes/coarse/link_0.stl" in errors[0] and "--strict" in errors[0]
    assert not strict_out.parent.exists()


def test_package_mesh_missing_uses_the_one_file_of_that_name_in_that_package(tmp_path):
    # robot_properties_fingers: meshes/stl/trifinger_table_without_border.stl is at meshes/
    pkg = tmp_path / "share" / "fingers"
    _package_xml(pkg, "fingers")
    mesh = _mesh(pkg / "meshes" / "table.stl")
    uri = "package://fingers/meshes/stl/table.stl"
    src = _collision_urdf(pkg / "urdf" / "stage.urdf", uri, uri)
    out = tmp_path / "out" / "stage.xml"
    proc = _convert(src, out, "--package-path", str(tmp_path / "share"))
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 2)
    lines = _warnings(proc, uri)
    assert len(lines) == 1 and str(mesh) in lines[0], proc.stderr  # once, not once per link


def test_two_files_of_that_name_are_an_error_naming_both(tmp_path):
    robot = tmp_path / "robot"
    a = _mesh(robot / "meshes" / "visual" / "link.stl")
    b = _mesh(robot / "meshes" / "collision" / "link.stl")
    src = _collision_urdf(robot / "robot.urdf", "meshes/coarse/link.stl")
    out = tmp_path / "out" / "robot.xml"
    # without --strict: a warning, the mesh dropped (test_convert_what_others_convert.py)
    proc = _convert(src, out, "--strict")
    assert proc.returncode == 2, proc.stderr
    errors = _errors(proc)
    assert len(errors) == 1 and errors[0].startswith("error:"), proc.stderr
    assert str(a) in errors[0] and str(b) in errors[0] and "meshes/coarse/link.stl" in errors[0]
    assert not out.parent.exists()


def test_no_file_of_that_name_keeps_the_missing_mesh_error(tmp_path):
    robot = tmp_path / "robot"
    _mesh(robot / "meshes" / "Link.stl")  # the name is case-sensitive
    _mesh(robot / "meshes" / "link.obj")  # and so is the extension
    src = _collision_urdf(robot / "robot.urdf", "meshes/coarse/link.stl")
    out = tmp_path / "out" / "robot.xml"
    # without --strict: a warning, the mesh dropped (test_convert_what_others_convert.py)
    proc = _convert(src, out, "--strict")
    assert proc.returncode == 2, proc.stderr
    errors = _errors(proc)
    assert len(errors) == 1 and "not found" in errors[0], proc.stderr
    assert "meshes/coarse/link.stl" in errors[0]


def test_many_missing_references_scan_each_folder_once(tmp_path, monkeypatch):
    from urdf2mjcf import packages

    robot = tmp_path / "robot"
    for i in range(3):
        _mesh(robot / "meshes" / f"link_{i}.stl")
    calls = []
    real = packages._index_files
    monkeypatch.setattr(packages, "_index_files", lambda root: calls.append(root) or real(root))
    r = PackageResolver(source=robot / "robot.urdf", use_environment=False)
    for i in range(200):
        found = r.resolve(f"meshes/coarse/link_{i}.stl")
        assert found.is_file() == (i < 3)
    assert calls == [robot.resolve()]
    assert len(r.notes) == 3


def _with_mujoco(path: Path, mujoco_block: str) -> Path:
    """``path``'s URDF with a ``<mujoco>`` block of the description's own."""
    path.write_text(path.read_text().replace("</robot>", f"{mujoco_block}</robot>"))
    return path


@pytest.mark.parametrize("attr", ["meshdir", "assetdir"])
def test_the_descriptions_own_compiler_meshdir_finds_its_meshes_as_mujoco_does(tmp_path, attr):
    # URIs of a package nobody has, and a <mujoco><compiler meshdir> that says where the
    # files are: MuJoCo's own import keeps the file names and looks there
    mesh = _mesh(tmp_path / "robot" / "assets" / "link.stl")
    uri = "package://vendor_robot_description/meshes/visual/link.stl"
    src = _urdf(tmp_path / "robot" / "urdf" / "robot.urdf", uri, uri)
    compiler = f'<compiler {attr}="../assets" strippath="true" discardvisual="false"/>'
    _with_mujoco(src, f"<mujoco>{compiler}</mujoco>")
    theirs = mujoco.MjModel.from_xml_path(str(src))  # the independent reading: both found
    assert list(theirs.geom_type).count(mujoco.mjtGeom.mjGEOM_MESH) == 2
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 2)
    assert "not found" not in proc.stderr and "dropped" not in proc.stderr, proc.stderr


def test_a_relative_path_below_the_descriptions_meshdir_is_found(tmp_path):
    mesh = _mesh(tmp_path / "robot" / "assets" / "visual" / "link.stl")
    src = _urdf(tmp_path / "robot" / "urdf" / "robot.urdf", "visual/link.stl")
    _with_mujoco(src, '<mujoco><compiler meshdir="../assets" discardvisual="false"/></mujoco>')
    theirs = mujoco.MjModel.from_xml_path(str(src))
    assert list(theirs.geom_type).count(mujoco.mjtGeom.mjGEOM_MESH) == 1
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    assert "dropped" not in proc.stderr, proc.stderr


def test_a_relative_path_one_folder_off_is_found_where_the_layout_keeps_meshes(tmp_path):
    # urdf/robot.urdf names ./meshes/x.stl; the package ships meshes/ beside urdf/
    mesh = _mesh(tmp_path / "robot" / "meshes" / "base.stl")
    src = _urdf(tmp_path / "robot" / "urdf" / "robot.urdf", "./meshes/base.stl", "meshes/base.stl")
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 2)
    lines = _warnings(proc, "one folder up")
    assert len(lines) == 2 and all(str(mesh) in ln for ln in lines), proc.stderr
    # a guess: --strict refuses it, naming the reference
    proc = _convert(src, tmp_path / "strict" / "robot.xml", "--strict")
    assert proc.returncode == 2 and "./meshes/base.stl" in proc.stderr, proc.stderr


def test_a_mesh_found_by_name_in_a_sibling_meshes_folder(tmp_path):
    mesh = _mesh(tmp_path / "robot" / "meshes" / "wheel.stl")
    src = _urdf(tmp_path / "robot" / "urdf" / "robot.urdf", "parts/wheel.stl")
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    _assert_uses(out, mesh, 1)
    assert len(_warnings(proc, "in the meshes folder one folder up")) == 1, proc.stderr


def test_a_certificate_never_passes_silently_over_meshes_it_could_not_find(tmp_path):
    mesh = _mesh(tmp_path / "robot" / "meshes" / "base.stl")
    src = _urdf(tmp_path / "robot" / "robot.urdf", str(mesh), "nowhere/lost_a.stl", "nowhere/lost_b.stl")
    out = tmp_path / "out" / "robot.xml"
    proc = _convert(src, out)
    assert proc.returncode == 0, proc.stderr
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("certificate:"))
    assert line.startswith("certificate: passed"), line
    assert line.endswith(
        "; the description's flaw: 2 meshes it names were not found or not readable and "
        "are missing from the model (see the warnings)"
    ), line
    assert len([ln for ln in proc.stderr.splitlines() if "lost_" in ln and "dropped" in ln]) == 2
