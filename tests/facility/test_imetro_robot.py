"""The iMETRO robot (facility/robots/imetro_robot): converts with the command
a user types, and the model matches the facts (facility-facts.md section 3)
and behaves in simulation: actuators and limits, masses, the real robot's
frame chain (the published offsets of clr_description composed independently),
UR10e kinematics against the DH parameters, the mimicking lift stage, holding
the home pose, settling after steps, the flange force-torque sensor, the two
RGBD cameras and a grasp of a handle strap.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

import urdf2mjcf
from tests.facility.mechanism_checks import dh_flange

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "facility" / "robots" / "imetro_robot"
SOURCE = PACKAGE / "urdf" / "imetro_robot.urdf.xacro"
ACTUATOR_CONFIG = PACKAGE / "config" / "actuators.yaml"

ARM = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]
ACTUATED = ["rail", "lift", *ARM, "finger_1_joint"]
MIMICS = {"lift_middle": ("lift", 0.5), "finger_2_joint": ("finger_1_joint", 1.0)}
# The home pose given to ros2_control as initial_value (and so the home keyframe):
# the published stow pose of the arm (facility-facts.md section 4), rail and lift 0.
STOW = (1.5010, -0.3316, -2.2515, -3.6477, -1.5533, 1.5708)
HOME = {"rail": 0.0, "lift": 0.0, **dict(zip(ARM, STOW, strict=True)), "finger_1_joint": 0.025}
# The real robot's fixed frame chain, parent -> child: (xyz, rpy), from the public
# description (clr_macro.xacro and the vention rail / ewellix lift macros it includes)
# and facility-facts.md section 3; the joints' origins are the moving joints' at zero.
PUBLISHED_CHAIN = [
    ("rail_link", (0.0874537, 0.114017, 0.300), (0, 0, 0)),  # clr_base -> rail
    ("rail_carriage_link", (-0.96975, 0, 0.096), (0, 0, 0)),  # rail joint origin
    ("carriage_link", (-0.003624, -0.0900, 0.0185), (0, 0, 0)),  # clr_carriage
    ("lift_plate_link", (0, 0, 0.054525), (0, 0, 0)),  # lower_lift_plate
    ("lift_lower_link", (0, 0, 0.295), (0, 0, 0)),  # ewellix lift base
    ("lift_upper_link", (0, 0, 0.0915), (0, 0, 0)),  # lift joint origin
    ("lift_top_plate_link", (0, 0, 0.253525), (0, 0, 0)),  # upper_lift_plate
    ("right_angle_mount", (0, 0, 0.009525), (0, 0, 0)),
    ("arm_plate_link", (0, 0.112509, 0.112509), (0, 0, 0)),  # ur10e_mount_plate
    ("base_link", (0, 0.0225, 0), (-math.pi / 2, math.pi, 0)),  # chonkur_mount_joint
]
# joint: (type, axis in its frame, lower, upper, velocity, effort); facility-facts.md section 3
LIMITS = {
    "rail": ("prismatic", (1, 0, 0), 0.0, 2.0, 0.15, 1000),
    "lift": ("prismatic", (0, 0, 1), 0.0, 0.7, 1.0, 1000),
    "lift_middle": ("prismatic", (0, 0, -1), 0.0, 0.35, None, None),
    "shoulder_pan_joint": ("revolute", (0, 0, 1), -2 * math.pi, 2 * math.pi, 2.094, 330),
    "shoulder_lift_joint": ("revolute", (0, 0, 1), -2 * math.pi, 2 * math.pi, 2.094, 330),
    "elbow_joint": ("revolute", (0, 0, 1), -math.pi, math.pi, math.pi, 150),
    "wrist_1_joint": ("revolute", (0, 0, 1), -2 * math.pi, 2 * math.pi, math.pi, 56),
    "wrist_2_joint": ("revolute", (0, 0, 1), -2 * math.pi, 2 * math.pi, math.pi, 56),
    "wrist_3_joint": ("revolute", (0, 0, 1), -2 * math.pi, 2 * math.pi, math.pi, 56),
    "finger_1_joint": ("prismatic", (0, 1, 0), 0.0, 0.025, 0.15, 185),
    "finger_2_joint": ("prismatic", (0, -1, 0), 0.0, 0.025, 0.15, 185),
}
# actuator: (kp, force limit, joint damping, armature); actuators.yaml = the facts' reference gains
GAINS = {
    "rail": (25000, 1000, 0, 0),
    "lift": (75000, 1000, 0, 0),
    "shoulder_pan_joint": (1e5, 330, 10, 0.1),
    "shoulder_lift_joint": (1e5, 330, 10, 0.1),
    "elbow_joint": (4e4, 150, 5, 0.1),
    "wrist_1_joint": (1e4, 56, 2, 0.1),
    "wrist_2_joint": (1e4, 56, 2, 0.1),
    "wrist_3_joint": (1e4, 56, 2, 0.1),
    "finger_1_joint": (1e5, 185, 0, 0.5),
}
MASSES = {
    "rail_link": 38.5,
    "rail_carriage_link": 2.9,
    "lift_lower_link": 19.5,
    "lift_middle_link": 15.6,
    "lift_upper_link": 15.2,
    "shoulder_link": 7.369,
    "upper_arm_link": 13.051,
    "forearm_link": 3.989,
    "wrist_1_link": 2.1,
    "wrist_2_link": 1.98,
    "wrist_3_link": 0.615,
    "gripper_base_link": 0.86,
    "finger_1_link": 0.05,
    "finger_2_link": 0.05,
    "base_link_inertia": 4.0,  # ur_description's UR10e base
    "wrist_camera_link": 0.072,  # RealSense D435
    "lift_camera_link": 0.072,
    # our estimates (aluminium; the real description leaves these massless)
    "carriage_link": 5.0,
    "lift_plate_link": 4.9,
    "lift_top_plate_link": 2.6,
    "right_angle_mount": 6.0,
    "arm_plate_link": 1.5,
    "tool_adapter_link": 0.3,
}
# UR10e standard DH parameters (public kinematics)
DH_D = (0.1807, 0.0, 0.0, 0.17415, 0.11985, 0.11655)
DH_A = (0.0, -0.6127, -0.57155, 0.0, 0.0, 0.0)
DH_ALPHA = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
PACKAGES = {
    "package_paths": [ROOT / "facility" / "robots"],
    "packages": {
        "facility_common": ROOT / "facility" / "common",
        "facility_meshes": ROOT / "meshes",
    },
    "use_environment": False,
    "actuator_config": ACTUATOR_CONFIG,
}


# -- conversion and helpers ----------------------------------------------------


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    """The documented command line, plus a JSON report."""
    out = tmp_path_factory.mktemp("imetro_robot") / "robot.xml"
    report = out.with_name("report.json")
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "urdf2mjcf",
            str(SOURCE),
            "-o",
            str(out),
            "--package-path",
            str(ROOT / "facility" / "robots"),
            "--package",
            f"facility_common={ROOT / 'facility' / 'common'}",
            "--package",
            f"facility_meshes={ROOT / 'meshes'}",
            "--actuator-config",
            str(ACTUATOR_CONFIG),
            "--no-ros-env",
            "--report",
            str(report),
            "--overwrite",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="module")
def model(converted) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(converted))


def _home(m: mujoco.MjModel, settle: float = 0.0) -> mujoco.MjData:
    """The home keyframe (qpos and servo targets), optionally simulated for ``settle`` s."""
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    while d.time < settle - 1e-9:
        mujoco.mj_step(m, d)
    return d


def _pose(m: mujoco.MjModel, d: mujoco.MjData, values: dict[str, float]) -> None:
    """Home with ``values`` set (mimic followers kept on their constraint), servo targets too."""
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    for name, q in values.items():
        d.qpos[m.joint(name).qposadr[0]] = q
    for follower, (leader, k) in MIMICS.items():
        d.qpos[m.joint(follower).qposadr[0]] = k * d.qpos[m.joint(leader).qposadr[0]]
    for i in range(m.nu):
        d.ctrl[i] = d.qpos[m.joint(m.actuator(i).trnid[0]).qposadr[0]]
    mujoco.mj_forward(m, d)


def _q(m: mujoco.MjModel, d: mujoco.MjData, joint: str) -> float:
    return float(d.qpos[m.joint(joint).qposadr[0]])


def _frame(d: mujoco.MjData, m: mujoco.MjModel, body: str) -> tuple[np.ndarray, np.ndarray]:
    b = m.body(body).id
    return d.xpos[b].copy(), d.xmat[b].reshape(3, 3).copy()


def _no_warnings(d: mujoco.MjData) -> None:
    fired = {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(d.warning) if w.number}
    assert not fired, f"MuJoCo warnings: {fired}"


def _dh(q) -> np.ndarray:
    return dh_flange(q, DH_D, DH_A, DH_ALPHA)


def _subtree_mass(m: mujoco.MjModel, body: str) -> float:
    return float(m.body_subtreemass[m.body(body).id])


# -- the conversion ---------------------------------------------------------------


def test_converts_without_warnings_with_every_output(converted):
    assert converted.is_file() and converted.with_name("scene.xml").is_file()
    notes = json.loads(converted.with_name("report.json").read_text())["notes"]
    warnings = [n for n in notes if n["kind"] == "warning"]
    assert warnings == []
    # the scene (floor, light) compiles too, and nothing touches at home
    m = mujoco.MjModel.from_xml_path(str(converted.with_name("scene.xml")))
    d = _home(m)
    assert d.ncon == 0


def test_joints_limits_and_mimics_as_the_facts():
    ir, _ = urdf2mjcf.build(SOURCE, urdf2mjcf.make_options(**PACKAGES))
    joints = ir.robot.joint_map
    for name, (kind, axis, lower, upper, velocity, effort) in LIMITS.items():
        j = joints[name]
        assert j.type == kind, name
        np.testing.assert_allclose(j.axis, axis, atol=1e-12, err_msg=name)
        assert (j.limit.lower, j.limit.upper) == pytest.approx((lower, upper), abs=1e-9), name
        if velocity is not None:
            assert (j.limit.velocity, j.limit.effort) == pytest.approx(
                (velocity, effort), abs=1e-3
            ), name
    for follower, (leader, k) in MIMICS.items():
        assert (joints[follower].mimic.joint, joints[follower].mimic.multiplier) == (leader, k)
        assert joints[follower].mimic.offset == 0
    # every link and joint hangs under the mount, the tree has the documented frames
    assert joints["imetro_robot_mount"].parent == "world"
    links = set(ir.robot.link_map)
    for frame in ("base", "base_link", "flange", "tool0", "ft_frame", "grasp_frame"):
        assert frame in links
    for cam in ("wrist_camera", "lift_camera"):
        assert {f"{cam}_link", f"{cam}_optical_frame"} <= links
    assert joints["tool_adapter_mount"].parent == "ft_frame", "the tool hangs below the F/T frame"
    assert joints["gripper_mount"].parent == "tool_adapter_link"
    assert joints["wrist_camera_joint"].parent == "wrist_camera_mount"
    assert joints["lift_camera_joint"].parent == "lift_camera_mount"


def test_prefix_names_every_link_and_joint(tmp_path):
    report = urdf2mjcf.convert(SOURCE, tmp_path / "robot.xml", args={"prefix": "left_"}, **PACKAGES)
    robot = report.model.robot
    assert all(link.name.startswith("left_") for link in robot.links if link.name != "world")
    assert all(j.name.startswith("left_") for j in robot.joints)
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "robot.xml"))
    assert sorted(m.actuator(i).name for i in range(m.nu)) == sorted("left_" + a for a in ACTUATED)
    assert m.sensor("left_ft_frame_force") and m.camera("left_wrist_camera_optical_frame")


# -- actuators ----------------------------------------------------------------------


def test_eight_position_servos_and_one_gripper_actuator(model):
    m = model
    names = [m.actuator(i).name for i in range(m.nu)]
    assert names == ACTUATED, "rail, lift, 6 arm joints, finger_1; mimics have none"
    for name in ACTUATED:
        a, j = m.actuator(name), m.joint(name)
        kp, force, damping, armature = GAINS[name]
        assert a.trnid[0] == j.id
        assert a.gaintype[0] == mujoco.mjtGain.mjGAIN_FIXED
        assert a.biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE, "position servo"
        assert a.gainprm[0] == pytest.approx(kp) and a.biasprm[1] == pytest.approx(-kp)
        assert -a.biasprm[2] > 0, "kv completed by the converter"
        np.testing.assert_allclose(a.ctrlrange, j.range, err_msg=name)
        np.testing.assert_allclose(a.forcerange, [-force, force], err_msg=name)
        assert m.jnt_actfrclimited[j.id] and m.jnt_actfrcrange[j.id][1] == pytest.approx(force)
        assert m.dof_damping[j.dofadr[0]] == pytest.approx(damping), name
        assert m.dof_armature[j.dofadr[0]] == pytest.approx(armature), name
    for follower in MIMICS:
        assert all(m.actuator(i).trnid[0] != m.joint(follower).id for i in range(m.nu))


def test_gravity_compensation_on_carriage_lift_and_arm_only(model):
    m = model
    compensated = {m.body(b).name for b in range(m.nbody) if m.body_gravcomp[b] > 0}
    assert compensated == {
        "rail_carriage_link",
        "lift_lower_link",
        "lift_middle_link",
        "lift_upper_link",
        "lift_top_plate_link",
        "right_angle_mount",
        "arm_plate_link",
        "base_link_inertia",
        "shoulder_link",
        "upper_arm_link",
        "forearm_link",
        "wrist_1_link",
        "wrist_2_link",
        "wrist_3_link",
    }
    for name in ACTUATED:
        assert m.jnt_actgravcomp[m.joint(name).id], (
            "through the actuators, within their force limits"
        )


# -- masses and kinematics -------------------------------------------------------------


def test_link_masses_match_the_facts(model):
    for body, mass in MASSES.items():
        assert model.body(body).mass[0] == pytest.approx(mass, abs=1e-9), body
    # frames are massless; what moves on the base is these parts and nothing else
    assert _subtree_mass(model, "rail_link") == pytest.approx(sum(MASSES.values()), abs=1e-9)


@pytest.mark.parametrize(
    "arm",
    [
        (0, 0, 0, 0, 0, 0),
        (0, -math.pi / 2, 0, 0, 0, 0),  # the facts' named home
        tuple(HOME[j] for j in ARM),
        (3.1927, -2.3913, -1.7760, -0.4700, -1.6177, -1.6134),  # demo_home
        (1.5010, -0.3316, -2.2515, -3.6477, -1.5533, 1.5708),  # stow
        (0.3, -1.1, 1.4, -2.0, 0.7, 2.5),
        (-2.5, -0.4, -2.9, 1.2, -2.2, -4.0),
    ],
)
def test_tool0_matches_ur10e_dh_forward_kinematics(model, arm):
    m = model
    d = mujoco.MjData(m)
    _pose(m, d, {"rail": 1.3, "lift": 0.45, **dict(zip(ARM, arm, strict=True))})
    # UR's base frame (DH frame 0) is base_link turned pi about z, as in ur_description
    p_base, r_base = _frame(d, m, "base")
    p_link, r_link = _frame(d, m, "base_link")
    np.testing.assert_allclose(p_base, p_link, atol=1e-12)
    np.testing.assert_allclose(r_base, r_link @ np.diag([-1.0, -1.0, 1.0]), atol=1e-12)
    t = _dh(arm)
    p_tool, r_tool = _frame(d, m, "tool0")
    np.testing.assert_allclose(p_tool, p_base + r_base @ t[:3, 3], atol=1e-6)
    np.testing.assert_allclose(r_tool, r_base @ t[:3, :3], atol=1e-6)
    # flange: x along the tool axis (ROS-Industrial), at the same point
    p_flange, r_flange = _frame(d, m, "flange")
    np.testing.assert_allclose(p_flange, p_tool, atol=1e-12)
    np.testing.assert_allclose(r_flange[:, 0], r_tool[:, 2], atol=1e-12)


def _rpy(r: float, p: float, y: float) -> np.ndarray:
    """URDF rpy: R = Rz(y) Ry(p) Rx(r)."""
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_frame_chain_is_the_real_robots(model):
    """Every frame from the base to the UR10e's base_link where the published offsets put
    it (composed here with numpy), and the arm hanging sideways: base z along +y."""
    m = model
    d = mujoco.MjData(m)
    for rail, lift in ((0.0, 0.0), (1.3, 0.45)):
        _pose(m, d, {"rail": rail, "lift": lift})
        p, r = np.zeros(3), np.eye(3)
        for body, xyz, rpy in PUBLISHED_CHAIN:
            p, r = p + r @ np.array(xyz, float), r @ _rpy(*rpy)
            if body == "rail_carriage_link":
                p = p + r @ np.array([rail, 0, 0])  # rail axis x
            if body == "lift_upper_link":
                p = p + r @ np.array([0, 0, lift])  # lift axis z
            p_m, r_m = _frame(d, m, body)
            np.testing.assert_allclose(p_m, p, atol=1e-9, err_msg=body)
            np.testing.assert_allclose(r_m, r, atol=1e-9, err_msg=body)
    _pose(m, d, {"rail": 0.0, "lift": 0.0})
    p_base, r_base = _frame(d, m, "base_link")
    np.testing.assert_allclose(p_base, [-0.885920, 0.159026, 1.231084], atol=1e-6)
    np.testing.assert_allclose(r_base[:, 2], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(r_base[:, 0], [-1, 0, 0], atol=1e-12)


@pytest.mark.parametrize(
    "arm",
    [
        # published waypoints at rail 0, lift 0: tool0 in the world from the published
        # offsets above and UR's DH parameters (both independent of the model)
        (2.443, -2.670, -1.571, -0.419, -1.500, -0.925),  # approach_bench_seat
        (2.5656, -3.0020, -0.9599, -0.6982, -1.5184, -1.0297),  # init
    ],
)
def test_tool0_in_the_world_at_published_waypoints(model, arm):
    m = model
    d = mujoco.MjData(m)
    _pose(m, d, {"rail": 0.0, "lift": 0.0, **dict(zip(ARM, arm, strict=True))})
    p, r = np.zeros(3), np.eye(3)
    for _, xyz, rpy in PUBLISHED_CHAIN:
        p, r = p + r @ np.array(xyz, float), r @ _rpy(*rpy)
    r = r @ np.diag([-1.0, -1.0, 1.0])  # base_link -> UR's DH base (ur_description)
    t = _dh(arm)
    p_tool, r_tool = _frame(d, m, "tool0")
    np.testing.assert_allclose(p_tool, p + r @ t[:3, 3], atol=1e-6)
    np.testing.assert_allclose(r_tool, r @ t[:3, :3], atol=1e-6)


def test_rail_and_lift_move_the_arm_base_along_x_and_z(model):
    m = model
    d = mujoco.MjData(m)
    _pose(m, d, {"rail": 0.0, "lift": 0.0})
    p0, _ = _frame(d, m, "base_link")
    _pose(m, d, {"rail": 1.7, "lift": 0.6})
    p1, _ = _frame(d, m, "base_link")
    np.testing.assert_allclose(p1 - p0, [1.7, 0.0, 0.6], atol=1e-12)


# -- mechanisms in simulation --------------------------------------------------------------


def test_lift_middle_stage_follows_the_lift_at_half_travel(model):
    m = model
    d = _home(m)
    d.ctrl[m.actuator("lift").id] = 0.6
    worst = 0.0
    while d.time < 3.0:
        mujoco.mj_step(m, d)
        worst = max(worst, abs(_q(m, d, "lift_middle") - 0.5 * _q(m, d, "lift")))
    _no_warnings(d)
    assert _q(m, d, "lift") == pytest.approx(0.6, abs=1e-3)
    assert _q(m, d, "lift_middle") == pytest.approx(0.3, abs=1e-3)
    assert worst < 1e-3, "within 1 mm of half the lift while it moves"
    # the middle stage hangs 0.034 m below the upper stage's origin and runs down it
    lower = d.xpos[m.body("lift_lower_link").id]
    assert d.xpos[m.body("lift_middle_link").id][2] - lower[2] == pytest.approx(
        0.0915 + 0.6 - 0.03397 - 0.3, abs=1e-3
    )


def test_home_keyframe_is_the_ros2_control_initial_values(model):
    m = model
    key = m.key("home")
    for name, q in HOME.items():
        assert key.qpos[m.joint(name).qposadr[0]] == pytest.approx(q, abs=1e-12), name
        assert key.ctrl[m.actuator(name).id] == pytest.approx(q, abs=1e-12), name
    for follower, (leader, k) in MIMICS.items():
        assert key.qpos[m.joint(follower).qposadr[0]] == pytest.approx(k * HOME[leader])


def test_home_pose_is_free_of_contact(model):
    m = model
    d = _home(m)
    assert d.ncon == 0
    # every pair of parts that may collide is over 3 mm apart (the real carriage runs
    # 4.5 mm beside the base's cable tray), and the arm over 2 cm from everything
    arm = m.body("base_link").id
    in_arm = {b for b in range(m.nbody) if _ancestor(m, b, arm)}
    for g1, g2 in _collidable_pairs(m):
        gap = mujoco.mj_geomDistance(m, d, g1, g2, 0.05, None)
        in_the_arm = {int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])} & in_arm
        assert gap > (0.02 if in_the_arm else 0.003), (m.geom(g1).name, m.geom(g2).name)
    # stow: the tool pointing down in front (+y) of the lift, 1.2 m above the floor
    p_tool, r_tool = _frame(d, m, "tool0")
    assert r_tool[2, 2] < -0.98 and p_tool[2] > 1.1
    assert p_tool[1] - _frame(d, m, "base_link")[0][1] > 0.5


def _ancestor(m: mujoco.MjModel, body: int, ancestor: int) -> bool:
    while body:
        if body == ancestor:
            return True
        body = int(m.body_parentid[body])
    return False


def _collidable_pairs(m: mujoco.MjModel) -> list[tuple[int, int]]:
    """Geom pairs MuJoCo's filters let collide: contype/conaffinity, not welded
    together, not parent and child, not excluded."""
    excluded = {int(s) for s in m.exclude_signature}
    pairs = []
    for g1 in range(m.ngeom):
        for g2 in range(g1 + 1, m.ngeom):
            if not (
                m.geom_contype[g1] & m.geom_conaffinity[g2]
                or m.geom_contype[g2] & m.geom_conaffinity[g1]
            ):
                continue
            b1, b2 = sorted((int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])))
            w1, w2 = m.body_weldid[b1], m.body_weldid[b2]
            if w1 == w2:
                continue
            p1, p2 = m.body_weldid[m.body_parentid[w1]], m.body_weldid[m.body_parentid[w2]]
            if w1 and w2 and (w1 == p2 or w2 == p1):
                continue
            if (b1 << 16) + b2 in excluded or (b2 << 16) + b1 in excluded:
                continue
            pairs.append((g1, g2))
    return pairs


def test_rail_lift_and_gripper_travel_without_self_contact(model):
    m = model
    d = mujoco.MjData(m)
    for rail in np.linspace(0, 2.0, 5):
        for lift in np.linspace(0, 0.7, 5):
            for finger in (0.0, 0.025):
                _pose(m, d, {"rail": rail, "lift": lift, "finger_1_joint": finger})
                assert d.ncon == 0, (rail, lift, finger)


def test_holds_home_for_five_seconds(model):
    m = model
    d = _home(m)
    p0, _ = _frame(d, m, "tool0")
    worst = 0.0
    while d.time < 5.0:
        mujoco.mj_step(m, d)
        worst = max(worst, float(np.linalg.norm(d.body("tool0").xpos - p0)))
    _no_warnings(d)
    assert worst < 1e-3, f"tool moved {worst * 1e3:.3f} mm"
    assert d.ncon == 0


@pytest.mark.parametrize("name", ACTUATED)
def test_a_step_on_each_joint_settles(model, name):
    m = model
    hinge = m.joint(name).type[0] == mujoco.mjtJoint.mjJNT_HINGE
    # large steps saturate the servos (force limits); small ones show the damping
    big = 0.1 if hinge else (-0.01 if name.startswith("finger") else 0.05)
    small = 1e-3 if hinge else (-1e-4 if name.startswith("finger") else 5e-4)
    for step in (big, small):
        d = _home(m, settle=0.5)
        i = m.actuator(name).id
        q0, target = _q(m, d, name), d.ctrl[i] + step
        d.ctrl[i] = target
        t0, trace = d.time, []
        while d.time < t0 + 2.0:
            mujoco.mj_step(m, d)
            trace.append((d.time - t0, _q(m, d, name)))
        _no_warnings(d)
        t, q = np.array(trace).T
        final = q[-1]
        # reached: within 1 % of the step, plus the payload's static sag (0.3 mm / 0.3 mrad)
        assert abs(final - target) < 0.01 * abs(step) + 3e-4, (step, final - target)
        assert abs(d.qvel[m.joint(name).dofadr[0]]) < 1e-4
        # settled within 2 % of the step by 0.6 s and stays there
        outside = np.nonzero(np.abs(q - final) > 0.02 * abs(step))[0]
        assert len(outside) == 0 or t[outside[-1]] < 0.6, (step, t[outside[-1]])
        if step == small:
            overshoot = np.max((q - final) * np.sign(step)) / abs(final - q0)
            assert overshoot < 0.05, f"{name}: {overshoot:.1%} overshoot in the linear range"


# -- sensors -----------------------------------------------------------------------------


def _ft_world(m: mujoco.MjModel, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    r = d.site_xmat[m.site("ft_frame").id].reshape(3, 3)
    return r @ d.sensor("ft_frame_force").data, r @ d.sensor("ft_frame_torque").data


def test_ft_sensor_reads_the_weight_of_what_hangs_below_it(model):
    m = model
    assert m.sensor("ft_frame_force").type[0] == mujoco.mjtSensor.mjSENS_FORCE
    assert m.sensor("ft_frame_torque").type[0] == mujoco.mjtSensor.mjSENS_TORQUE
    site = m.site("ft_frame")
    assert m.body(site.bodyid[0]).name == "ft_frame"
    payload = _subtree_mass(m, "ft_frame")
    assert payload == pytest.approx(0.3 + 0.86 + 2 * 0.05 + 0.072), (
        "tool adapter, gripper, fingers, wrist camera"
    )
    weight = payload * -m.opt.gravity[2]
    # tool down (home), then tool horizontal: the wrench the arm holds the gripper with
    for wrist in ({}, {"wrist_3_joint": 0.0}, {"wrist_1_joint": -2.0}):
        d = mujoco.MjData(m)
        _pose(m, d, wrist)
        while d.time < 1.5:
            mujoco.mj_step(m, d)
        force, _ = _ft_world(m, d)
        assert np.linalg.norm(force) == pytest.approx(weight, rel=0.01), wrist
        np.testing.assert_allclose(force, [0, 0, weight], atol=0.01 * weight)


def test_cameras_are_640x480_with_58_deg_vertical_fov_and_look_where_mounted(model):
    m = model
    d = _home(m)
    for name in ("wrist_camera_optical_frame", "lift_camera_optical_frame"):
        cam = m.camera(name)
        assert tuple(m.cam_resolution[cam.id]) == (640, 480)
        assert cam.fovy[0] == pytest.approx(58.0, abs=1e-6)
        assert m.body(cam.bodyid[0]).name == name, "on the ROS optical frame"
    # MuJoCo cameras look along -z; the published mounts: the wrist camera 8 deg off the
    # tool axis (pitch -1.429 rad), the lift camera level along +y (yaw 1.588 rad)
    wrist = -d.cam_xmat[m.camera("wrist_camera_optical_frame").id].reshape(3, 3)[:, 2]
    _, r_tool = _frame(d, m, "tool0")
    assert math.degrees(math.acos(wrist @ r_tool[:, 2])) < 10, "along the tool axis"
    lift = -d.cam_xmat[m.camera("lift_camera_optical_frame").id].reshape(3, 3)[:, 2]
    np.testing.assert_allclose(lift, _rpy(-3.0512, -0.0276, 1.5884)[:, 0], atol=1e-9)


@pytest.mark.parametrize("camera", ["wrist_camera_optical_frame", "lift_camera_optical_frame"])
def test_cameras_render_rgb_and_depth_headlessly(converted, gl_context, camera):
    m = mujoco.MjModel.from_xml_path(str(converted.with_name("scene.xml")))
    d = _home(m)
    with mujoco.Renderer(m, 480, 640) as r:
        r.update_scene(d, camera=camera)
        rgb = r.render()
        r.enable_depth_rendering()
        r.update_scene(d, camera=camera)
        depth = r.render()
    assert rgb.shape == (480, 640, 3) and depth.shape == (480, 640)
    assert rgb.std() > 5, "an image, not a blank"
    # both look level at home: a pixel near the bottom or the top edge of the depth image
    # sees the floor, at the depth (along the optical axis) a ray cast by MuJoCo finds
    cam = m.camera(camera).id
    rot = d.cam_xmat[cam].reshape(3, 3)
    f = 240 / math.tan(math.radians(29))
    hit = np.zeros(1, np.int32)
    visible = np.array([1, 1, 1, 0, 0, 0], np.uint8)
    housing = m.body(camera.replace("_optical_frame", "_link")).id  # behind the optical frame
    seen = []
    for row in (460, 19):
        ray = rot @ np.array([(320.5 - 320) / f, -(row + 0.5 - 240) / f, -1.0])
        distance = mujoco.mj_ray(m, d, d.cam_xpos[cam], ray, visible, 1, housing, hit)
        # in units of the ray: the depth along the optical axis; nearer than the near
        # clip (0.1 m) is the gripper's own fingers
        if 0.1 < distance < 10.0:
            seen.append(row)
            assert float(depth[row, 320]) == pytest.approx(distance, rel=0.01)
    assert seen, "the floor in view"


# -- the gripper ---------------------------------------------------------------------------


def test_finger_pads_grip_and_meet_at_the_grasp_frame(model):
    m = model
    d = mujoco.MjData(m)
    for opening in (0.0, 0.0125, 0.025):
        _pose(m, d, {"finger_1_joint": opening})
        p_grasp, r_grasp = _frame(d, m, "grasp_frame")
        pads = [m.geom(f"finger_{n}_pad") for n in (1, 2)]
        centres = [d.geom_xpos[p.id] for p in pads]
        np.testing.assert_allclose((centres[0] + centres[1]) / 2, p_grasp, atol=1e-9)
        gap = np.linalg.norm(centres[0] - centres[1]) - 2 * pads[0].size[1]
        assert gap == pytest.approx(2 * (0.001 + opening), abs=1e-9)
        # pads face each other across the gripper's y axis, which is tool0's x (the real
        # Hand-E's fingers open along tool0's x)
        across = (centres[0] - centres[1]) / np.linalg.norm(centres[0] - centres[1])
        np.testing.assert_allclose(across, r_grasp[:, 1], atol=1e-9)
        _, r_tool = _frame(d, m, "tool0")
        assert abs(across @ r_tool[:, 0]) == pytest.approx(1.0, abs=1e-9)
    for pad in pads:
        assert 2 * pad.size[0] > 0.03, "wider than a 3 cm handle strap"
        assert pad.friction[0] == pytest.approx(1.5) and pad.condim[0] == 4
        assert pad.priority[0] == 1, "the pad's contact parameters win"
        np.testing.assert_allclose(pad.solref, [0.004, 1])


def test_grasps_and_lifts_a_bag_handle_strap(converted):
    """A 3 cm wide, 6 mm thick strap carrying the CTB's 1.8 kg, between the pads: the
    gripper closes on it and the lift raises it 0.2 m; the strap neither drops nor slips
    (the standalone's options: elliptic cones, impratio 10, as the facility's)."""
    m0 = mujoco.MjModel.from_xml_path(str(converted))
    d0 = _home(m0)
    p_grasp, r_grasp = _frame(d0, m0, "grasp_frame")
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, r_grasp.flatten())

    spec = mujoco.MjSpec.from_file(str(converted))
    strap = spec.worldbody.add_body(name="strap", pos=p_grasp, quat=quat)
    strap.add_freejoint(name="strap")
    strap.explicitinertial = True
    strap.mass, strap.ipos = 1.8, [0, 0, 0.02]
    strap.inertia = [0.0015, 0.0015, 0.0002]
    strap.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.015, 0.003, 0.05], pos=[0, 0, 0.02])
    key = spec.key("home")
    key.qpos = list(key.qpos) + list(p_grasp) + list(quat)
    m = spec.compile()
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    # fingers 0.5 mm clear of the strap, then closed on it
    for finger in ("finger_1_joint", "finger_2_joint"):
        d.qpos[m.joint(finger).qposadr[0]] = 0.0025
    d.ctrl[m.actuator("finger_1_joint").id] = 0.0
    mujoco.mj_forward(m, d)

    def strap_in_grasp() -> np.ndarray:
        p, r = _frame(d, m, "grasp_frame")
        return r.T @ (d.body("strap").xpos - p)

    while d.time < 0.5:
        mujoco.mj_step(m, d)
    held = strap_in_grasp()
    assert np.linalg.norm(held) < 5e-4, "caught within 0.5 mm of the grasp frame"
    # pads on the strap (0.5 mm into the soft contact), squeezing with over 100 N
    assert _q(m, d, "finger_1_joint") == pytest.approx(0.0015, abs=2e-4)
    assert d.actuator("finger_1_joint").force[0] < -100
    z0 = d.body("strap").xpos[2]
    d.ctrl[m.actuator("lift").id] = 0.2
    while d.time < 3.0:
        mujoco.mj_step(m, d)
    _no_warnings(d)
    assert d.body("strap").xpos[2] - z0 == pytest.approx(0.2, abs=0.002)
    assert np.linalg.norm(strap_in_grasp() - held) < 5e-4, "no slip"
