"""Issue 19 item 6 for the converter: every number it reads is finite and in range.

A bad number -- NaN, infinity, 1e300, a negative count -- on the command line,
in the URDF, in its ``<mujoco>`` extension, in the actuator config or in a mesh
is one ``error:`` line naming where it came from, exit 2, nothing written; never
an internal error (ValueError, OverflowError, LinAlgError) or a model with NaN.
A mesh vertex that is not finite drops the faces that use it, with a warning.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.security.attack import assert_one_error, run

TIMEOUT = 60

INERTIAL = (
    '<inertial><origin xyz="{xyz}"/><mass value="{mass}"/>'
    '<inertia ixx="{ixx}" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)
JOINT = (
    '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
    '<origin xyz="{jxyz}" rpy="{rpy}"/><axis xyz="0 0 1"/>'
    '<limit lower="{lower}" upper="{upper}" effort="{effort}" velocity="{velocity}"/></joint>'
)
VALUES = {
    "xyz": "0 0 0",
    "mass": "1",
    "ixx": "0.01",
    "jxyz": "0 0 0.1",
    "rpy": "0 0 0",
    "lower": "-1",
    "upper": "1",
    "effort": "10",
    "velocity": "1",
}

CUBE_VERTS = [
    (0, 0, 0),
    (1, 0, 0),
    (1, 1, 0),
    (0, 1, 0),
    (0, 0, 1),
    (1, 0, 1),
    (1, 1, 1),
    (0, 1, 1),
]
CUBE_FACES = [
    (1, 3, 2), (1, 4, 3), (5, 6, 7), (5, 7, 8), (1, 2, 6), (1, 6, 5),
    (2, 3, 7), (2, 7, 6), (3, 4, 8), (3, 8, 7), (4, 1, 5), (4, 5, 8),
]  # fmt: skip


def urdf(extra: str = "", link: str = "", **values: str) -> str:
    v = {**VALUES, **values}
    box = '<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>'
    return (
        f'<robot name="r"><link name="base">{INERTIAL.format(**v)}{link}</link>'
        f'<link name="arm">{INERTIAL.format(**VALUES)}{box}</link>'
        f"{JOINT.format(**v)}{extra}</robot>"
    )


def convert(tmp_path: Path, text: str, *args: str, command: tuple[str, ...] = ()):
    source = tmp_path / "robot.urdf"
    source.write_text(text)
    output = tmp_path / "out" / "robot.xml"
    if command:  # urdf2mjcf batch PATHS -o FOLDER
        argv = (*command, str(source), "-o", str(tmp_path / "out"))
    else:
        argv = (str(source), "-o", str(output))
    res = run("urdf2mjcf", *argv, "--no-cache", *args, cwd=tmp_path, timeout=TIMEOUT)
    return res, (tmp_path / "out").exists()


def assert_bad_number(tmp_path: Path, text: str, *needles: str, args=(), command=()) -> str:
    res, made = convert(tmp_path, text, *args, command=command)
    line = assert_one_error(res, *needles)
    assert not made, "output written for a bad number"
    return line


# -- command-line options ------------------------------------------------------------------


@pytest.mark.parametrize(
    "args",
    [
        ("--density", "nan"),
        ("--density", "inf"),
        ("--density", "-1"),
        ("--density", "0"),
        ("--density", "1e300"),
        ("--link-density", "base=nan"),
        ("--link-density", "base=-inf"),
        ("--link-density", "base"),
        ("--max-faces", "0"),
        ("--max-faces", "3"),
        ("--max-faces", "nan"),
        ("-j", "-1"),
        ("-j", "100000"),
        ("--decompose-timeout", "nan"),
        ("--decompose-timeout", "inf"),
    ],
)
def test_bad_option_number_is_one_error_naming_the_option(tmp_path: Path, args) -> None:
    option = args[0]
    line = assert_bad_number(tmp_path, urdf(), option.lstrip("-")[:3], args=args)
    assert "expected" in line or "is not" in line, line  # says what is valid


@pytest.mark.parametrize(
    "args", [("--density", "nan"), ("--max-faces", "0"), ("--decompose-timeout", "-1")]
)
def test_batch_options_are_checked_too(tmp_path: Path, args) -> None:
    assert_bad_number(tmp_path, urdf(), args[0], args=args, command=("batch",))


# -- numbers in the URDF -------------------------------------------------------------------


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e300"])
@pytest.mark.parametrize(
    ("field", "element"),
    [
        ("xyz", "origin xyz"),
        ("mass", "mass value"),
        ("ixx", "inertia ixx"),
        ("jxyz", "origin xyz"),
        ("rpy", "origin rpy"),
        ("lower", "limit lower"),
        ("upper", "limit upper"),
        ("effort", "limit effort"),
        ("velocity", "limit velocity"),
    ],
)
def test_bad_urdf_number_is_one_error_naming_the_element(
    tmp_path: Path, field: str, element: str, value: str
) -> None:
    if field in ("xyz", "jxyz", "rpy"):
        value = f"{value} 0 0"
    where = (
        "joint 'j'"
        if field in ("jxyz", "rpy", "lower", "upper", "effort", "velocity")
        else ("link 'base'")
    )
    assert_bad_number(tmp_path, urdf(**{field: value}), "robot.urdf", where, element)


def test_large_joint_limit_meaning_unlimited_is_accepted(tmp_path: Path) -> None:
    # example-robot-data's iris writes lower="-1e+16" upper="1e+16"
    res, made = convert(tmp_path, urdf(lower="-1e+16", upper="1e+16"), "--no-validate")
    assert res.returncode == 0, res.stderr[-2000:]


# -- numbers in the <mujoco> extension -----------------------------------------------------


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ('<option timestep="nan"/>', "timestep"),
        ('<option timestep="0"/>', "timestep"),
        ('<option timestep="-0.001"/>', "timestep"),
        ('<option timestep="10"/>', "timestep"),
        ('<option iterations="1e9"/>', "iterations"),
        ('<option iterations="2.5"/>', "iterations"),
        ('<option gravity="0 0 1e300"/>', "gravity"),
        ('<option><flag energy="enable"/></option><option density="inf"/>', "density"),
        ('<compiler boundmass="nan"/>', "boundmass"),
        ('<size memory="100000G"/>', "memory"),
        ('<visual><global offwidth="1000000"/></visual>', "offwidth"),
        ('<statistic extent="-inf"/>', "extent"),
    ],
)
def test_bad_extension_number_is_one_error_naming_the_element(
    tmp_path: Path, content: str, needle: str
) -> None:
    assert_bad_number(tmp_path, urdf(extra=f"<mujoco>{content}</mujoco>"), "mujoco", needle)


# -- numbers in the actuator config --------------------------------------------------------


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ("joints: {j: {kp: .nan}}", "kp"),
        ("joints: {j: {kv: .inf}}", "kv"),
        ("joints: {j: {kp: 1e300}}", "kp"),
        ("joints: {j: {forcerange: [-1e300, 1e300]}}", "forcerange"),
        ("joints: {j: {armature: -1}}", "armature"),
        ("defaults: {bandwidth_hz: 0}", "bandwidth_hz"),
        ("gravcomp: {base: .nan}", "gravcomp"),
        (f"joints: {{j: {{kp: {'9' * 400}}}}}", "kp"),
    ],
)
def test_bad_actuator_config_number_is_one_error_naming_the_key(
    tmp_path: Path, body: str, needle: str
) -> None:
    config = tmp_path / "actuators.yaml"
    config.write_text(body + "\n")
    line = assert_bad_number(
        tmp_path, urdf(), "actuators.yaml", needle, args=("--actuator-config", str(config))
    )
    assert len(line) < 400, line


# -- mesh vertices -------------------------------------------------------------------------


def write_obj(path: Path, verts, faces) -> None:
    lines = [f"v {x} {y} {z}" for x, y, z in verts] + [f"f {a} {b} {c}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("bad", ["nan", "inf", "1e300"])
def test_faces_using_a_non_finite_vertex_are_dropped_with_a_warning(
    tmp_path: Path, bad: str
) -> None:
    # the cube, plus one stray triangle reaching a NaN vertex: the cube is kept
    verts = [*CUBE_VERTS, (bad, 0, 0)]
    write_obj(tmp_path / "part.obj", verts, [*CUBE_FACES, (1, 2, 9)])
    mesh = '<collision><geometry><mesh filename="part.obj" scale="0.1 0.1 0.1"/></geometry></collision>'
    res, made = convert(tmp_path, urdf(link=mesh))
    assert res.returncode == 0, res.stderr[-2000:]
    assert "1 face(s) with a NaN, infinite or out-of-range vertex" in res.stderr
    assert "nan" not in (tmp_path / "out" / "robot.xml").read_text().lower()


def test_mesh_with_only_non_finite_faces_is_dropped_naming_it(tmp_path: Path) -> None:
    """No usable triangle left: the geom is dropped with a warning saying why (as any
    collision mesh without usable triangles, issue 24), an error with --strict."""
    verts = [(float("nan"), 0, 0), *CUBE_VERTS[1:]]
    faces = [f for f in CUBE_FACES if 1 in f]
    write_obj(tmp_path / "part.obj", verts, faces)
    mesh = '<collision><geometry><mesh filename="part.obj"/></geometry></collision>'
    res, made = convert(tmp_path, urdf(link=mesh))
    assert res.returncode == 0, res.stderr
    (line,) = [w for w in res.stderr.splitlines() if "part.obj" in w]
    assert line.startswith("warning:") and "no usable triangles" in line and "NaN" in line
    assert made
    res, _ = convert(tmp_path, urdf(link=mesh), "--strict", "--overwrite")
    assert_one_error(res, "part.obj", "no usable triangles", "NaN")
