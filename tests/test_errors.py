"""Bad input: one line on stderr starting with 'error:', naming the file and
the element; exit code 2; no traceback; nothing written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import urdf2mjcf
from urdf2mjcf import errors

LINK = '<link name="{n}"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'


def robot(body: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="bad">\n{body}\n</robot>\n'


def chain(*names: str) -> str:
    links = "".join(LINK.format(n=n) for n in names)
    joints = "".join(
        f'<joint name="j{i}" type="revolute"><parent link="{a}"/><child link="{b}"/><axis xyz="0 0 1"/>'
        f'<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        for i, (a, b) in enumerate(zip(names, names[1:], strict=False))
    )
    return links + joints


def mesh_link(filename: str, where: str = "collision") -> str:
    return (
        LINK.format(n="base").replace("</link>", "")
        + f'<{where}><geometry><mesh filename="{filename}"/></geometry></{where}></link>'
    )


CASES = {
    "malformed_xml": (
        "robot.urdf",
        '<robot name="x"><link name="a"></robot>',
        "line",
        errors.InputError,
    ),
    "missing_mesh": (
        "robot.urdf",
        robot(mesh_link("meshes/nowhere.stl")),
        "link 'base'",
        errors.MeshError,
    ),
    "lfs_pointer_mesh": ("robot.urdf", robot(mesh_link("lfs.stl")), "LFS", errors.MeshError),
    "unknown_package": (
        "robot.urdf",
        robot(mesh_link("package://no_such_pkg/meshes/a.stl")),
        "no_such_pkg",
        errors.PackageNotFoundError,
    ),
    "two_roots": (
        "robot.urdf",
        robot(LINK.format(n="a") + LINK.format(n="b")),
        "2 root links",
        errors.URDFError,
    ),
    "joint_cycle": (
        "robot.urdf",
        robot(
            chain("a", "b", "c")
            + '<joint name="back" type="fixed"><parent link="c"/><child link="a"/></joint>'
        ),
        "cycle",
        errors.URDFError,
    ),
    "duplicate_link": (
        "robot.urdf",
        robot(LINK.format(n="a") + LINK.format(n="a")),
        "link 'a'",
        errors.URDFError,
    ),
    "unknown_joint_type": (
        "robot.urdf",
        robot(
            LINK.format(n="a")
            + LINK.format(n="b")
            + '<joint name="s" type="screw"><parent link="a"/><child link="b"/></joint>'
        ),
        "joint 's'",
        errors.URDFError,
    ),
    "cylinder_without_radius": (
        "robot.urdf",
        robot(
            LINK.format(n="a").replace(
                "</link>",
                '<collision><geometry><cylinder length="0.1"/></geometry></collision></link>',
            )
        ),
        "radius",
        errors.URDFError,
    ),
    "negative_mass": (
        "robot.urdf",
        robot(LINK.format(n="a").replace('value="1"', 'value="-2"')),
        "link 'a'",
        errors.InertiaError,
    ),
    "xacro_error": (
        "robot.urdf.xacro",
        '<robot name="x" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="${undefined_property * 2}"/></robot>',
        "undefined_property",
        errors.XacroError,
    ),
}


STRICT = {"missing_mesh", "unknown_package"}
"""Errors only with --strict: without it the mesh is dropped with a warning
(tests/test_convert_what_others_convert.py)."""


def _write_case(tmp_path: Path, name: str) -> tuple[Path, str, type]:
    filename, text, needle, exc = CASES[name]
    src = tmp_path / "in" / filename
    src.parent.mkdir()
    src.write_text(text)
    (src.parent / "lfs.stl").write_text(
        "version https://git-lfs.github.com/spec/v1\noid sha256:4d7a214614ab2935c943f9e0ff69d22eadbb8f32b1258daaa5e2ca24d17e2393\nsize 12345\n"
    )
    return src, needle, exc


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_gives_one_error_line_exit_2_and_no_output(case, tmp_path):
    src, needle, _ = _write_case(tmp_path, case)
    before = sorted(p.read_bytes() for p in src.parent.iterdir())
    out = tmp_path / "out" / "robot.xml"
    proc = subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", str(src), "-o", str(out), "--no-ros-env"]
        + (["--strict"] if case in STRICT else []),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ")
    assert "Traceback" not in proc.stderr
    assert src.name in lines[0], "the message names the file"
    assert needle in lines[0]
    assert not (tmp_path / "out").exists(), "nothing is written on failure"
    assert sorted(p.read_bytes() for p in src.parent.iterdir()) == before, "input untouched"


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_raises_specific_error_from_api(case, tmp_path):
    src, needle, exc = _write_case(tmp_path, case)
    with pytest.raises(exc) as info:
        urdf2mjcf.convert(
            src, tmp_path / "out" / "robot.xml", use_environment=False, strict=case in STRICT
        )
    assert needle in str(info.value)
    assert isinstance(info.value, errors.ConversionError)


def test_existing_output_is_not_overwritten_without_flag(tmp_path, data_dir):
    src = tmp_path / "r.urdf"
    src.write_text(robot(LINK.format(n="a")))
    out = tmp_path / "robot.xml"
    out.write_text("keep me")
    proc = subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", str(src), "-o", str(out)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and "--overwrite" in proc.stderr
    assert out.read_text() == "keep me"
    proc = subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", str(src), "-o", str(out), "--overwrite"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert "<mujoco" in out.read_text()


def test_bad_xacro_argument_syntax_is_a_one_line_usage_error(tmp_path):
    src = tmp_path / "r.urdf"
    src.write_text(robot(LINK.format(n="a")))
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "urdf2mjcf",
            str(src),
            "use_gripper=true",
            "-o",
            str(tmp_path / "o.xml"),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and len(proc.stderr.strip().splitlines()) == 1
