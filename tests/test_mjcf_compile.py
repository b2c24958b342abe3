"""The compile helper: a collision-only compile (visual geoms and their meshes left
out) has the dynamics and the contacts of the whole document, and is refused where
it could differ. The reference is MuJoCo compiling the document as written."""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

import urdf2mjcf
from urdf2mjcf.mjcf import compile as mjcf_compile

MESHES = Path(__file__).parent / "data" / "meshes"

URDF = """<robot name="arm">
  <link name="base">
    <visual><geometry><mesh filename="meshes/colored_box.dae"/></geometry></visual>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.2 0.2 0.1"/></geometry></collision>
    <inertial><mass value="2"/><inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
  <link name="upper">
    <visual><geometry><mesh filename="meshes/ball.stl"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/ball.stl"/></geometry></collision>
    <inertial><origin xyz="0 0 0.1"/><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><origin xyz="0 0 0.3" rpy="0.3 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="10" velocity="1"/>
  </joint>
</robot>
"""


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> tuple[bytes, dict[str, bytes]]:
    """The robot MJCF as converted, and every file beside it by relative name."""
    tmp = tmp_path_factory.mktemp("arm")
    (tmp / "meshes").mkdir()
    shutil.copy(MESHES / "colored_box.dae", tmp / "meshes")
    trimesh.creation.icosphere(subdivisions=3, radius=0.05).export(tmp / "meshes" / "ball.stl")
    (tmp / "arm.urdf").write_text(URDF)
    out = tmp / "out"
    urdf2mjcf.convert(tmp / "arm.urdf", out / "robot.xml", use_environment=False, scene=False)
    files = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    return files["robot.xml"], files


def at_home(m):
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    return d


def colliding(m, d) -> list[tuple]:
    """(type, world position, world frame, size) of each geom that collides, in order."""
    out = []
    for g in range(m.ngeom):
        if m.geom_contype[g] or m.geom_conaffinity[g]:
            out.append((int(m.geom_type[g]), *d.geom_xpos[g], *d.geom_xmat[g], *m.geom_size[g]))
    return out


def test_collision_only_compile_has_the_dynamics_and_contacts_of_the_whole(written):
    xml, files = written
    whole = mujoco.MjModel.from_xml_string(xml.decode(), files)
    light, light_data = mjcf_compile.compile_home(xml, files, collision_only=True)
    assert light.nmesh < whole.nmesh  # the visual meshes were left out
    assert light.nmeshface < whole.nmeshface
    d, dl = at_home(whole), light_data
    mujoco.mj_forward(light, dl)
    np.testing.assert_array_equal(light.body_mass, whole.body_mass)
    np.testing.assert_array_equal(light.body_inertia, whole.body_inertia)
    full, full_light = np.zeros((whole.nv, whole.nv)), np.zeros((light.nv, light.nv))
    mujoco.mj_fullM(whole, d, full)
    mujoco.mj_fullM(light, dl, full_light)
    np.testing.assert_array_equal(full, full_light)
    np.testing.assert_array_equal(d.xipos, dl.xipos)
    assert colliding(whole, d) == colliding(light, dl) and colliding(whole, d)
    # the collision meshes themselves, vertex for vertex
    mesh_of = {light.mesh(i).name: i for i in range(light.nmesh)}
    for i in range(whole.nmesh):
        name = whole.mesh(i).name
        if name in mesh_of:
            j = mesh_of[name]
            a = whole.mesh_vert[
                whole.mesh_vertadr[i] : whole.mesh_vertadr[i] + whole.mesh_vertnum[i]
            ]
            b = light.mesh_vert[
                light.mesh_vertadr[j] : light.mesh_vertadr[j] + light.mesh_vertnum[j]
            ]
            np.testing.assert_array_equal(a, b)


def test_visual_geoms_that_could_matter_are_kept(written):
    xml, _ = written
    assert mjcf_compile.without_visuals(xml) is not None
    # a visual class that collides: its geoms make contacts
    colliding_class = xml.replace(
        b'<geom contype="0" conaffinity="0" group="2" density="0"/>',
        b'<geom contype="1" conaffinity="0" group="2" density="0"/>',
    )
    assert colliding_class != xml
    assert mjcf_compile.without_visuals(colliding_class) is None
    # masses from geoms: visual geoms would weigh
    from_geoms = xml.replace(b'inertiafromgeom="false"', b'inertiafromgeom="true"')
    assert from_geoms != xml
    assert mjcf_compile.without_visuals(from_geoms) is None


def test_a_document_that_needs_what_was_left_out_compiles_whole(written):
    xml, files = written
    # a contact pair names a visual geom: left out, the pair would not compile
    light = mjcf_compile.without_visuals(xml)
    assert light is not None
    name = b"visual_probe"
    tagged = xml.replace(b'<geom class="visual"', b'<geom name="visual_probe" class="visual"', 1)
    tagged = tagged.replace(
        b"</worldbody>",
        b'</worldbody>\n  <contact><pair geom1="visual_probe" geom2="base_collision"/></contact>',
        1,
    )
    assert name in tagged
    m, _ = mjcf_compile.compile_home(tagged, files, collision_only=True)
    whole = mujoco.MjModel.from_xml_string(tagged.decode(), files)
    assert m.nmesh == whole.nmesh and m.npair == 1


def test_a_collision_only_compile_is_given_only_the_files_it_names(written, monkeypatch):
    xml, files = written
    given: list[set[str]] = []
    compile_xml = mjcf_compile.compile_xml

    def spy(doc, assets, warnings=None):
        given.append(set(assets))
        return compile_xml(doc, assets, warnings)

    monkeypatch.setattr(mjcf_compile, "compile_xml", spy)
    light, _ = mjcf_compile.compile_home(xml, files, collision_only=True)
    assert len(given) == 1
    meshes = {light.mesh(i).name for i in range(light.nmesh)}
    assert meshes and all(any(m in name for name in given[0]) for m in meshes)
    left_out = set(files) - given[0]
    assert "robot.xml" in left_out and any("colored_box" in n for n in left_out), left_out


def test_the_scene_pass_reuses_the_actuator_pass_compile_of_the_same_shape(tmp_path, monkeypatch):
    """The actuators pass compiles the robot (to size its gains); the scene pass needs only
    where the same bodies and geoms are at home: the conversion hands it that model
    (mjcf_compile.HomeCompiles), and the floor it places is where a fresh compile puts it."""
    calls = []
    real = mjcf_compile.compile_xml

    def counting(xml, files, warnings=None):
        text = xml if isinstance(xml, bytes) else xml.encode()
        if b"<include" not in text:  # validation compiles scene.xml, which includes the robot
            calls.append(len(text))
        return real(xml, files, warnings)

    monkeypatch.setattr(mjcf_compile, "compile_xml", counting)
    source = Path(__file__).parent / "data" / "sim_robot" / "urdf" / "sim_arm.urdf.xacro"
    report = urdf2mjcf.convert(source, tmp_path / "robot.xml", use_environment=False, certify=False)
    assert report.compiled is not None
    assert len(calls) == 1, "the scene pass compiled the robot again"
    monkeypatch.setattr(mjcf_compile, "compile_xml", real)
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "robot.xml"))
    d = at_home(m)
    lowest = min(
        d.geom_xpos[g][2] - m.geom_rbound[g]
        for g in range(m.ngeom)
        if m.geom_contype[g] or m.geom_conaffinity[g]
    )
    scene = mujoco.MjModel.from_xml_path(str(tmp_path / "scene.xml"))
    floor = scene.geom("floor")
    # the floor is at or below the robot's lowest point (never above the origin), and no
    # lower than that point's bounding sphere allows
    assert lowest - 1e-9 <= floor.pos[2] <= 0.0
