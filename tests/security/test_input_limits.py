"""Issue 19 item 5 for the converter: nothing hangs, nothing exhausts memory.

Each probe runs the real ``urdf2mjcf`` command in a fresh process under the
address-space limit of :mod:`tests.security.attack` and a time limit: a FIFO
read would block until the timeout, a ``/dev/zero`` read or an alias bomb would
hit the memory limit (MemoryError: 'internal error', exit 1). Only regular
files are read, within their size limits; validation steps a bounded number of
times whatever the model's timestep.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.security.attack import assert_one_error, run, snapshot

TIMEOUT = 60
"""Seconds a probe may take (a conversion of these tiny robots takes a few)."""

CUBE_OBJ = """\
v 0 0 0
v 0.1 0 0
v 0.1 0.1 0
v 0 0.1 0
v 0 0 0.1
v 0.1 0 0.1
v 0.1 0.1 0.1
v 0 0.1 0.1
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
"""

INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)

BILLION_LAUGHS = """\
a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]
b: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]
c: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]
d: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]
e: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]
f: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]
g: &g [*f,*f,*f,*f,*f,*f,*f,*f,*f]
h: &h [*g,*g,*g,*g,*g,*g,*g,*g,*g]
i: &i [*h,*h,*h,*h,*h,*h,*h,*h,*h]
"""


def robot(body: str = "", extra: str = "") -> str:
    """A one-link robot: its link holds ``body`` (visuals, collisions), ``extra``
    follows the link (joints, ``<mujoco>``)."""
    return f'<robot name="r"><link name="base">{INERTIAL}{body}</link>{extra}</robot>'


def mesh_visual(filename: str) -> str:
    return f'<visual><geometry><mesh filename="{filename}"/></geometry></visual>'


def convert(tmp_path: Path, urdf: str, *args: str, env: dict[str, str] | None = None):
    """Run ``urdf2mjcf`` on ``urdf`` (written to tmp_path/robot.urdf) into tmp_path/out;
    the result, and whether the output folder was made."""
    source = tmp_path / "robot.urdf"
    source.write_text(urdf)
    output = tmp_path / "out" / "robot.xml"
    res = run(
        "urdf2mjcf",
        str(source),
        "-o",
        str(output),
        "--no-cache",
        *args,
        cwd=tmp_path,
        timeout=TIMEOUT,
        env=env,
    )
    return res, output.parent.exists()


def assert_refused(tmp_path: Path, urdf: str, *needles: str, args: tuple[str, ...] = ()) -> str:
    before = snapshot(tmp_path)
    res, made = convert(tmp_path, urdf, *args)
    line = assert_one_error(res, *needles)
    assert not made, "output written for refused input"
    after = snapshot(tmp_path)
    after.pop(str(tmp_path / "robot.urdf"), None)
    before.pop(str(tmp_path / "robot.urdf"), None)
    assert after == before  # nothing else made, nothing changed
    return line


# -- meshes and the files they pull in -----------------------------------------------------


def test_mesh_that_is_a_fifo_is_refused_not_opened(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "part.obj")
    assert_refused(tmp_path, robot(mesh_visual("part.obj")), "part.obj", "FIFO")


def test_mesh_symlinked_to_dev_zero_is_refused(tmp_path: Path) -> None:
    (tmp_path / "part.stl").symlink_to("/dev/zero")
    assert_refused(tmp_path, robot(mesh_visual("part.stl")), "part.stl", "device")


@pytest.mark.parametrize("mtl", ["/dev/zero", "fifo"])
def test_obj_mtllib_that_is_not_a_regular_file_is_refused(tmp_path: Path, mtl: str) -> None:
    if mtl == "fifo":
        os.mkfifo(tmp_path / "part.mtl")
        mtl = "part.mtl"
    (tmp_path / "part.obj").write_text(f"mtllib {mtl}\n" + CUBE_OBJ)
    kind = "device" if mtl == "/dev/zero" else "FIFO"
    assert_refused(tmp_path, robot(mesh_visual("part.obj")), "part.obj", mtl, kind)


def test_obj_texture_that_is_a_fifo_is_refused(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "skin.png")
    (tmp_path / "part.mtl").write_text("newmtl skin\nKd 1 1 1\nmap_Kd skin.png\n")
    uv = "vt 0 0\nvt 1 0\nvt 1 1\n"
    faces = "".join(
        f"f {a}/1 {b}/2 {c}/3\n"
        for a, b, c in (line.split()[1:] for line in CUBE_OBJ.splitlines() if line[0] == "f")
    )
    verts = "".join(line + "\n" for line in CUBE_OBJ.splitlines() if line[0] == "v")
    (tmp_path / "part.obj").write_text(f"mtllib part.mtl\n{verts}{uv}usemtl skin\n{faces}")
    assert_refused(tmp_path, robot(mesh_visual("part.obj")), "skin.png", "FIFO")


def test_urdf_texture_that_is_a_fifo_is_refused(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "skin.png")
    visual = (
        '<visual><geometry><box size="0.1 0.1 0.1"/></geometry>'
        '<material name="m"><texture filename="skin.png"/></material></visual>'
    )
    assert_refused(tmp_path, robot(visual), "skin.png", "FIFO", "material 'm'")


def test_mesh_over_the_size_limit_names_file_and_variable(tmp_path: Path) -> None:
    # 0.001 MB is 1048 bytes; the cube with a comment is past it (no huge file needed)
    (tmp_path / "part.obj").write_text("# " + "x" * 2000 + "\n" + CUBE_OBJ)
    before = snapshot(tmp_path)
    res, made = convert(
        tmp_path, robot(mesh_visual("part.obj")), env={"URDF2MJCF_MAX_MESH_MB": "0.001"}
    )
    assert_one_error(res, "part.obj", "URDF2MJCF_MAX_MESH_MB", "limit")
    assert not made
    before.pop(str(tmp_path / "robot.urdf"), None)
    after = snapshot(tmp_path)
    after.pop(str(tmp_path / "robot.urdf"), None)
    assert after == before


# -- the <mujoco> extension ----------------------------------------------------------------


def test_extension_asset_file_that_is_a_fifo_is_refused(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "extra.stl")
    ext = '<mujoco><asset><mesh name="extra" file="extra.stl"/></asset></mujoco>'
    assert_refused(tmp_path, robot(extra=ext), "extra.stl", "FIFO", "mujoco asset mesh")


@pytest.mark.parametrize(
    "content",
    [
        '<worldbody><include file="/dev/zero"/></worldbody>',
        '<worldbody><body name="b"><include file="/dev/zero"/></body></worldbody>',
    ],
)
def test_extension_element_that_makes_mujoco_read_a_file_is_refused(
    tmp_path: Path, content: str
) -> None:
    assert_refused(tmp_path, robot(extra=f"<mujoco>{content}</mujoco>"), "include", "read a file")


def test_tiny_timestep_validates_in_bounded_steps(tmp_path: Path) -> None:
    # MuJoCo accepts any positive timestep; 1e-300 asked 1e300 steps of validation
    res, made = convert(tmp_path, robot(extra='<mujoco><option timestep="1e-300"/></mujoco>'))
    assert res.returncode == 0, res.stderr[-2000:]
    assert made


# -- YAML inputs ---------------------------------------------------------------------------


def test_actuator_config_that_is_a_fifo_is_refused(tmp_path: Path) -> None:
    fifo = tmp_path / "actuators.yaml"
    os.mkfifo(fifo)
    assert_refused(
        tmp_path, robot(), "actuators.yaml", "FIFO", args=("--actuator-config", str(fifo))
    )


def test_actuator_config_alias_bomb_is_refused(tmp_path: Path) -> None:
    bomb = tmp_path / "actuators.yaml"
    bomb.write_text(BILLION_LAUGHS)
    assert_refused(
        tmp_path,
        robot(),
        "actuators.yaml",
        "expands to more than",
        args=("--actuator-config", str(bomb)),
    )


def test_actuator_config_that_is_not_yaml_is_not_echoed(tmp_path: Path) -> None:
    # a system file named by mistake (or by a recipe): the error quotes a short excerpt
    passwd = tmp_path / "passwd"
    secret = "".join(f"user{i}:x:{1000 + i}:{1000 + i}::/home/user{i}:/bin/sh " for i in range(200))
    passwd.write_text(secret)
    line = assert_refused(tmp_path, robot(), "passwd", args=("--actuator-config", str(passwd)))
    assert len(line) < 400, line
    assert "user150" not in line


def test_schema_errors_quote_only_an_excerpt(tmp_path: Path) -> None:
    from urdf2mjcf.errors import InputError
    from urdf2mjcf.schema import load

    text = tmp_path / "components.yaml"
    text.write_text("root:x:0:0:root:/root:/bin/bash " * 500)
    data, source = load(text, "component table")
    for check in (
        lambda: source.mapping(data, "components"),
        lambda: source.number(data, "components"),
        lambda: source.mapping({data: 1}, "x") and source.known({data: 1}, ["a"], "components"),
    ):
        with pytest.raises(InputError) as err:
            check()
        assert len(str(err.value)) < 400, str(err.value)


def test_package_xml_that_is_a_fifo_is_skipped(tmp_path: Path) -> None:
    from urdf2mjcf.packages import _package_xml_name

    os.mkfifo(tmp_path / "package.xml")
    assert _package_xml_name(tmp_path) is None  # would block forever if opened
