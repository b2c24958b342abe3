"""The <mujoco> extension pass: merge rules, overrides, errors, keyframes.

Every merged model is compiled by MuJoCo 4.0, the oracle for what the
merged MJCF means.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from lxml import etree

from urdf2mjcf.errors import MeshError, PackageNotFoundError, URDFError, ValidationError
from urdf2mjcf.ir import Extension
from urdf2mjcf.mjcf.document import SECTIONS, Document
from urdf2mjcf.passes import (
    collision,
    emit,
    extension,
    inertia,
    meshes,
    parse,
    validate,
    xacro,
)
from urdf2mjcf.passes.extension import ExtensionConfig

DATA = Path(__file__).parents[1] / "data"
BOX_STL = DATA / "meshes" / "box.stl"

LINK = (
    '<link name="{n}"><inertial><origin xyz="0 0 0.1"/><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.002" ixy="0" ixz="0" iyz="0"/></inertial>'
    '<collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.03" length="0.2"/></geometry></collision></link>'
)
JOINT = (
    '<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
    '<origin xyz="0 0 0.2"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="5" velocity="1"/>'
    "{extra}</joint>"
)
ARM = (
    LINK.format(n="base")
    + LINK.format(n="upper_arm")
    + LINK.format(n="forearm")
    + JOINT.format(n="shoulder", p="base", c="upper_arm", extra='<dynamics friction="0.3"/>')
    + JOINT.format(n="elbow", p="upper_arm", c="forearm", extra="")
)


def write(tmp_path: Path, mujoco_xml: str = "", *, name: str = "arm.urdf", head: str = "") -> Path:
    path = tmp_path / name
    path.write_text(
        f'<?xml version="1.0"?>\n<robot name="arm"{head}>\n{ARM}\n{mujoco_xml}\n</robot>\n'
    )
    return path


def emitted(path: Path, emit_cfg: emit.EmitConfig | None = None, **xacro_cfg):
    """(model, emit result, resolver) from the real passes."""
    doc = xacro.run(path, xacro.XacroConfig(use_environment=False, **xacro_cfg))
    model = parse.run(doc)
    model = meshes.run(model, meshes.MeshConfig())
    model = collision.run(model, collision.CollisionConfig())
    model = inertia.run(model, inertia.InertiaConfig())
    return model, emit.run(model, emit_cfg or emit.EmitConfig()), doc.resolver


def convert(tmp_path: Path, mujoco_xml: str, *, check: bool = True, **xacro_cfg):
    model, before, resolver = emitted(write(tmp_path, mujoco_xml), **xacro_cfg)
    cfg = ExtensionConfig(resolver=resolver, check=check)
    return before, extension.run(before, model, cfg)


def compiled(result: Document) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(result.xml.decode(), dict(result.files))


def root(result: Document) -> etree._Element:
    return etree.fromstring(result.xml)


def raises(tmp_path: Path, mujoco_xml: str, kind=URDFError, **kwargs):
    with pytest.raises(kind) as info:
        convert(tmp_path, mujoco_xml, **kwargs)
    assert info.value.file == str(tmp_path / "arm.urdf")
    return info.value


# -- identity -----------------------------------------------------------------


def test_robot_without_mujoco_comes_out_byte_identical(tmp_path):
    before, after = convert(tmp_path, "")
    assert after.xml == before.xml
    assert after.files == before.files
    assert after.notes == before.notes


@pytest.mark.parametrize("case", ["joints", "mimic", "dae_material"])
def test_empty_mujoco_element_reserialises_emit_output_byte_identical(case):
    """Parse and re-serialise is the identity on emit's output (assets, textures, mimics)."""
    model, before, resolver = emitted(DATA / "golden" / f"{case}.urdf")
    robot = dataclasses.replace(model.robot, extensions=(Extension("mujoco", "<mujoco/>"),))
    after = extension.run(
        before, dataclasses.replace(model, robot=robot), ExtensionConfig(resolver=resolver)
    )
    assert after.xml == before.xml
    assert after.files == before.files
    assert after.notes[-1].message == "applied nothing (empty)"


def test_disabled_pass_ignores_mujoco_elements(tmp_path):
    model, before, resolver = emitted(
        write(tmp_path, '<mujoco><option timestep="0.001"/></mujoco>')
    )
    after = extension.run(before, model, ExtensionConfig(enabled=False, resolver=resolver))
    assert after is before


# -- merged sections ----------------------------------------------------------


def test_option_attributes_merge_into_generated_option(tmp_path):
    _, after = convert(
        tmp_path, '<mujoco><option timestep="0.001"><flag energy="enable"/></option></mujoco>'
    )
    m = compiled(after)
    assert m.opt.timestep == 0.001
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # ours kept
    assert m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_ENERGY
    assert len(root(after).findall("option")) == 1


def test_compiler_meshdir_of_mujocos_urdf_idiom_is_ignored_with_a_note(tmp_path):
    _, after = convert(
        tmp_path,
        '<mujoco><compiler meshdir="../meshes" balanceinertia="true" discardvisual="false"/></mujoco>',
    )
    compiler = root(after).find("compiler")
    assert compiler.get("meshdir") == "assets"
    assert compiler.get("balanceinertia") == "true"
    assert any(n.element == "mujoco compiler" and "meshdir" in n.message for n in after.notes)
    compiled(after)


@pytest.mark.parametrize(
    "attrs, needle",
    [
        ('angle="degree"', "radians"),
        ('autolimits="false"', "limited"),
        ('inertiafromgeom="true"', "<inertial>"),
        ('angle=""', "radians"),
    ],
)
def test_compiler_attributes_the_model_depends_on_cannot_change(tmp_path, attrs, needle):
    error = raises(tmp_path, f"<mujoco><compiler {attrs}/></mujoco>")
    assert error.element == "mujoco compiler"
    assert "is not supported" in error.detail and needle in error.detail


def test_compiler_attributes_equal_to_ours_are_accepted(tmp_path):
    _, after = convert(tmp_path, '<mujoco><compiler angle="radian" autolimits="true"/></mujoco>')
    compiled(after)


def test_default_classes_merge_into_existing_and_new_ones_are_added(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco><default>
             <joint damping="0.25"/>
             <default class="collision"><geom friction="0.7 0.005 0.0001"/></default>
             <default class="rubber"><geom friction="1.5 0.01 0.001"/></default>
           </default>
           <override><geom name="forearm_collision" class="rubber"/></override></mujoco>""",
    )
    top = root(after).find("default")
    assert [c.tag for c in top][0] == "joint"  # element settings before nested classes
    assert [d.get("class") for d in top.iter("default")][1:] == ["visual", "collision", "rubber"]
    assert top.find("default[@class='collision']/geom").attrib == {
        "group": "3",
        "friction": "0.7 0.005 0.0001",
    }
    m = compiled(after)
    geoms = {m.geom(i).name: i for i in range(m.ngeom)}
    np.testing.assert_allclose(m.geom_friction[geoms["base_collision"]], [0.7, 0.005, 0.0001])
    np.testing.assert_allclose(m.geom_friction[geoms["forearm_collision"]], [1.5, 0.01, 0.001])
    np.testing.assert_allclose(m.dof_damping, [0.25, 0.25])


def test_nested_default_class_merges_into_the_existing_class_wherever_it_is(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco><default><default class="collision">
             <default class="soft"><geom solref="0.02 1"/></default>
           </default></default></mujoco>""",
    )
    collision_class = root(after).find("default/default[@class='collision']")
    assert collision_class.find("default").get("class") == "soft"  # nested: inherits group 3
    compiled(after)


def test_default_rejects_a_class_on_the_top_level_default_and_a_nested_one_without_class(tmp_path):
    error = raises(
        tmp_path, '<mujoco><default class="rubber"><geom friction="1 0 0"/></default></mujoco>'
    )
    assert error.element == "mujoco default class 'rubber'"
    assert '<default><default class="rubber">' in error.detail
    error = raises(tmp_path, "<mujoco><default><default><geom/></default></default></mujoco>")
    assert error.element == "mujoco default" and "needs class" in error.detail


# -- assets ------------------------------------------------------------------


def test_asset_mesh_is_copied_under_a_content_hash_name_and_keeps_its_name(tmp_path):
    (tmp_path / "meshes").mkdir()
    shutil.copy(BOX_STL, tmp_path / "meshes" / "box.stl")
    _, after = convert(
        tmp_path,
        """<mujoco><asset><mesh file="meshes/box.stl" scale="0.1 0.1 0.1"/></asset>
           <geom parent="forearm" name="box_geom" type="mesh" mesh="box"/></mujoco>""",
    )
    mesh = root(after).find("asset/mesh[@name='box']")
    assert mesh is not None and list(mesh.attrib)[0] == "name"
    assert mesh.get("file").startswith("box_") and mesh.get("file").endswith(".stl")
    assert after.files[f"assets/{mesh.get('file')}"] == BOX_STL.read_bytes()
    m = compiled(after)
    assert m.nmesh == 1 and m.geom(m.ngeom - 1).name == "box_geom"


def test_asset_files_resolve_through_packages(tmp_path):
    pkg = tmp_path / "pkgs" / "my_description"
    (pkg / "meshes").mkdir(parents=True)
    shutil.copy(BOX_STL, pkg / "meshes" / "box.stl")
    _, after = convert(
        tmp_path,
        '<mujoco><asset><mesh name="part" file="package://my_description/meshes/box.stl"/></asset></mujoco>',
        packages={"my_description": pkg},
    )
    assert BOX_STL.read_bytes() in after.files.values()
    compiled(after)


def test_texture_goes_to_the_texture_folder(tmp_path):
    _, after = convert(
        tmp_path,
        f"""<mujoco><asset><texture name="grid" type="2d" file="{DATA / "meshes" / "quadrants.png"}"/>
            <material name="grid" texture="grid"/></asset></mujoco>""",
    )
    file = root(after).find("asset/texture").get("file")
    assert f"assets/{file}" in after.files
    assert compiled(after).ntex == 1


def test_missing_asset_file_is_a_mesh_error_naming_the_asset(tmp_path):
    error = raises(
        tmp_path, '<mujoco><asset><mesh file="meshes/nope.stl"/></asset></mujoco>', MeshError
    )
    assert error.element == "mujoco asset mesh 'nope'"
    assert "file not found" in error.detail and "nope.stl" in error.detail


def test_git_lfs_pointer_asset_is_an_error(tmp_path):
    (tmp_path / "lfs.stl").write_bytes(
        b"version https://git-lfs.github.com/spec/v1\noid sha256:00\n"
    )
    error = raises(
        tmp_path, '<mujoco><asset><mesh name="m" file="lfs.stl"/></asset></mujoco>', MeshError
    )
    assert "git lfs pull" in error.detail


def test_unknown_package_in_an_asset_is_a_package_error(tmp_path):
    error = raises(
        tmp_path,
        '<mujoco><asset><mesh name="m" file="package://no_such_pkg/m.stl"/></asset></mujoco>',
        PackageNotFoundError,
    )
    assert error.element == "mujoco asset mesh 'm'"


# -- bodies ------------------------------------------------------------------


def test_extra_body_goes_under_the_named_link_and_elements_before_child_bodies(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco>
             <body parent="forearm" name="tool" pos="0 0 0.2">
               <inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>
               <geom name="tool_geom" type="box" size="0.02 0.02 0.02"/>
             </body>
             <site parent="upper_arm" name="marker"/>
             <camera parent="world" name="overview" pos="1 0 1" xyaxes="0 1 0 -1 0 1"/>
           </mujoco>""",
    )
    m = compiled(after)
    tool = m.body("tool")
    assert m.body(tool.parentid[0]).name == "forearm"
    np.testing.assert_allclose(tool.pos, [0, 0, 0.2])
    assert m.geom("tool_geom").bodyid[0] == tool.id
    assert m.site("marker").bodyid[0] == m.body("upper_arm").id
    assert m.cam("overview").bodyid[0] == 0
    upper = root(after).find(".//body[@name='upper_arm']")
    assert [c.tag for c in upper][-2:] == ["site", "body"]  # the site before the child body
    assert "parent" not in etree.tostring(upper).decode()


def test_worldbody_content_is_added_to_the_world(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco><worldbody><body name="ball" pos="1 0 0.5"><freejoint name="ball_free"/>
           <inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>
           <geom type="sphere" size="0.05"/></body></worldbody></mujoco>""",
    )
    m = compiled(after)
    assert m.body(m.body("ball").parentid[0]).name == "world"


def test_body_level_element_without_parent_is_an_error(tmp_path):
    error = raises(tmp_path, '<mujoco><geom name="g" size="0.1"/></mujoco>')
    assert error.element == "mujoco geom 'g'"
    assert 'needs parent="BODY"' in error.detail and "<worldbody>" in error.detail


def test_a_parent_that_does_not_exist_drops_the_element_with_a_warning_listing_the_bodies(tmp_path):
    _, after = convert(tmp_path, '<mujoco><body parent="hand" name="finger"/></mujoco>')
    assert mujoco.mj_name2id(compiled(after), mujoco.mjtObj.mjOBJ_BODY, "finger") == -1
    warned = _warned(after, "'hand'")
    assert warned == [
        "mujoco body 'finger': parent body 'hand' does not exist; this element of the "
        "description's <mujoco> is dropped (bodies: world, base, upper_arm, forearm)"
    ]


def test_a_parent_that_was_fused_puts_the_element_at_the_fused_links_place(tmp_path):
    tool = '<joint name="tool_joint" type="fixed"><parent link="forearm"/><child link="tool"/><origin xyz="0.01 0 0.2" rpy="0 0 0.5"/></joint><link name="tool"/>'
    path = write(tmp_path, tool + '<mujoco><site parent="tool" name="tcp" pos="0.1 0 0"/></mujoco>')
    model, before, resolver = emitted(path, emit.EmitConfig(fuse_fixed=True))
    after = extension.run(before, model, ExtensionConfig(resolver=resolver))
    m = compiled(after)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    # where the tcp would be on an unfused tool link: the tool's site, then 0.1 m along its x
    tool_site = m.site("tool")
    expected = d.site_xpos[tool_site.id] + d.site_xmat[tool_site.id].reshape(3, 3) @ [0.1, 0, 0]
    assert m.site_bodyid[m.site("tcp").id] == m.body("forearm").id
    np.testing.assert_allclose(d.site_xpos[m.site("tcp").id], expected, atol=1e-12)
    assert any("fused into body 'forearm'" in n.message for n in after.notes)


def test_an_assembled_world_keeps_a_missing_parent_an_error(tmp_path):
    model, before, resolver = emitted(write(tmp_path, '<mujoco><body parent="hand" name="f"/></mujoco>'))
    with pytest.raises(URDFError, match="parent body 'hand' does not exist; bodies: world"):
        extension.run(before, model, ExtensionConfig(resolver=resolver, assembly=True))


# -- keyframes ----------------------------------------------------------------


def test_key_named_like_an_existing_one_replaces_it_in_place(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco><keyframe><key name="ready" qpos="0.5 0.5"/><key name="home" qpos="0.1 -0.2"/>
           </keyframe></mujoco>""",
    )
    m = compiled(after)
    assert [m.key(i).name for i in range(m.nkey)] == ["home", "ready"]  # home stays key 0
    np.testing.assert_allclose(m.key("home").qpos, [0.1, -0.2])
    assert after.qpos_home == (0.1, -0.2)


def test_added_joints_pad_the_generated_home_keyframe(tmp_path):
    before, after = convert(
        tmp_path,
        """<mujoco>
             <body parent="upper_arm" name="slider" pos="0 0 0.1">
               <joint name="slide" type="slide" axis="1 0 0" ref="0.02"/>
               <inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>
             </body>
             <worldbody><body name="ball" pos="1 2 3"><freejoint/>
               <inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/></body></worldbody>
             <override><key name="home" time="0"/></override>
           </mujoco>""",
        check=False,
    )
    assert before.qpos_home == (0.0, 0.0)
    m = compiled(after)
    # shoulder, elbow (forearm comes before the slider added after it), slide at its ref, ball
    np.testing.assert_allclose(m.key("home").qpos, [0, 0, 0.02, 1, 2, 3, 1, 0, 0, 0])
    assert after.qpos_home == tuple(m.key("home").qpos)


def test_a_user_key_is_taken_verbatim(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco><worldbody><body name="ball"><freejoint/>
           <inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/></body></worldbody>
           <keyframe><key name="home" qpos="0.5 0.5"/></keyframe></mujoco>""",
    )
    assert root(after).find("keyframe/key").get("qpos") == "0.5 0.5"
    # MuJoCo fills a short key from qpos0
    np.testing.assert_allclose(compiled(after).key("home").qpos, [0.5, 0.5, 0, 0, 0, 1, 0, 0, 0])


# -- overrides ----------------------------------------------------------------


def test_override_sets_replaces_and_removes_attributes(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco><override>
             <joint name="elbow" armature="0.1" damping="2"/>
             <joint name="shoulder" frictionloss="" range="-0.5 0.5"/>
           </override></mujoco>""",
    )
    shoulder = root(after).find(".//joint[@name='shoulder']")
    assert "frictionloss" not in shoulder.attrib and shoulder.get("range") == "-0.5 0.5"
    m = compiled(after)
    np.testing.assert_allclose(m.dof_armature, [0, 0.1])
    np.testing.assert_allclose(m.dof_damping, [0, 2])
    np.testing.assert_allclose(m.dof_frictionloss, [0, 0])
    np.testing.assert_allclose(m.jnt_range[0], [-0.5, 0.5])


def test_override_sees_elements_added_before_it_but_not_after(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco><actuator><motor name="m" joint="elbow"/></actuator>
           <override><actuator name="m" gear="3"/></override></mujoco>""",
    )
    assert compiled(after).actuator_gear[0][0] == 3
    error = raises(
        tmp_path,
        """<mujoco><override><actuator name="m" gear="3"/></override>
           <actuator><motor name="m" joint="elbow"/></actuator></mujoco>""",
    )
    assert error.element == "mujoco override actuator 'm'"
    assert error.detail == "no actuator 'm' in the model; the model has no named actuators"


def test_override_of_a_missing_element_lists_what_exists(tmp_path):
    error = raises(
        tmp_path, '<mujoco><override><joint name="wrist" damping="1"/></override></mujoco>'
    )
    assert error.element == "mujoco override joint 'wrist'"
    assert error.detail == "no joint 'wrist' in the model; joints: shoulder, elbow"
    error = raises(
        tmp_path, '<mujoco><override><body name="hand" gravcomp="1"/></override></mujoco>'
    )
    assert error.detail == "no body 'hand' in the model; bodies: base, upper_arm, forearm"


def test_override_without_name_is_an_error(tmp_path):
    error = raises(tmp_path, '<mujoco><override><joint damping="1"/></override></mujoco>')
    assert error.element == "mujoco override joint" and "needs name=" in error.detail


def test_override_of_an_unknown_element_lists_the_valid_ones(tmp_path):
    error = raises(
        tmp_path, '<mujoco><override><position name="elbow" kp="1"/></override></mujoco>'
    )
    assert error.element == "mujoco override position"
    assert "valid: body, joint, geom" in error.detail
    assert "<actuator name=...>" in error.detail


def test_override_with_child_elements_is_an_error(tmp_path):
    error = raises(
        tmp_path,
        '<mujoco><override><body name="forearm"><geom size="1"/></body></override></mujoco>',
    )
    assert error.element == "mujoco override body 'forearm'"
    assert "only sets attributes" in error.detail and "<geom>" in error.detail


# -- structure errors -----------------------------------------------------------


def test_unknown_element_in_mujoco_lists_the_valid_ones(tmp_path):
    error = raises(tmp_path, "<mujoco><include file='x.xml'/></mujoco>")
    assert error.element == "mujoco include"
    assert error.detail.startswith("unknown element <include>; valid: compiler, option, size,")
    assert error.detail.endswith("override")


def test_attributes_on_mujoco_are_an_error(tmp_path):
    error = raises(tmp_path, '<mujoco model="x"/>')
    assert error.element == "mujoco" and "takes no attributes" in error.detail


def test_missing_sections_are_created_in_menagerie_order(tmp_path):
    _, after = convert(
        tmp_path,
        """<mujoco>
             <sensor><jointpos name="q" joint="elbow"/></sensor>
             <tendon><fixed name="t"><joint joint="elbow" coef="1"/></fixed></tendon>
             <equality><joint joint1="elbow" joint2="shoulder"/></equality>
             <contact><exclude body1="base" body2="forearm"/></contact>
             <statistic meansize="0.1"/>
             <size memory="10M"/>
           </mujoco>""",
    )
    tags = [c.tag for c in root(after)]
    assert tags == sorted(tags, key=SECTIONS.index)
    assert {"size", "statistic", "contact", "equality", "tendon", "sensor"} <= set(tags)
    m = compiled(after)
    assert (m.nsensor, m.ntendon, m.neq, m.nexclude) == (1, 1, 1, 1)


def test_xacro_namespace_does_not_leak_into_the_model(tmp_path):
    path = write(
        tmp_path,
        '<xacro:property name="dt" value="0.002"/><mujoco><option timestep="${dt}"/></mujoco>',
        name="arm.urdf.xacro",
        head=' xmlns:xacro="http://www.ros.org/wiki/xacro"',
    )
    model, before, resolver = emitted(path)
    after = extension.run(before, model, ExtensionConfig(resolver=resolver))
    assert b"xmlns" not in after.xml
    assert compiled(after).opt.timestep == 0.002


# -- MuJoCo's verdict ---------------------------------------------------------


def test_error_in_a_generated_element_inside_an_overridden_body_is_left_to_validate(tmp_path):
    """Only content that came from <mujoco> is blamed; the rest is validate's to report."""
    model, before, resolver = emitted(
        write(tmp_path, '<mujoco><override><body name="forearm" gravcomp="1"/></override></mujoco>')
    )
    root = before.edit()
    next(g for g in root.iter("geom") if g.get("name") == "forearm_collision").set("bogus", "1")
    result = dataclasses.replace(before, root=root)
    after = extension.run(result, model, ExtensionConfig(resolver=resolver))
    with pytest.raises(ValueError, match="unrecognized attribute: 'bogus'"):
        compiled(after)


def test_misspelt_attribute_is_reported_against_the_override(tmp_path):
    error = raises(
        tmp_path, '<mujoco><override><joint name="elbow" armatur="0.1"/></override></mujoco>'
    )
    assert error.element == "mujoco override joint 'elbow'"
    assert error.detail == (
        "MuJoCo rejects <joint name='elbow'>: Schema violation: unrecognized attribute: 'armatur'"
    )


def _warned(result: Document, needle: str) -> list[str]:
    return [f"{n.element}: {n.message}" for n in result.notes if n.kind == "warning" and needle in n.message]


def test_content_naming_a_body_the_model_lacks_is_dropped_with_a_warning(tmp_path):
    # a typo in one exclude: urdfdom reads the robot, and so do we (without that exclude)
    xml = (
        '<mujoco><contact><exclude body1="base" body2="hand"/>'
        '<exclude body1="base" body2="forearm"/></contact>'
        '<sensor><framepos objtype="body" objname="gripper"/><framepos objtype="body" objname="forearm"/></sensor>'
        "</mujoco>"
    )
    _, after = convert(tmp_path, xml)
    m = compiled(after)
    forearm = m.body("forearm").id
    assert m.nexclude == 1 and {m.exclude_signature[0] >> 16, m.exclude_signature[0] & 0xFFFF} == {0 + m.body("base").id, forearm}
    assert m.nsensor == 1 and m.sensor_objid[0] == forearm
    hand, gripper = _warned(after, "'hand'"), _warned(after, "'gripper'")
    assert len(hand) == 1 and hand[0].startswith("mujoco contact exclude: body2='hand' names no body")
    assert "dropped" in hand[0] and "forearm" in hand[0]  # it lists the bodies there are
    assert len(gripper) == 1 and gripper[0].startswith("mujoco sensor framepos: objname='gripper'")


def test_content_naming_a_fused_link_names_the_body_it_was_fused_into(tmp_path):
    tool = (
        '<link name="tool0"/><joint name="flange" type="fixed"><parent link="forearm"/>'
        '<child link="tool0"/><origin xyz="0 0 0.2"/></joint>'
    )
    xml = tool + '<mujoco><contact><exclude body1="base" body2="tool0"/></contact></mujoco>'
    model, before, resolver = emitted(write(tmp_path, xml), emit.EmitConfig(fuse_fixed=True))
    after = extension.run(before, model, ExtensionConfig(resolver=resolver))
    m = compiled(after)
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "tool0") == -1  # fused
    assert m.nexclude == 1
    assert {m.exclude_signature[0] >> 16, m.exclude_signature[0] & 0xFFFF} == {m.body("base").id, m.body("forearm").id}
    assert any("fused into body 'forearm'" in n.message for n in after.notes)


def test_bad_reference_in_raw_content_is_reported_against_that_content(tmp_path):
    error = raises(
        tmp_path,
        """<mujoco><body parent="forearm" name="tool"><joint/><geom size="0.01"/></body></mujoco>""",
    )
    assert error.element == "mujoco body 'tool'"
    assert "mass and inertia of moving bodies" in error.detail
    assert error.detail.endswith("give the body an <inertial>)")


def test_adding_an_element_that_exists_points_to_override(tmp_path):
    error = raises(
        tmp_path, '<mujoco><site parent="forearm" name="x"/><site parent="base" name="x"/></mujoco>'
    )
    assert error.element == "mujoco site 'x'"
    assert error.detail == (
        "MuJoCo rejects <site name='x'>: repeated name 'x' in site "
        "(to change an existing element, use <override>)"
    )


def test_without_check_a_bad_attribute_fails_validation_with_mujocos_message(tmp_path):
    _, after = convert(
        tmp_path,
        '<mujoco><override><joint name="elbow" armatur="0.1"/></override></mujoco>',
        check=False,
    )
    out = tmp_path / "out"
    out.mkdir()
    (out / "arm.xml").write_bytes(after.xml)
    with pytest.raises(ValidationError) as info:
        validate.run(out / "arm.xml", validate.ValidateConfig())
    assert "unrecognized attribute: 'armatur'" in str(info.value)
    assert "Element 'joint', line" in str(info.value)


def test_documented_example_converts_and_validates(tmp_path):
    """The example in docs/extension.md, with stand-in files, converts and simulates."""
    text = (Path(__file__).parents[2] / "docs" / "extension.md").read_text()
    block = re.search(r"```xml\n(.*?)```", text, re.S).group(1)
    mujoco_xml = re.search(r"<mujoco>.*</mujoco>", block, re.S).group(0)
    pkg = tmp_path / "arm_description"
    for folder in ("meshes", "textures", "urdf"):
        (pkg / folder).mkdir(parents=True)
    shutil.copy(BOX_STL, pkg / "meshes" / "finger.stl")
    shutil.copy(DATA / "meshes" / "quadrants.png", pkg / "textures" / "grid.png")
    tool = '<joint name="tool_joint" type="fixed"><parent link="forearm"/><child link="tool"/><origin xyz="0 0 0.2"/></joint><link name="tool"/>'
    model, before, resolver = emitted(write(pkg / "urdf", tool + mujoco_xml))
    after = extension.run(before, model, ExtensionConfig(resolver=resolver))
    out = tmp_path / "out"
    for rel, data in after.files.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)
    (out / "arm.xml").write_bytes(after.xml)
    checked = validate.run(out / "arm.xml", validate.ValidateConfig())
    assert checked is not None and checked.nq == 3
    assert after.qpos_home == (0.3, -0.6, 0.0)
