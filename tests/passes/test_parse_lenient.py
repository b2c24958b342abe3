"""Parse-level leniency: what urdfdom or other simulators read, we convert.

Each liberty is one ``warning:`` line naming the file and the element; with
``--strict`` it is one ``error:`` line and exit code 2. Every case goes
through the command line, and its output is compiled and stepped by MuJoCo.
Frames are checked against a clean twin of the file, scipy's rotations or
pinocchio.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

DATA = Path(__file__).parent.parent / "data"
BOX_STL = DATA / "meshes" / "box.stl"
INERT = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
)


def urdf(body: str, name: str = "wild") -> str:
    return f'<?xml version="1.0"?>\n<robot name="{name}">\n{body}\n</robot>\n'


def link(name: str, inner: str = "") -> str:
    return f'<link name="{name}">{INERT}{inner}</link>'


def joint(name: str, jtype: str, parent: str, child: str, inner: str = "") -> str:
    return (
        f'<joint name="{name}" type="{jtype}"><parent link="{parent}"/>'
        f'<child link="{child}"/>{inner}</joint>'
    )


def run_cli(src: Path, out: Path, *extra: str, env: dict | None = None):
    return subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", str(src), "-o", str(out), "--no-ros-env", *extra],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, **(env or {})},
    )


def lines(stderr: str, kind: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith(f"{kind}: ")]


def compile_and_step(xml: Path, seconds: float = 1.0) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """MuJoCo compiles the scene and simulates it from the home keyframe without warnings."""
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    for _ in range(int(seconds / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert np.isfinite(d.qpos).all() and np.isfinite(d.qacc).all()
    assert not any(w.number for w in d.warning), "MuJoCo warned while stepping"
    return m, d


def body_pose(m: mujoco.MjModel, d: mujoco.MjData, name: str) -> tuple[np.ndarray, np.ndarray]:
    b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
    return d.xpos[b].copy(), d.xmat[b].reshape(3, 3).copy()


@dataclass
class Wild:
    """One wild input: the file, what its warnings name, and how to run it."""

    filename: str
    text: str
    needles: list[str]
    """One per expected warning: text the warning line contains (the element)."""
    args: tuple[str, ...] = ()
    env: dict[str, str] = field(default_factory=dict)
    setup: Callable[[Path], None] | None = None

    def write(self, folder: Path) -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        if self.setup is not None:
            self.setup(folder)
        src = folder / self.filename
        src.write_text(self.text.replace("@DIR@", str(folder)))
        return src


def convert_wild(case: Wild, tmp_path: Path) -> tuple[Path, Path, list[str]]:
    """Convert leniently; every expected warning is there, naming file and element."""
    src = case.write(tmp_path / "in")
    out = tmp_path / "out" / "robot.xml"
    proc = run_cli(src, out, *case.args, env=case.env)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    warnings = lines(proc.stderr, "warning")
    ours = [w for w in warnings if src.name in w]
    assert len(ours) == len(case.needles), proc.stderr
    for needle in case.needles:
        assert any(needle in w for w in ours), (needle, proc.stderr)
    return src, out, warnings


# -- 1. bytes lxml rejects -----------------------------------------------------

CLEAN = urdf(
    link("base", '<collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision>')
    + link("arm", '<collision><geometry><sphere radius="0.05"/></geometry></collision>')
    + joint(
        "j1",
        "revolute",
        "base",
        "arm",
        '<origin xyz="0.1 0 0.2" rpy="0.3 0 0"/><axis xyz="0 1 0"/>'
        '<limit lower="-1" upper="1" effort="5" velocity="1"/>',
    )
)
XACRO_CLEAN = CLEAN.replace(
    '<robot name="wild">',
    '<robot name="wild" xmlns:xacro="http://www.ros.org/wiki/xacro">'
    '<xacro:property name="r" value="0.05"/>',
).replace('radius="0.05"', 'radius="${r}"')

BYTES = {
    "version_0_0": Wild(
        "robot.urdf", CLEAN.replace('version="1.0"', 'version="0.0"'), ["XML declaration"]
    ),
    "whitespace_before_declaration": Wild(
        "robot.urdf", "\n   \n" + CLEAN, ["XML declaration: whitespace"]
    ),
    "comment_before_declaration": Wild(
        "robot.urdf", "<!-- exported by a CAD tool -->\n" + CLEAN, ["XML declaration: a comment"]
    ),
    "content_after_robot": Wild(
        "robot.urdf", CLEAN + "</robot>\nstray text\n", ["end of document"]
    ),
    "xacro_comment_before_declaration": Wild(
        "robot.urdf.xacro", "<!-- header -->\n" + XACRO_CLEAN, ["XML declaration: a comment"]
    ),
}


def with_drake(text: str) -> str:
    """``drake:`` elements and attributes where Drake's exports put them, undeclared."""
    proximity = (
        '<drake:proximity_properties><drake:mu_static value="0.5"/></drake:proximity_properties>'
    )
    group = (
        '<drake:collision_filter_group name="g"><drake:member link="base"/>'
        "</drake:collision_filter_group>"
    )
    return (
        text.replace("</geometry></collision>", f"</geometry>{proximity}</collision>", 1)
        .replace('<limit lower="-1"', '<limit drake:acceleration="2.5" lower="-1"')
        .replace("</robot>", f"{group}\n</robot>")
    )


BYTES |= {
    "undeclared_prefix": Wild("robot.urdf", with_drake(CLEAN), ["namespace prefix 'drake'"]),
    "xacro_undeclared_prefix": Wild(
        "robot.urdf.xacro", with_drake(XACRO_CLEAN), ["namespace prefix 'drake'"]
    ),
}


@pytest.fixture(scope="module")
def clean_bytes(tmp_path_factory) -> bytes:
    """The clean file's MJCF, converted once by the command for every repaired twin."""
    clean_src = tmp_path_factory.mktemp("clean") / "in" / "robot.urdf"
    clean_src.parent.mkdir(parents=True)
    clean_src.write_text(CLEAN)
    clean_out = clean_src.parents[1] / "out" / "robot.xml"
    assert run_cli(clean_src, clean_out).returncode == 0
    return clean_out.read_bytes()


@pytest.mark.parametrize("case", sorted(BYTES))
def test_repaired_bytes_convert_exactly_like_the_clean_file(case, tmp_path, clean_bytes):
    wild = BYTES[case]
    _, out, _ = convert_wild(wild, tmp_path / "wild")
    assert out.read_bytes() == clean_bytes, "same model, same frames, same bytes"
    m, _ = compile_and_step(out.with_name("scene.xml"))
    assert m.njnt == 1


def test_undeclared_prefix_converts_like_the_twin_that_declares_it(tmp_path):
    """urdfdom ignores namespaces; lxml needs the prefix bound. Bound to a URN no
    pass knows, the elements are foreign and ignored, exactly as when declared."""
    wild = Wild("robot.urdf", with_drake(CLEAN), ["namespace prefix 'drake'"])
    assert "<drake:proximity_properties>" in wild.text and "drake:acceleration" in wild.text
    _, out, warnings = convert_wild(wild, tmp_path / "wild")
    assert len(warnings) == 1, warnings
    twin = tmp_path / "twin" / "robot.urdf"
    twin.parent.mkdir()
    declared = '<robot name="wild" xmlns:drake="http://drake.mit.edu">'
    twin.write_text(wild.text.replace('<robot name="wild">', declared))
    proc = run_cli(twin, tmp_path / "twin" / "out" / "robot.xml")
    assert proc.returncode == 0 and not lines(proc.stderr, "warning"), proc.stderr
    assert out.read_bytes() == (tmp_path / "twin" / "out" / "robot.xml").read_bytes()
    m, _ = compile_and_step(out.with_name("scene.xml"))
    assert m.njnt == 1 and (m.geom_bodyid > 0).sum() == 2


def test_declaration_repair_keeps_line_numbers_for_later_errors(tmp_path):
    """A repaired file that is still malformed is reported at its own line."""
    from lxml import etree

    broken = CLEAN.replace("</link>", "</link>\n").replace('<link name="arm">', '<link name="arm>')
    with pytest.raises(etree.XMLSyntaxError) as info:  # the reference: lxml, same lines
        etree.fromstring(broken.encode())
    src = tmp_path / "robot.urdf"
    src.write_text("<!-- c --> " + broken)  # the comment shares line 1 with the declaration
    proc = run_cli(src, tmp_path / "out" / "robot.xml")
    assert proc.returncode == 2
    errors = lines(proc.stderr, "error")
    assert len(errors) == 1 and f"line {info.value.position[0]}:" in errors[0], proc.stderr
    assert info.value.position[0] > 3


# -- 2. vectors with extra numbers -------------------------------------------


def _mesh_setup(folder: Path) -> None:
    (folder / "meshes").mkdir(exist_ok=True)
    shutil.copy(BOX_STL, folder / "meshes" / "box.stl")


def extra_numbers(extra: bool) -> str:
    x = " 7" if extra else ""
    return urdf(
        link(
            "base",
            f'<visual><origin xyz="0 0 0.05{x}"/><geometry><box size="0.1 0.1 0.1{x}"/></geometry>'
            f'<material name="red"><color rgba="1 0 0 1{x}"/></material></visual>',
        )
        + link(
            "arm",
            '<collision><geometry><mesh filename="meshes/box.stl" '
            f'scale="0.1 0.2 0.3{x}"/></geometry></collision>',
        )
        + joint(
            "j1",
            "revolute",
            "base",
            "arm",
            f'<origin xyz="0.1 0.2 0.3" rpy="0.4 -0.5 1.57{x}"/><axis xyz="0 0 1{x}"/>'
            '<limit lower="-1" upper="1" effort="5" velocity="1"/>',
        )
    )


EXTRA = Wild(
    "robot.urdf",
    extra_numbers(True),
    [
        "link 'base' visual 0 <origin xyz>",
        "link 'base' visual 0 <box size>",
        "link 'base' visual 0 <color rgba>",
        "link 'arm' collision 0 <mesh scale>",
        "joint 'j1' <origin rpy>",
        "joint 'j1' <axis xyz>",
    ],
    setup=_mesh_setup,
)


def test_extra_numbers_use_the_first_n_and_frames_stay_exact(tmp_path):
    src, out, warnings = convert_wild(EXTRA, tmp_path / "wild")
    assert all("the first" in w for w in warnings if src.name in w)
    clean = Wild("robot.urdf", extra_numbers(False), [], setup=_mesh_setup)
    _, clean_out, _ = convert_wild(clean, tmp_path / "clean")
    assert out.read_bytes() == clean_out.read_bytes(), "the 3-number file, byte for byte"

    m, _ = compile_and_step(out.with_name("scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)  # joint at zero
    pos, rot = body_pose(m, d, "arm")
    expected = Rotation.from_euler("xyz", [0.4, -0.5, 1.57]).as_matrix()  # URDF rpy: fixed axes
    np.testing.assert_allclose(pos, [0.1, 0.2, 0.3], atol=1e-15)
    np.testing.assert_allclose(rot, expected, atol=1e-15)
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "arm_collision")
    mesh = m.geom_dataid[g]
    verts = m.mesh_vert[m.mesh_vertadr[mesh] : m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
    world = d.geom_xpos[g] + verts @ d.geom_xmat[g].reshape(3, 3).T
    in_link = (world - pos) @ rot  # MuJoCo recentres meshes; the link frame does not move
    extent = in_link.max(axis=0) - in_link.min(axis=0)
    # box.stl is 0.1 x 0.2 x 0.3 (float32 vertices); scaled by the first three numbers
    np.testing.assert_allclose(extent, [0.01, 0.04, 0.09], rtol=1e-6)


# -- 3. lower > upper ---------------------------------------------------------

LIMITS = Wild(
    "robot.urdf",
    urdf(
        link("base")
        + link("arm", '<collision><geometry><sphere radius="0.05"/></geometry></collision>')
        + link("slider", '<collision><geometry><sphere radius="0.05"/></geometry></collision>')
        + joint(
            "hinge",
            "revolute",
            "base",
            "arm",
            '<origin xyz="0 0 0.5"/><axis xyz="0 1 0"/>'
            '<limit lower="1.5" upper="-1.5" effort="5" velocity="1"/>',
        )
        + joint(
            "slide",
            "prismatic",
            "arm",
            "slider",
            '<origin xyz="0.2 0 0"/><axis xyz="1 0 0"/>'
            '<limit lower="0.3" upper="0.1" effort="5" velocity="1"/>',
        )
    ),
    ["joint 'hinge' <limit>", "joint 'slide' <limit>"],
)


def test_lower_above_upper_leaves_the_joint_unlimited(tmp_path):
    _, out, _ = convert_wild(LIMITS, tmp_path)
    m, _ = compile_and_step(out.with_name("scene.xml"))
    for name in ("hinge", "slide"):
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        assert not m.jnt_limited[j]
    assert m.key_qpos[0].tolist() == [0.0, 0.0]
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    pos, _ = body_pose(m, d, "slider")
    assert pos.tolist() == [0.2, 0.0, 0.5]


# -- 4. spherical joints -------------------------------------------------------


def ball_robot(jtype: str) -> str:
    control = """
  <ros2_control name="arm" type="system">
    <hardware><plugin>mock_components/GenericSystem</plugin></hardware>
    <joint name="shoulder"><command_interface name="position"/><state_interface name="position"/></joint>
    <joint name="wrist"><command_interface name="position"/><state_interface name="position"/></joint>
    <joint name="finger"><command_interface name="position"/>
      <state_interface name="position"><param name="initial_value">0.3</param></state_interface>
    </joint>
  </ros2_control>"""
    return urdf(
        link("base", '<collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision>')
        + link(
            "arm",
            '<collision><geometry><cylinder radius="0.03" length="0.3"/></geometry></collision>',
        )
        + link("hand", '<collision><geometry><box size="0.05 0.08 0.02"/></geometry></collision>')
        + '<link name="palm"/>'  # no inertial: the ball's child is massless but for its subtree
        + link("tip", '<collision><geometry><sphere radius="0.02"/></geometry></collision>')
        + joint(
            "shoulder",
            "revolute",
            "base",
            "arm",
            '<origin xyz="0 0 0.1" rpy="0 0.2 0"/><axis xyz="0 1 0"/>'
            '<limit lower="-2" upper="2" effort="50" velocity="2"/>',
        )
        + joint(
            "wrist",
            jtype,
            "arm",
            "hand",
            '<origin xyz="0.01 0.02 0.3" rpy="0.1 0.2 0.3"/><limit upper="0.7" effort="5" velocity="1"/>'
            '<dynamics damping="0.1"/>',
        )
        + joint("palm_fixed", "fixed", "hand", "palm", '<origin xyz="0 0 0.02"/>')
        + joint(
            "finger",
            "prismatic",
            "palm",
            "tip",
            '<origin xyz="0 0.03 0.01" rpy="0 0 0.5"/><axis xyz="1 0 0"/>'
            '<limit lower="0" upper="0.5" effort="5" velocity="1"/>',
        )
        + control
    )


@pytest.mark.parametrize("jtype", ["spherical", "ball"])
def test_spherical_joint_is_a_ball_and_its_frames_match_pinocchio(jtype, tmp_path):
    case = Wild("robot.urdf", ball_robot(jtype), [f"joint 'wrist': type '{jtype}'"])
    src, out, warnings = convert_wild(case, tmp_path)
    assert any("wrist" in w and "no actuator" in w for w in warnings), warnings

    m, _ = compile_and_step(out.with_name("scene.xml"))
    wrist = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "wrist")
    finger = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "finger")
    assert m.jnt_type[wrist] == mujoco.mjtJoint.mjJNT_BALL
    assert m.jnt_limited[wrist] and m.jnt_range[wrist].tolist() == [0.0, 0.7]
    assert m.dof_damping[m.jnt_dofadr[wrist]] == 0.1
    # home keyframe: shoulder 0, the ball's identity quaternion, the finger's initial value
    assert m.nq == 6 and m.key_qpos[0].tolist() == [0.0, 1.0, 0.0, 0.0, 0.0, 0.3]
    assert m.jnt_qposadr[finger] == 5
    assert m.nu == 2 and m.key_ctrl[0].tolist() == [0.0, 0.3]
    sensors = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SENSOR, i) for i in range(m.nsensor)}
    assert "finger_pos" in sensors and not any(s.startswith("wrist") for s in sensors)

    # Pinocchio does not read spherical joints; a floating joint at zero translation
    # is the same rotation, in pinocchio's (x, y, z, w) order.
    import pinocchio as pin

    twin = src.with_name("twin.urdf")
    twin.write_text(src.read_text().replace(f'type="{jtype}"', 'type="floating"'))
    pm = pin.buildModelFromUrdf(str(twin))
    pd = pm.createData()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    for _ in range(4):
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        shoulder, slide = rng.uniform(-2, 2), rng.uniform(0, 0.5)
        d.qpos[:] = [shoulder, *quat, slide]
        mujoco.mj_kinematics(m, d)
        q = pin.neutral(pm)
        q[pm.joints[pm.getJointId("shoulder")].idx_q] = shoulder
        iq = pm.joints[pm.getJointId("wrist")].idx_q
        q[iq : iq + 7] = [0, 0, 0, quat[1], quat[2], quat[3], quat[0]]
        q[pm.joints[pm.getJointId("finger")].idx_q] = slide
        pin.framesForwardKinematics(pm, pd, q)
        for name in ("arm", "hand", "palm", "tip"):
            placement = pd.oMf[pm.getFrameId(name, pin.FrameType.BODY)]
            pos, rot = body_pose(m, d, name)
            np.testing.assert_allclose(pos, placement.translation, atol=1e-12)
            np.testing.assert_allclose(rot, placement.rotation, atol=1e-12)


def test_mimic_of_a_ball_joint_is_ignored_with_a_warning(tmp_path):
    text = ball_robot("spherical").replace(
        '<limit lower="0" upper="0.5" effort="5" velocity="1"/>',
        '<limit lower="0" upper="0.5" effort="5" velocity="1"/><mimic joint="wrist"/>',
    )
    src, out, warnings = convert_wild(
        Wild("robot.urdf", text, ["joint 'wrist': type 'spherical'"]), tmp_path
    )
    assert any("joint 'finger'" in w and "mimic ignored" in w for w in warnings), warnings
    m, _ = compile_and_step(out.with_name("scene.xml"))
    assert m.neq == 0


# -- 5. planes and unknown geometry ---------------------------------------------

PLANES = Wild(
    "robot.urdf",
    urdf(
        link(
            "base",
            '<collision><origin xyz="0 0 -0.5" rpy="0.3 0 0"/>'
            '<geometry><plane normal="0 1 1" size="4 6"/></geometry></collision>'
            '<collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision>'
            '<visual><geometry><heightmap uri="terrain.png"/></geometry></visual>',
        )
        + link(
            "arm",
            '<collision><geometry><plane normal="0 0 1"/></geometry></collision>'
            '<collision><geometry><cdf uri="x.cdf"/></geometry></collision>'
            '<collision><geometry><sphere radius="0.05"/></geometry></collision>'
            "<visual><geometry><made_up_shape/></geometry></visual>",
        )
        + joint(
            "j1",
            "revolute",
            "base",
            "arm",
            '<origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>'
            '<limit lower="-1" upper="1" effort="5" velocity="1"/>',
        )
    ),
    [
        "link 'base' collision 0 <plane>",
        "link 'base' visual 0 <heightmap>",
        "link 'arm' collision 0 <plane>",
        "link 'arm' collision 1 <cdf>",
        "link 'arm' visual 0 <made_up_shape>",
    ],
)


def test_plane_in_a_static_link_is_a_mujoco_plane_and_dropped_from_a_moving_one(tmp_path):
    _, out, warnings = convert_wild(PLANES, tmp_path)
    assert any("link 'arm' collision 0 <plane>" in w and "dropped" in w for w in warnings)
    m, _ = compile_and_step(out.with_name("scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    plane = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "base_collision_0")
    assert plane >= 0
    assert m.geom_type[plane] == mujoco.mjtGeom.mjGEOM_PLANE
    assert m.geom_size[plane].tolist() == [2.0, 3.0, 0.05]
    normal = Rotation.from_euler("xyz", [0.3, 0, 0]).apply([0, 1, 1]) / math.sqrt(2)
    np.testing.assert_allclose(d.geom_xmat[plane].reshape(3, 3)[:, 2], normal, atol=1e-15)
    np.testing.assert_allclose(d.geom_xpos[plane], [0, 0, -0.5], atol=1e-15)
    arm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "arm")
    assert [m.geom_type[g] for g in range(m.ngeom) if m.geom_bodyid[g] == arm] == [
        mujoco.mjtGeom.mjGEOM_SPHERE
    ]


def test_floating_base_drops_planes_everywhere(tmp_path):
    case = Wild(
        PLANES.filename,
        PLANES.text,
        [n.replace("<plane>", "<plane>: plane in a moving link") for n in PLANES.needles],
        args=("--floating-base",),
    )
    _, out, _ = convert_wild(case, tmp_path)
    m, _ = compile_and_step(out.with_name("scene.xml"))
    robot = [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0]
    assert mujoco.mjtGeom.mjGEOM_PLANE not in [m.geom_type[g] for g in robot]


# -- 6. zero-size shapes -----------------------------------------------------

ZERO = Wild(
    "robot.urdf",
    urdf(
        link("base", '<collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision>')
        + link(
            "arm",
            '<visual><geometry><sphere radius="0"/></geometry></visual>'
            '<collision><geometry><box size="0 0 0"/></geometry></collision>'
            '<collision><geometry><cylinder radius="0" length="0.1"/></geometry></collision>'
            '<collision><geometry><cylinder radius="0.1" length="0"/></geometry></collision>'
            '<collision><geometry><mesh filename="meshes/box.stl" scale="1 0 1"/></geometry>'
            "</collision>"
            '<collision><origin xyz="0 0 0.1"/><geometry><capsule radius="0.04" length="0"/>'
            "</geometry></collision>",
        )
        + joint(
            "j1",
            "revolute",
            "base",
            "arm",
            '<origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>'
            '<limit lower="-1" upper="1" effort="5" velocity="1"/>',
        )
    ),
    [
        "link 'arm' visual 0 <sphere>",
        "link 'arm' collision 0 <box>",
        "link 'arm' collision 1 <cylinder>",
        "link 'arm' collision 2 <cylinder>",
        "link 'arm' collision 3 <mesh>",
        "link 'arm' collision 4 <capsule>",
        "<capsule> is URDF 1.1 and this file declares version 1.0",
    ],
    setup=_mesh_setup,
)


def test_zero_size_shapes_are_dropped(tmp_path):
    _, out, warnings = convert_wild(ZERO, tmp_path)
    assert sum("zero size; dropped" in w for w in warnings) == 5
    m, _ = compile_and_step(out.with_name("scene.xml"))
    arm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "arm")
    kept = [g for g in range(m.ngeom) if m.geom_bodyid[g] == arm]
    assert len(kept) == 1 and m.geom_type[kept[0]] == mujoco.mjtGeom.mjGEOM_SPHERE
    assert m.geom_size[kept[0]][0] == 0.04 and m.geom_pos[kept[0]].tolist() == [0, 0, 0.1]


# -- 7. substitution args in a plain URDF -------------------------------------


def _package_setup(folder: Path) -> None:
    _mesh_setup(folder)
    pkg = folder / "pkgs" / "meshpkg"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>meshpkg</name></package>")
    shutil.copy(BOX_STL, pkg / "meshes" / "box.stl")


def _mesh(filename: str, x: float) -> str:
    return (
        f'<collision><origin xyz="{x} 0 0"/>'
        f'<geometry><mesh filename="{filename}" scale="0.1 0.1 0.1"/></geometry></collision>'
    )


SUBST = Wild(
    "robot.urdf",
    urdf(
        link(
            "base",
            _mesh("$(find meshpkg)/meshes/box.stl", 0.0)
            + _mesh("$(env LENIENT_TEST_MESH_DIR)/box.stl", 0.2)
            + _mesh("$(optenv LENIENT_TEST_UNSET_VAR @DIR@/meshes)/box.stl", 0.4),
        )
    ),
    ["$(find meshpkg)", "$(env LENIENT_TEST_MESH_DIR)", "$(optenv LENIENT_TEST_UNSET_VAR"],
    args=("--package-path", "@DIR@/pkgs"),
    env={"LENIENT_TEST_MESH_DIR": "@DIR@/meshes"},
    setup=_package_setup,
)


def _at(case: Wild, folder: Path) -> Wild:
    """The case with its folder placeholders filled in."""
    fill = lambda s: s.replace("@DIR@", str(folder))  # noqa: E731
    return Wild(
        case.filename,
        case.text,
        case.needles,
        tuple(fill(a) for a in case.args),
        {k: fill(v) for k, v in case.env.items()},
        case.setup,
    )


def test_substitution_args_in_a_plain_urdf_resolve_as_xacro_would(tmp_path):
    os.environ.pop("LENIENT_TEST_UNSET_VAR", None)
    _, out, warnings = convert_wild(_at(SUBST, tmp_path / "in"), tmp_path)
    assert all("link 'base' <mesh> filename" in w for w in warnings if "$(" in w)
    m, _ = compile_and_step(out.with_name("scene.xml"))
    assert m.ngeom == 3 + 1  # three meshes and the scene's floor
    assert m.nmesh == 1, "the same file three times: one asset"


def test_unset_env_in_a_plain_urdf_is_an_error_naming_the_element(tmp_path):
    src = tmp_path / "robot.urdf"
    src.write_text(urdf(link("base", _mesh("$(env LENIENT_TEST_UNSET_VAR)/box.stl", 0))))
    proc = run_cli(src, tmp_path / "out" / "robot.xml")
    assert proc.returncode == 2
    errors = lines(proc.stderr, "error")
    assert len(errors) == 1 and src.name in errors[0] and "<mesh> filename" in errors[0]


def test_only_env_optenv_find_are_substituted_and_not_in_ros_only_elements(tmp_path):
    """$(arg) needs a xacro run (it stays text); a plugin's $(find) is never opened by us."""
    src = tmp_path / "robot.urdf"
    src.write_text(
        urdf(
            link(
                "base",
                '<visual name="$(arg tag)"><geometry><sphere radius="0.1"/></geometry></visual>',
            )
            + '<gazebo><plugin name="p" filename="$(find no_such_pkg)/lib/plugin.so"/></gazebo>'
        )
    )
    proc = run_cli(src, tmp_path / "out" / "robot.xml")
    assert proc.returncode == 0, proc.stderr
    assert "$(" not in "".join(lines(proc.stderr, "warning")), proc.stderr


# -- --strict: every liberty is an error ---------------------------------------

STRICT = {
    **{f"bytes_{k}": v for k, v in BYTES.items()},
    "extra_numbers": EXTRA,
    "lower_above_upper": LIMITS,
    "spherical": Wild("robot.urdf", ball_robot("spherical"), ["joint 'wrist'"]),
    "ball": Wild("robot.urdf", ball_robot("ball"), ["joint 'wrist'"]),
    "plane": PLANES,
    "zero_size": ZERO,
    "substitution": SUBST,
}


@pytest.mark.parametrize("case", sorted(STRICT))
def test_strict_turns_each_liberty_into_one_error_line(case, tmp_path):
    wild = _at(STRICT[case], tmp_path / "in")
    src = wild.write(tmp_path / "in")
    out = tmp_path / "out" / "robot.xml"
    proc = run_cli(src, out, "--strict", *wild.args, env=wild.env)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    errors = lines(proc.stderr, "error")
    assert len(errors) == 1, proc.stderr
    assert src.name in errors[0] and any(n in errors[0] for n in wild.needles), errors[0]
    assert not out.parent.exists(), "nothing written"
