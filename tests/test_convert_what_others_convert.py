"""Descriptions urdfdom, RViz or Gazebo accept and we used to refuse (issue 24 item 3),
through the command line: each liberty is one ``warning:`` line and the model MuJoCo
compiles; ``--strict`` turns it into the one error line. Every hint an error prints is
followed here as printed and must work (``--trust-xacro``'s is followed in
tests/security/test_xacro_code.py, ``--overwrite``'s in tests/test_errors.py).

Meshes are made here with trimesh (GLB with a material and an embedded texture
included); nothing is copied from a robot collection.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from tests.security.attack import Result, assert_one_error, run

INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)


def link(name: str, *geoms: str, inertial: str = INERTIAL) -> str:
    return f'<link name="{name}">{inertial}{"".join(geoms)}</link>'


def mesh(role: str, filename: str) -> str:
    return f'<{role}><geometry><mesh filename="{filename}"/></geometry></{role}>'


def box(role: str) -> str:
    return f'<{role}><geometry><box size="0.1 0.1 0.1"/></geometry></{role}>'


def joint(parent: str, child: str, kind: str = "revolute", xyz: str = "0 0 0.2") -> str:
    limit = '<limit lower="-1" upper="1" effort="1" velocity="1"/>' if kind != "fixed" else ""
    return (
        f'<joint name="{parent}_{child}" type="{kind}"><parent link="{parent}"/>'
        f'<child link="{child}"/><origin xyz="{xyz}"/><axis xyz="0 0 1"/>{limit}</joint>'
    )


def write_urdf(path: Path, *body: str, extra_ns: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        f'<?xml version="1.0"?>\n<robot name="r"{extra_ns}>\n{"".join(body)}\n</robot>\n'
    )
    return path


def cube(path: Path, size: float = 0.1) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box(extents=(size, size, size)).export(path)
    return path


def convert(tmp_path: Path, src: Path, *args: str) -> tuple[Result, Path]:
    out = tmp_path / "out" / "robot.xml"
    tmp_path.mkdir(parents=True, exist_ok=True)
    res = run(
        "urdf2mjcf",
        str(src),
        "-o",
        str(out),
        "--overwrite",
        "--no-ros-env",
        "--cache-dir",
        str(tmp_path / "cache"),
        *args,
        cwd=tmp_path,
    )
    return res, out


def ok(res: Result) -> list[str]:
    """Exit 0; the warning lines."""
    assert res.returncode == 0, res.stderr[-3000:]
    assert "Traceback" not in res.stderr
    return [line for line in res.stderr.splitlines() if line.startswith("warning: ")]


def geoms(out: Path, body: str, group: int | None = None) -> list[int]:
    """Geoms of ``body`` in the written model (collision: contype or conaffinity set)."""
    m = mujoco.MjModel.from_xml_path(str(out))
    b = m.body(body).id
    ids = [g for g in range(m.ngeom) if m.geom_bodyid[g] == b]
    if group == 3:  # collision geoms collide
        ids = [g for g in ids if m.geom_contype[g] or m.geom_conaffinity[g]]
    return ids


def collision_geoms(out: Path, body: str) -> int:
    return len(geoms(out, body, group=3))


# -- a mesh that cannot be found, or is ambiguous ------------------------------------


def test_missing_collision_mesh_is_a_warning_and_the_geom_is_dropped(tmp_path):
    src = write_urdf(
        tmp_path / "robot" / "robot.urdf",
        link("base", box("collision")),
        link("arm", mesh("visual", "meshes/gone.stl"), mesh("collision", "meshes/gone.stl")),
        joint("base", "arm"),
    )
    res, out = convert(tmp_path, src)
    warnings = ok(res)
    assert any(
        "link 'arm' collision mesh 'meshes/gone.stl'" in w and "dropped" in w for w in warnings
    )
    assert any("link 'arm'" in w and "no collision geometry left" in w for w in warnings)
    assert collision_geoms(out, "arm") == 0 and collision_geoms(out, "base") == 1

    res, strict_out = convert(tmp_path / "strict", src, "--strict")
    assert_one_error(res, "robot.urdf", "link 'arm'", "meshes/gone.stl")
    assert not strict_out.parent.exists()


def test_unknown_package_is_a_warning_and_both_printed_hints_work(tmp_path):
    parts = tmp_path / "elsewhere" / "parts_pkg"
    cube(parts / "meshes" / "arm.stl")
    src = write_urdf(  # two levels down: the resolver's own guesses do not reach parts_pkg
        tmp_path / "ws" / "src" / "robot" / "robot.urdf",
        link("base", box("collision")),
        link("arm", mesh("collision", "package://parts_pkg/meshes/arm.stl")),
        joint("base", "arm"),
    )
    res, out = convert(tmp_path, src)
    assert any("package 'parts_pkg' not found" in w and "dropped" in w for w in ok(res))
    assert collision_geoms(out, "arm") == 0

    res, _ = convert(tmp_path / "s", src, "--strict")
    line = assert_one_error(res, "parts_pkg", "--package parts_pkg=DIR", "--package-path")
    assert "with the folder that contains it" in line
    # followed as printed: the package's folder, or the folder that contains it
    for args in (("--package", f"parts_pkg={parts}"), ("--package-path", str(parts.parent))):
        res, out = convert(tmp_path / args[0].strip("-"), src, "--strict", *args)
        assert res.returncode == 0, res.stderr
        assert collision_geoms(out, "arm") == 1


def test_package_named_like_a_sub_folder_of_the_own_package(tmp_path):
    """``package://visual/link_1.dae`` where the file is ``meshes/<model>/visual/link_1.dae``
    of the URDF's own package (an export that cut the real package prefix off)."""
    pkg = tmp_path / "abb_support"
    (pkg / "package.xml").parent.mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>abb_support</name></package>")
    target = pkg / "meshes" / "irb_99" / "visual" / "link_1.dae"
    target.parent.mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.2, 0.3)).export(target)
    src = write_urdf(
        pkg / "urdf" / "irb_99.urdf",
        link("base", box("collision")),
        link("link_1", mesh("visual", "package://visual/link_1.dae"), box("collision")),
        joint("base", "link_1"),
    )
    res, out = convert(tmp_path, src)
    warnings = ok(res)
    assert any("package 'visual' not found" in w and str(target.parent) in w for w in warnings)
    m = mujoco.MjModel.from_xml_path(str(out))
    (mesh_id,) = range(m.nmesh)
    extent = np.ptp(m.mesh_vert[m.mesh_vertadr[mesh_id] :][: m.mesh_vertnum[mesh_id]], axis=0)
    assert np.allclose(sorted(extent), [0.1, 0.2, 0.3], atol=1e-6)


def test_ambiguous_mesh_is_a_warning_and_the_printed_hint_works(tmp_path):
    robot = tmp_path / "robot"
    a = cube(robot / "meshes" / "left" / "link.stl")
    cube(robot / "meshes" / "right" / "link.stl", 0.2)
    body = [link("base", box("collision")), None, joint("base", "arm")]
    body[1] = link("arm", mesh("collision", "meshes/coarse/link.stl"))
    src = write_urdf(robot / "robot.urdf", *body)  # type: ignore[arg-type]
    res, out = convert(tmp_path, src)
    assert any("several files of that name" in w and "dropped" in w for w in ok(res))
    assert collision_geoms(out, "arm") == 0
    res, _ = convert(tmp_path / "s", src, "--strict")
    assert_one_error(res, "several files of that name", "write the path of the one meant")
    # followed: the URDF names the one meant
    body[1] = link("arm", mesh("collision", str(a.relative_to(robot))))
    write_urdf(src, *body)  # type: ignore[arg-type]
    res, out = convert(tmp_path / "fixed", src, "--strict")
    assert res.returncode == 0, res.stderr
    assert collision_geoms(out, "arm") == 1


def test_a_guess_refused_by_strict_works_when_its_hint_is_followed(tmp_path):
    """``--strict allows no such guess: pass --package or --package-path``."""
    robot = tmp_path / "robot"
    cube(robot / "meshes" / "arm.stl")
    src = write_urdf(
        robot / "urdf" / "robot.urdf",
        link("base", box("collision")),
        link("arm", mesh("collision", "package://meshes/arm.stl")),
        joint("base", "arm"),
    )
    res, _ = convert(tmp_path, src, "--strict")
    assert_one_error(res, "--strict allows no such guess", "pass --package or --package-path")
    res, out = convert(tmp_path / "f", src, "--strict", "--package", f"meshes={robot / 'meshes'}")
    assert res.returncode == 0, res.stderr
    assert collision_geoms(out, "arm") == 1


def test_a_mesh_that_is_a_fifo_stays_an_error(tmp_path):
    """Missing, ambiguous or undecodable meshes are dropped; one that is no regular
    file is refused, as before (the security rule of urdf2mjcf/untrusted.py)."""
    robot = tmp_path / "robot"
    robot.mkdir()
    os.mkfifo(robot / "pipe.stl")
    src = write_urdf(
        robot / "robot.urdf",
        link("base", box("collision")),
        link("arm", mesh("collision", "pipe.stl")),
        joint("base", "arm"),
    )
    res, _ = convert(tmp_path, src)
    assert_one_error(res, "link 'arm' collision mesh 'pipe.stl'")


# -- package://NAME where NAME is a file -------------------------------------------


def test_package_uri_naming_a_file_beside_the_description(tmp_path):
    robot = tmp_path / "robot"
    cube(robot / "wheel.obj")
    src = write_urdf(
        robot / "robot.urdf",
        link("base", box("collision")),
        link(
            "wheel", mesh("visual", "package://wheel.obj"), mesh("collision", "package://wheel.obj")
        ),
        joint("base", "wheel", "continuous"),
    )
    res, out = convert(tmp_path, src)
    assert any("'package://wheel.obj' names a file" in w for w in ok(res))
    assert collision_geoms(out, "wheel") == 1 and len(geoms(out, "wheel")) == 2


def test_package_uri_naming_a_file_elsewhere_works_when_the_hint_is_followed(tmp_path):
    parts = tmp_path / "parts"
    cube(parts / "wheel.obj")
    src = write_urdf(
        tmp_path / "robot" / "robot.urdf",
        link("base", box("collision")),
        link("wheel", mesh("collision", "package://wheel.obj")),
        joint("base", "wheel", "continuous"),
    )
    res, _ = convert(tmp_path, src, "--strict")
    line = assert_one_error(res, "package://wheel.obj", "--package wheel.obj=DIR")
    assert "Is a directory" not in line
    res, out = convert(tmp_path / "f", src, "--strict", "--package", f"wheel.obj={parts}")
    assert res.returncode == 0, res.stderr
    assert collision_geoms(out, "wheel") == 1


# -- leftover xacro calls in a plain .urdf -----------------------------------------


def test_leftover_xacro_macro_calls_in_a_plain_urdf_are_ignored(tmp_path):
    ns = ' xmlns:xacro="http://www.ros.org/wiki/xacro"'
    src = write_urdf(
        tmp_path / "robot" / "robot.urdf",
        '<xacro:grey/><xacro:grey/><xacro:insert_gazebo_plugins prefix="x"/>',
        link("base", box("collision")),
        link("arm", box("collision")),
        joint("base", "arm"),
        extra_ns=ns,
    )
    res, out = convert(tmp_path, src)
    warnings = ok(res)
    assert any("xacro:grey" in w and "2 call(s) ignored" in w for w in warnings), warnings
    assert any("xacro:insert_gazebo_plugins" in w for w in warnings), warnings
    assert collision_geoms(out, "arm") == 1
    res, _ = convert(tmp_path / "s", src, "--strict")
    assert_one_error(res, "xacro:grey", "--strict")


def test_an_undefined_macro_in_a_xacro_file_stays_an_error(tmp_path):
    ns = ' xmlns:xacro="http://www.ros.org/wiki/xacro"'
    src = write_urdf(tmp_path / "robot.urdf.xacro", "<xacro:grey/>", link("base"), extra_ns=ns)
    res, _ = convert(tmp_path, src)
    assert_one_error(res, "unknown macro name: xacro:grey")


# -- the world frame ---------------------------------------------------------------


@pytest.mark.parametrize("kind", ["fixed", "revolute"])
def test_parent_world_that_is_not_defined_is_the_world_body(tmp_path, kind):
    src = write_urdf(
        tmp_path / "robot.urdf",
        link("base", box("collision")),
        link("arm", box("collision")),
        joint("world", "base", kind, xyz="0.5 0.25 1"),
        joint("base", "arm"),
    )
    res, out = convert(tmp_path, src)
    warnings = ok(res)
    assert any("parent link 'world' is not defined" in w and "link 'base'" in w for w in warnings)
    m = mujoco.MjModel.from_xml_path(str(out))
    base = m.body("base")
    assert base.parentid[0] == 0 and np.allclose(base.pos, (0.5, 0.25, 1.0))
    assert m.njnt == (1 if kind == "fixed" else 2)  # welded: no free joint is added
    if kind == "revolute":
        assert m.joint("world_base").bodyid[0] == base.id
    res, _ = convert(tmp_path / "s", src, "--strict")
    assert_one_error(res, "parent link 'world' is not defined")


def test_any_other_undefined_parent_is_an_error_naming_it(tmp_path):
    src = write_urdf(
        tmp_path / "robot.urdf",
        link("gripper", box("collision")),
        joint("ur5_tool0", "gripper", "fixed"),
    )
    res, _ = convert(tmp_path, src)
    assert_one_error(res, "joint 'ur5_tool0_gripper'", "parent link 'ur5_tool0' does not exist")


# -- meshes with nothing to collide with, inertials without mass ------------------------


def test_collision_mesh_without_usable_triangles_is_dropped(tmp_path):
    robot = tmp_path / "robot"
    robot.mkdir()
    flat = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [2, 0, 0]], faces=[[0, 1, 2]])
    (robot / "empty.stl").write_bytes(flat.export(file_type="stl"))
    src = write_urdf(
        robot / "robot.urdf",
        link("base", box("collision")),
        link("arm", mesh("collision", "empty.stl"), box("collision")),
        joint("base", "arm"),
    )
    res, out = convert(tmp_path, src)
    warnings = ok(res)
    assert any("empty.stl" in w and "no usable triangles" in w and "dropped" in w for w in warnings)
    assert collision_geoms(out, "arm") == 1  # the box stays


def test_inertial_without_mass_is_read_as_mass_zero(tmp_path):
    no_mass = (
        '<inertial><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
    )
    src = write_urdf(
        tmp_path / "robot.urdf",
        link("base", box("collision")),
        link("arm", inertial=no_mass),
        link("tip", box("collision")),
        joint("base", "arm"),
        joint("arm", "tip"),
    )
    res, out = convert(tmp_path, src)
    assert any("link 'arm' <inertial>" in w and "no <mass>" in w for w in ok(res))
    m = mujoco.MjModel.from_xml_path(str(out))
    import pinocchio as pin

    pm = pin.buildModelFromUrdf(str(src))  # urdfdom: the inertial is skipped, mass 0
    assert pm.inertias[pm.getJointId("base_arm")].mass == 0.0
    # a zero-mass link, as the inertia pass treats one: at most its minimum mass
    assert m.body_mass[m.body("arm").id] <= 1e-3
    res, _ = convert(tmp_path / "s", src, "--strict")
    assert_one_error(res, "no <mass>")


# -- glTF -----------------------------------------------------------------------------


def _textured_box() -> trimesh.Trimesh:
    from PIL import Image

    box_mesh = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    pixels = np.zeros((8, 8, 3), dtype=np.uint8)
    pixels[:, :4] = (200, 30, 40)
    pixels[:, 4:] = (20, 160, 60)
    material = trimesh.visual.material.PBRMaterial(
        name="paint",
        baseColorFactor=(255, 255, 255, 255),
        baseColorTexture=Image.fromarray(pixels),
    )
    uv = np.random.default_rng(0).uniform(0, 1, (len(box_mesh.vertices), 2))
    box_mesh.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    return box_mesh


def test_glb_mesh_converts_with_its_material_and_texture(tmp_path):
    robot = tmp_path / "robot"
    robot.mkdir()
    (robot / "arm.glb").write_bytes(_textured_box().export(file_type="glb"))
    plain = trimesh.creation.box(extents=(0.2, 0.1, 0.1))
    plain.visual.face_colors = (10, 20, 250, 255)
    # glTF as JSON with its buffer in a side file
    for name, data in trimesh.Scene(plain).export(file_type="gltf").items():
        (robot / ("plain.gltf" if name == "model.gltf" else name)).write_bytes(data)
    src = write_urdf(
        robot / "robot.urdf",
        link("base", mesh("visual", "plain.gltf"), box("collision")),
        link("arm", mesh("visual", "arm.glb"), mesh("collision", "arm.glb")),
        joint("base", "arm"),
    )
    res, out = convert(tmp_path, src)
    ok(res)
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.ntex == 1 and collision_geoms(out, "arm") == 1
    (visual,) = [g for g in geoms(out, "arm") if g not in geoms(out, "arm", 3)]
    mat = m.geom_matid[visual]
    assert mat >= 0 and m.mat_texid[mat][mujoco.mjtTextureRole.mjTEXROLE_RGB] == 0
    png = list((out.parent / "assets").glob("*.png"))
    assert len(png) == 1
    from PIL import Image

    with Image.open(png[0]) as img:
        colours = {tuple(c) for c in np.asarray(img.convert("RGB")).reshape(-1, 3)}
    assert colours == {(200, 30, 40), (20, 160, 60)}
    (base_visual,) = [g for g in geoms(out, "base") if g not in geoms(out, "base", 3)]
    rgba = m.mat_rgba[m.geom_matid[base_visual]]
    assert np.allclose(rgba, (10 / 255, 20 / 255, 250 / 255, 1.0), atol=2e-3)
