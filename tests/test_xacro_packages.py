"""xacro expansion with arguments and package lookup without ROS."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from urdf2mjcf.cli import urdf2mjcf_command
from urdf2mjcf.errors import PackageNotFoundError
from urdf2mjcf.packages import PackageResolver
from urdf2mjcf.passes import parse, xacro

BOX_STL = None


def _stl(path: Path) -> Path:
    import trimesh

    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box((0.1, 0.1, 0.1)).export(path)
    return path


def _package(root: Path, folder: str, name: str | None = None) -> Path:
    pkg = root / folder
    (pkg / "meshes").mkdir(parents=True)
    if name:
        (pkg / "package.xml").write_text(
            f"<package format='3'><name>{name}</name><version>1.0.0</version></package>"
        )
    _stl(pkg / "meshes" / "part.stl")
    return pkg


XACRO = """<?xml version="1.0"?>
<robot name="gripper_bot" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="use_gripper" default="false"/>
  <xacro:arg name="finger_length" default="0.05"/>
  <xacro:include filename="$(find parts_pkg)/urdf/parts.xacro"/>
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="package://parts_pkg/meshes/part.stl"/></geometry></visual></link>
  <xacro:if value="$(arg use_gripper)">
    <xacro:finger name="finger" length="$(arg finger_length)"/>
  </xacro:if>
</robot>
"""
PARTS = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="finger" params="name length">
    <link name="${name}"><inertial><mass value="0.1"/><inertia ixx="1e-5" iyy="1e-5" izz="1e-5" ixy="0" ixz="0" iyz="0"/></inertial>
      <collision><geometry><box size="0.01 0.01 ${length}"/></geometry></collision></link>
    <joint name="${name}_joint" type="prismatic"><parent link="base"/><child link="${name}"/><axis xyz="1 0 0"/>
      <limit lower="0" upper="0.025" effort="20" velocity="0.1"/></joint>
  </xacro:macro>
</robot>
"""


@pytest.fixture
def workspace(tmp_path: Path) -> Path:
    share = tmp_path / "ws" / "install" / "share"
    pkg = _package(share, "parts_pkg", "parts_pkg")
    (pkg / "urdf").mkdir()
    (pkg / "urdf" / "parts.xacro").write_text(PARTS)
    src = tmp_path / "robot.urdf.xacro"
    src.write_text(XACRO)
    return tmp_path


def test_xacro_arguments_select_components(workspace):
    share = workspace / "ws" / "install" / "share"
    for args, expect in (
        ({}, {"base"}),
        ({"use_gripper": "true", "finger_length": "0.08"}, {"base", "finger"}),
    ):
        cfg = xacro.XacroConfig(args=args, package_paths=(share,), use_environment=False)
        model = parse.run(xacro.run(workspace / "robot.urdf.xacro", cfg))
        assert {link.name for link in model.robot.links} == expect
    finger = model.robot.link_map["finger"].collisions[0].geometry
    assert finger.size == (0.01, 0.01, 0.08)


def test_cli_takes_ros_style_arguments_and_package_path(workspace):
    out = workspace / "out" / "robot.xml"
    result = CliRunner().invoke(
        urdf2mjcf_command,
        [
            str(workspace / "robot.urdf.xacro"),
            "-o",
            str(out),
            "use_gripper:=true",
            "--package-path",
            str(workspace / "ws" / "install" / "share"),
            "--no-ros-env",
        ],
    )
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert 'name="finger_joint"' in text
    assert (out.parent / "scene.xml").is_file()
    assert any((out.parent / "assets").iterdir())


def test_unknown_package_in_find_is_a_package_error(workspace):
    cfg = xacro.XacroConfig(use_environment=False)
    with pytest.raises(PackageNotFoundError, match="parts_pkg"):
        xacro.run(workspace / "robot.urdf.xacro", cfg)


def test_package_found_by_package_xml_name_when_folder_differs(tmp_path):
    _package(tmp_path / "src", "folder_name", "real_name")
    r = PackageResolver(
        source=tmp_path / "x.urdf", package_paths=(tmp_path / "src",), use_environment=False
    )
    assert r.find("real_name") == (tmp_path / "src" / "folder_name").resolve()
    assert r.find("folder_name") == (tmp_path / "src" / "folder_name").resolve()


def test_explicit_package_beats_search_path(tmp_path):
    a = _package(tmp_path / "a", "pkg", "pkg")
    b = _package(tmp_path / "b", "pkg", "pkg")
    r = PackageResolver(
        source=tmp_path / "x.urdf",
        packages={"pkg": b},
        package_paths=(tmp_path / "a",),
        use_environment=False,
    )
    assert r.find("pkg") == b.resolve() != a.resolve()


def test_environment_variables_are_searched(tmp_path, monkeypatch):
    _package(tmp_path / "ros1", "old_pkg", "old_pkg")
    _package(tmp_path / "prefix" / "share", "new_pkg", "new_pkg")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "ros1"))
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path / "prefix"))
    r = PackageResolver(source=tmp_path / "x.urdf")
    assert r.find("old_pkg").name == "old_pkg"
    assert r.find("new_pkg") == (tmp_path / "prefix" / "share" / "new_pkg").resolve()
    off = PackageResolver(source=tmp_path / "x.urdf", use_environment=False)
    with pytest.raises(PackageNotFoundError):
        off.find("new_pkg")


def test_walking_up_from_source_finds_enclosing_package(tmp_path):
    pkg = _package(tmp_path, "my_robot_description", "my_robot_description")
    vendored = tmp_path / "bundle" / "other_description"
    (vendored / "urdf").mkdir(parents=True)
    r = PackageResolver(source=pkg / "urdf" / "robot.urdf", use_environment=False)
    assert r.find("my_robot_description") == pkg.resolve()
    r2 = PackageResolver(source=vendored / "urdf" / "robot.urdf", use_environment=False)
    assert r2.find("other_description") == vendored.resolve(), (
        "folder name counts without package.xml"
    )


@pytest.mark.parametrize(
    "uri, expect",
    [
        ("package://pkg/meshes/part.stl", "pkg/meshes/part.stl"),
        ("package:///pkg/meshes/part.stl", "pkg/meshes/part.stl"),
        ("meshes/part.stl", "src_dir/meshes/part.stl"),
    ],
)
def test_resource_uris_resolve(tmp_path, uri, expect):
    _package(tmp_path, "pkg", "pkg")
    src = tmp_path / "src_dir" / "robot.urdf"
    r = PackageResolver(source=src, package_paths=(tmp_path,), use_environment=False)
    assert r.resolve(uri) == (tmp_path / expect).resolve() or r.resolve(uri) == tmp_path / expect


def test_file_uri_is_an_absolute_path(tmp_path):
    r = PackageResolver(source=tmp_path / "robot.urdf", use_environment=False)
    assert r.resolve("file:///opt/meshes/a%20b.stl") == Path("/opt/meshes/a b.stl")
