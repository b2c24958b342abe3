"""Actuators pass: ros2_control, transmissions and the actuator file become MuJoCo
actuators whose default gains hold a robot under gravity; checked in simulation."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.api import robot_tree  # emit's document, as the pipeline hands it over
from urdf2mjcf.errors import InputError, URDFError
from urdf2mjcf.ir import Model
from urdf2mjcf.passes import collision, emit, inertia, meshes, parse, xacro
from urdf2mjcf.passes.actuators import ActuatorConfig, run

THETA_TOL = ActuatorConfig().sag_tolerance


# --- URDF snippets -----------------------------------------------------------------------------


def rod(name: str, mass: float, length: float = 0.4, radius: float = 0.02) -> str:
    """A solid cylinder of ``length`` along +x from the link origin."""
    ixx = mass * radius**2 / 2
    iyy = mass * (3 * radius**2 + length**2) / 12
    return f"""
  <link name="{name}">
    <inertial><origin xyz="{length / 2} 0 0"/><mass value="{mass}"/>
      <inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{iyy}"/></inertial>
    <collision><origin xyz="{length / 2} 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="{radius}" length="{length}"/></geometry></collision>
  </link>"""


def block(name: str, mass: float, size: float = 0.05, collide: bool = True) -> str:
    i = mass * size**2 / 6
    shape = f'<geometry><box size="{size} {size} {size}"/></geometry>'
    geom = f"<collision>{shape}</collision>" if collide else f"<visual>{shape}</visual>"
    return f"""
  <link name="{name}">
    <inertial><mass value="{mass}"/><inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial>
    {geom}
  </link>"""


def joint(name, jtype, parent, child, xyz="0 0 0", axis="0 1 0", limit="", extra="") -> str:
    return f"""
  <joint name="{name}" type="{jtype}"><parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{xyz}"/><axis xyz="{axis}"/>{limit}{extra}</joint>"""


def limit(lower=None, upper=None, effort=None, velocity=None) -> str:
    attrs = {"lower": lower, "upper": upper, "effort": effort, "velocity": velocity}
    return "<limit " + " ".join(f'{k}="{v}"' for k, v in attrs.items() if v is not None) + "/>"


def ros2_control(*joints: str, plugin: str = "mock_components/GenericSystem") -> str:
    return f"""
  <ros2_control name="system" type="system">
    <hardware><plugin>{plugin}</plugin><param name="calculate_dynamics">true</param></hardware>
    {"".join(joints)}
    <sensor name="ft"><state_interface name="force.x"/><param name="frame_id">tool0</param></sensor>
  </ros2_control>"""


def rc_joint(name: str, *interfaces: str, params: str = "", inner: str = "") -> str:
    cis = "".join(
        f'<command_interface name="{ci}">{inner if k == 0 else ""}</command_interface>'
        for k, ci in enumerate(interfaces)
    )
    return (
        f'<joint name="{name}">{cis}<state_interface name="position"/>'
        f'<state_interface name="velocity"/>{params}</joint>'
    )


def param(name: str, value) -> str:
    return f'<param name="{name}">{value}</param>'


def robot(*parts: str) -> str:
    return '<robot name="r">\n  <link name="world"/>' + "".join(parts) + "\n</robot>\n"


BASE = joint("mount", "fixed", "world", "base_link", xyz="0 0 0.5") + block(
    "base_link", 5.0, 0.2, collide=False
)  # no collision geometry: a base welded to the world would collide with everything on it


def two_link_arm(control: str = "") -> str:
    """Shoulder and elbow about y; at zero both links point along +x (horizontal)."""
    return robot(
        BASE,
        joint("shoulder", "revolute", "base_link", "link1", xyz="0 0 0.15",
              limit=limit(-2, 2, effort=100, velocity=2)),
        rod("link1", 2.0),
        joint("elbow", "revolute", "link1", "link2", xyz="0.4 0 0",
              limit=limit(-2.5, 2.5, effort=50, velocity=2)),
        rod("link2", 1.5),
        control,
    )  # fmt: skip


ARM_CONTROL = ros2_control(rc_joint("shoulder", "position"), rc_joint("elbow", "position"))


def gripper(control: str) -> str:
    """Two prismatic fingers on a fixed palm; finger_b mimics finger_a."""
    fingers = ""
    for side, sign in (("a", 1), ("b", -1)):
        mimic = '<mimic joint="finger_a" multiplier="1" offset="0"/>' if side == "b" else ""
        fingers += joint(f"finger_{side}", "prismatic", "base_link", f"link_{side}",
                         xyz=f"0 {sign * 0.03} 0", axis=f"0 {sign} 0",
                         limit=limit(0, 0.04, effort=40, velocity=0.2), extra=mimic)  # fmt: skip
        fingers += block(f"link_{side}", 0.1, 0.02)
    return robot(BASE, fingers, control)


# --- running the passes ------------------------------------------------------------------------


def upstream(tmp_path: Path, urdf: str) -> Model:
    path = tmp_path / "robot.urdf"
    path.write_text(urdf)
    doc = xacro.run(path, xacro.XacroConfig(use_environment=False))
    model = meshes.run(parse.run(doc), meshes.MeshConfig())
    model = collision.run(model, collision.CollisionConfig())
    return inertia.run(model, inertia.InertiaConfig())


def convert(tmp_path: Path, urdf: str, yaml_text: str | None = None, **cfg) -> Model:
    if yaml_text is not None:
        cfg["config_file"] = tmp_path / "actuators.yaml"
        cfg["config_file"].write_text(yaml_text)
    return run(upstream(tmp_path, urdf), ActuatorConfig(**cfg), robot_tree)


def compile_model(model: Model) -> tuple[mujoco.MjModel, mujoco.MjData, str]:
    res = emit.run(model, emit.EmitConfig())
    xml = res.xml.decode()
    m = mujoco.MjModel.from_xml_string(xml, dict(res.files))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    for i in range(m.nu):  # servos start at the home pose
        if m.actuator_biastype[i] == mujoco.mjtBias.mjBIAS_AFFINE:
            d.ctrl[i] = d.qpos[m.jnt_qposadr[m.actuator_trnid[i, 0]]]
    mujoco.mj_forward(m, d)
    return m, d, xml


def actuator_map(model: Model):
    return {a.joint: a for a in model.actuators}


def messages(model: Model, kind: str) -> list[str]:
    return [f"{n.element}: {n.message}" for n in model.notes if n.kind == kind]


def simulate(m, d, seconds: float, qadr: int) -> np.ndarray:
    trace = []
    for _ in range(int(round(seconds / m.opt.timestep))):
        mujoco.mj_step(m, d)
        trace.append(d.qpos[qadr])
    return np.array(trace)


# --- mapping: ros2_control ---------------------------------------------------------------------


def three_joint_robot(control: str) -> str:
    return robot(
        BASE,
        joint("pos", "revolute", "base_link", "l1", axis="0 0 1", limit=limit(-1.5, 1.5, 30, 2)),
        rod("l1", 1.0, 0.2),
        joint("vel", "continuous", "l1", "l2", xyz="0.2 0 0", axis="0 0 1", limit=limit(effort=20, velocity=3)),
        rod("l2", 0.5, 0.2),
        joint("eff", "prismatic", "l2", "l3", xyz="0.2 0 0", axis="1 0 0", limit=limit(0, 0.1, 15, 0.5)),
        block("l3", 0.2),
        control,
    )  # fmt: skip


def test_each_command_interface_maps_to_its_actuator_type_with_ranges_from_the_limits(tmp_path):
    control = ros2_control(
        rc_joint("pos", "position"), rc_joint("vel", "velocity"), rc_joint("eff", "effort")
    )
    model = convert(tmp_path, three_joint_robot(control))
    acts = actuator_map(model)
    assert [a.joint for a in model.actuators] == ["pos", "vel", "eff"], "URDF joint order"
    assert (acts["pos"].kind, acts["pos"].ctrlrange, acts["pos"].forcerange) == (
        "position", (-1.5, 1.5), (-30.0, 30.0)
    )  # fmt: skip
    assert (acts["vel"].kind, acts["vel"].ctrlrange, acts["vel"].forcerange) == (
        "velocity", (-3.0, 3.0), (-20.0, 20.0)
    )  # fmt: skip
    assert (acts["eff"].kind, acts["eff"].ctrlrange, acts["eff"].forcerange) == (
        "motor", (-15.0, 15.0), None
    )  # fmt: skip
    assert acts["pos"].kp > 0 and acts["pos"].kv > 0 and acts["vel"].kv > 0
    assert acts["eff"].kp is None and acts["eff"].kv is None

    m, _, _ = compile_model(model)
    pos, vel, eff = (m.actuator(n) for n in ("pos", "vel", "eff"))
    assert pos.biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE
    assert pos.gainprm[0] == pytest.approx(acts["pos"].kp)
    assert pos.biasprm[1:3] == pytest.approx([-acts["pos"].kp, -acts["pos"].kv])
    assert vel.biasprm[2] == pytest.approx(-acts["vel"].kv) and vel.biasprm[1] == 0
    assert eff.biastype[0] == mujoco.mjtBias.mjBIAS_NONE and eff.gainprm[0] == 1
    np.testing.assert_allclose(eff.ctrlrange, [-15, 15])
    assert m.actuator_forcelimited[eff.id] == 0


def test_continuous_joint_position_servo_has_no_ctrlrange(tmp_path):
    model = convert(tmp_path, three_joint_robot(ros2_control(rc_joint("vel", "position"))))
    assert actuator_map(model)["vel"].ctrlrange is None
    assert actuator_map(model)["vel"].forcerange == (-20.0, 20.0)


def test_several_command_interfaces_prefer_position_then_velocity_then_effort(tmp_path):
    control = ros2_control(
        rc_joint("pos", "effort", "velocity", "position"),
        rc_joint("vel", "effort", "velocity"),
    )
    acts = actuator_map(convert(tmp_path, three_joint_robot(control)))
    assert (acts["pos"].kind, acts["vel"].kind) == ("position", "velocity")
    assert "eff" not in acts, "a joint not in ros2_control gets no actuator"


def test_joint_params_override_the_defaults(tmp_path):
    params = "".join(
        param(k, v)
        for k, v in {"kp": 120, "kd": 7, "armature": 0.05, "damping": 1.5, "friction": 0.3,
                     "force_limit": 12}.items()
    )  # fmt: skip
    inner = param("min", -0.5) + param("max", 0.75)
    control = ros2_control(
        rc_joint("pos", "position", params=params, inner=inner),
        rc_joint("vel", "velocity", params=param("d", 4) + param("max_effort", 9)),
    )
    model = convert(tmp_path, three_joint_robot(control))
    acts = actuator_map(model)
    assert (acts["pos"].kp, acts["pos"].kv) == (120.0, 7.0)
    assert acts["pos"].ctrlrange == (-0.5, 0.75) and acts["pos"].forcerange == (-12.0, 12.0)
    assert (acts["vel"].kv, acts["vel"].forcerange) == (4.0, (-9.0, 9.0))
    tuning = model.joint_tuning["pos"]
    assert (tuning.armature, tuning.damping, tuning.frictionloss) == (0.05, 1.5, 0.3)
    m, _, _ = compile_model(model)
    j = m.joint("pos")
    assert (m.dof_armature[j.dofadr[0]], m.dof_damping[j.dofadr[0]]) == (0.05, 1.5)
    assert m.dof_frictionloss[j.dofadr[0]] == 0.3


def test_only_min_given_completes_the_command_range_from_the_joint_limit(tmp_path):
    control = ros2_control(rc_joint("pos", "position", inner=param("min", -1)))
    assert actuator_map(convert(tmp_path, three_joint_robot(control)))["pos"].ctrlrange == (-1, 1.5)


def test_bad_param_number_raises_urdf_error_naming_the_joint(tmp_path):
    control = ros2_control(rc_joint("pos", "position", params=param("kp", "${kp}")))
    with pytest.raises(URDFError, match=r"joint 'pos'.*'kp'"):
        convert(tmp_path, three_joint_robot(control))


def test_unknown_fixed_and_state_only_joints_get_no_actuator(tmp_path):
    control = ros2_control(
        rc_joint("ghost", "position"),
        rc_joint("mount", "position"),
        '<joint name="pos"><state_interface name="position"/></joint>',
        rc_joint("vel", "velocity"),
    )
    model = convert(tmp_path, three_joint_robot(control))
    assert list(actuator_map(model)) == ["vel"]
    warnings = messages(model, "warning")
    assert any("'ghost'" in w and "not in the URDF" in w for w in warnings)
    assert any("'mount'" in w and "fixed" in w for w in warnings)


# --- mapping: transmissions --------------------------------------------------------------------


def transmission(joint_name: str, interface: str, on_actuator: bool = False, reduction=1) -> str:
    hw = f"<hardwareInterface>{interface}</hardwareInterface>"
    return f"""
  <transmission name="t_{joint_name}"><type>transmission_interface/SimpleTransmission</type>
    <joint name="{joint_name}">{"" if on_actuator else hw}</joint>
    <actuator name="m_{joint_name}">{hw if on_actuator else ""}<mechanicalReduction>{reduction}</mechanicalReduction></actuator>
  </transmission>"""


def test_ros1_transmissions_map_hardware_interfaces_with_or_without_prefix(tmp_path):
    tags = (
        transmission("pos", "hardware_interface/PositionJointInterface")
        + transmission("vel", "VelocityJointInterface", on_actuator=True)
        + transmission("eff", "hardware_interface/EffortJointInterface", reduction=50)
    )
    model = convert(tmp_path, three_joint_robot(tags))
    acts = actuator_map(model)
    assert {n: a.kind for n, a in acts.items()} == {
        "pos": "position",
        "vel": "velocity",
        "eff": "motor",
    }
    assert any("mechanicalReduction 50 ignored" in n for n in messages(model, "info"))
    assert compile_model(model)[0].nu == 3


def test_pr2_style_transmission_without_interface_is_an_effort_actuator(tmp_path):
    tags = """
  <transmission type="pr2_mechanism_model/SimpleTransmission" name="t">
    <actuator name="m"/><joint name="pos"/><mechanicalReduction>1</mechanicalReduction>
  </transmission>"""
    model = convert(tmp_path, three_joint_robot(tags))
    assert actuator_map(model)["pos"].kind == "motor"
    assert any("PR2 style" in n for n in messages(model, "info"))


def test_ros2_control_wins_over_a_transmission_for_the_same_joint(tmp_path):
    tags = transmission("pos", "EffortJointInterface") + ros2_control(rc_joint("pos", "position"))
    model = convert(tmp_path, three_joint_robot(tags))
    assert actuator_map(model)["pos"].kind == "position"


# --- the actuator file -------------------------------------------------------------------------

ARM_YAML = """
classes:
  big: {kp: 2500, kv: 150, forcerange: 90, armature: 0.1, damping: 2}
joints:
  shoulder: {class: big}
  "elb*": {type: position, kp: 900}
gravcomp: ["link1"]
"""


def test_actuator_file_overrides_urdf_params_and_classes_become_default_classes(tmp_path):
    control = ros2_control(
        rc_joint("shoulder", "position", params=param("kp", 10) + param("force_limit", 5)),
        rc_joint("elbow", "velocity"),
    )
    model = convert(tmp_path, two_link_arm(control), ARM_YAML)
    acts = actuator_map(model)
    sh, el = acts["shoulder"], acts["elbow"]
    assert (sh.kp, sh.kv, sh.forcerange, sh.actuator_class) == (2500.0, 150.0, (-90.0, 90.0), "big")
    assert (el.kind, el.kp, el.actuator_class) == ("position", 900.0, None), "the file's type wins"
    assert el.kv > 0, "kv completed for the given kp"
    assert model.joint_tuning["shoulder"].armature == 0.1
    assert dict(model.gravcomp) == {"link1": 1.0}

    m, _, xml = compile_model(model)
    assert '<default class="big">' in xml and '<position kp="2500" kv="150"' in xml
    a = m.actuator("shoulder")
    assert a.gainprm[0] == 2500 and a.biasprm[2] == -150
    np.testing.assert_allclose(a.forcerange, [-90, 90])
    assert m.dof_armature[m.joint("shoulder").dofadr[0]] == 0.1
    assert (m.body_gravcomp[m.body("link1").id], m.body_gravcomp[m.body("link2").id]) == (1.0, 0.0)


def test_actuator_file_adds_actuators_to_a_robot_without_ros2_control(tmp_path):
    model = convert(tmp_path, two_link_arm(), 'joints: {"*": {type: position}}\n')
    assert [a.joint for a in model.actuators] == ["shoulder", "elbow"], "the fixed mount is skipped"
    assert all(a.kind == "position" and a.kp > 0 for a in model.actuators)


def test_type_none_in_the_file_removes_a_ros2_control_actuator_but_keeps_tuning(tmp_path):
    yaml_text = "joints:\n  elbow: {type: none, damping: 3}\n"
    model = convert(tmp_path, two_link_arm(ARM_CONTROL), yaml_text)
    assert list(actuator_map(model)) == ["shoulder"]
    assert model.joint_tuning["elbow"].damping == 3


def test_later_file_entries_override_earlier_ones_key_by_key(tmp_path):
    yaml_text = 'joints:\n  "*": {kp: 100, kv: 5}\n  elbow: {kp: 300}\n'
    acts = actuator_map(convert(tmp_path, two_link_arm(), yaml_text))
    assert (acts["shoulder"].kp, acts["elbow"].kp, acts["elbow"].kv) == (100, 300, 5)


def test_file_pattern_matching_no_joint_is_a_warning(tmp_path):
    model = convert(tmp_path, two_link_arm(ARM_CONTROL), 'joints:\n  "wrist_*": {kp: 1}\n')
    assert any("'wrist_*' matches no joint" in w for w in messages(model, "warning"))
    assert len(model.actuators) == 2


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("joints: {shoulder: {kp: 1}\n", "not valid YAML at line"),
        ("joint: {}\n", r"unknown key 'joint'"),
        ("joints: {shoulder: {kpp: 1}}\n", r"joints: shoulder: unknown key 'kpp'"),
        ("joints: {shoulder: {kp: -1}}\n", r"joints: shoulder: kp: must be >= 0"),
        ("joints: {shoulder: {kp: fast}}\n", r"kp: expected a number"),
        ("joints: {shoulder: {type: servo}}\n", r"type: unknown type 'servo'"),
        ("joints: {shoulder: {class: huge}}\n", r"unknown class 'huge'"),
        ("joints: {shoulder: {ctrlrange: [1, 0]}}\n", r"ctrlrange: expected lo < hi"),
        ("classes: {visual: {kp: 1}}\n", r"class name 'visual' is reserved"),
        ("gravcomp: {link1: 2}\n", r"gravcomp: link1: fraction must be in \[0, 1\]"),
        ("- just a list\n", "expected a mapping"),
    ],
)
def test_bad_actuator_file_raises_input_error_naming_the_file_and_key(tmp_path, text, match):
    with pytest.raises(InputError, match=match) as info:
        convert(tmp_path, two_link_arm(), text)
    assert info.value.file == str(tmp_path / "actuators.yaml")


def test_missing_actuator_file_raises_input_error(tmp_path):
    with pytest.raises(InputError, match="cannot read actuator file"):
        convert(tmp_path, two_link_arm(), config_file=tmp_path / "nope.yaml")


def test_numbers_written_like_1e5_are_accepted(tmp_path):
    acts = actuator_map(
        convert(tmp_path, two_link_arm(ARM_CONTROL), "joints: {shoulder: {kp: 1e5}}")
    )
    assert acts["shoulder"].kp == 1e5


# --- mimic joints ------------------------------------------------------------------------------


def test_mimic_follower_gets_no_actuator_and_the_pair_is_driven_by_one(tmp_path):
    control = ros2_control(rc_joint("finger_a", "position"), rc_joint("finger_b", "position"))
    model = convert(tmp_path, gripper(control))
    assert [a.joint for a in model.actuators] == ["finger_a"]
    assert any("'finger_b'" in n and "mimics 'finger_a'" in n for n in messages(model, "info"))

    m, d, _ = compile_model(model)
    a, b = (m.joint(n).qposadr[0] for n in ("finger_a", "finger_b"))
    d.ctrl[m.actuator("finger_a").id] = 0.03
    simulate(m, d, 1.0, a)
    assert d.qpos[a] == pytest.approx(0.03, abs=3e-4)
    assert d.qpos[b] == pytest.approx(d.qpos[a], abs=2e-4), "the follower follows its leader"


def test_mimic_leader_gains_count_the_followers_inertia(tmp_path):
    control = ros2_control(rc_joint("finger_a", "position"))
    model = convert(tmp_path, gripper(control))
    # Horizontal fingers: no gravity load, so kp comes from the bandwidth on both fingers' mass.
    omega = 2 * math.pi * ActuatorConfig().bandwidth_hz
    kp = actuator_map(model)["finger_a"].kp
    assert kp == pytest.approx(0.2 * omega**2, rel=0.01)


def test_design_defaults_in_the_file_replace_the_config(tmp_path):
    yaml_text = "defaults: {bandwidth_hz: 20}\n"
    model = convert(tmp_path, gripper(ros2_control(rc_joint("finger_a", "position"))), yaml_text)
    assert actuator_map(model)["finger_a"].kp == pytest.approx(
        0.2 * (2 * math.pi * 20) ** 2, rel=0.01
    )


# --- default gains: the documented formulas ----------------------------------------------------


def pendulum(length: float, mass: float = 1.0, damping: float = 0.0) -> str:
    dyn = f'<dynamics damping="{damping}"/>' if damping else ""
    return robot(
        BASE,
        joint("hinge", "revolute", "base_link", "bob", limit=limit(-3, 3, 1000, 2), extra=dyn),
        rod("bob", mass, length, radius=0.005),
        ros2_control(rc_joint("hinge", "position")),
    )


def round_up_3(x: float) -> float:
    e = math.floor(math.log10(x)) - 2
    return math.ceil(x / 10**e - 1e-9) * 10**e


@pytest.mark.parametrize(("length", "damping"), [(0.5, 0.0), (0.5, 3.0), (0.05, 0.0)])
def test_single_joint_default_gains_follow_the_documented_formulas(tmp_path, length, damping):
    mass, radius = 1.0, 0.005
    model = convert(tmp_path, pendulum(length, mass, damping))
    inertia_about_pivot = mass * (3 * radius**2 + length**2) / 12 + mass * (length / 2) ** 2
    omega = 2 * math.pi * ActuatorConfig().bandwidth_hz
    load = mass * 9.81 * length / 2  # worst case: the rod horizontal
    kp = round_up_3(max(inertia_about_pivot * omega**2, load / THETA_TOL))
    kv = max(0.0, 2 * math.sqrt(kp * inertia_about_pivot) - damping)
    a = actuator_map(model)["hinge"]
    assert a.kp == pytest.approx(kp, rel=1e-9)
    assert a.kv == pytest.approx(kv, rel=5e-3)
    assert np.sqrt(a.kp / inertia_about_pivot) * 0.002 <= ActuatorConfig().max_omega_dt


def test_tiny_heavy_link_kp_is_limited_for_stability_and_the_warned_sag_is_what_happens(tmp_path):
    # 2 kg on 2 cm: holding it within 0.002 rad would need omega*dt > 1 at the 2 ms step.
    mass, length = 2.0, 0.02
    model = convert(tmp_path, pendulum(length, mass))
    kp = actuator_map(model)["hinge"].kp
    expected = mass * 9.81 * (length / 2) / kp
    assert expected > THETA_TOL
    assert any(
        "limited to" in w and f"expected sag {expected:.3g} rad" in w
        for w in messages(model, "warning")
    )
    m, d, _ = compile_model(model)
    trace = simulate(m, d, 2.0, m.joint("hinge").qposadr[0])
    assert np.all(np.isfinite(trace)) and not any(w.number for w in d.warning)
    assert trace[-1] == pytest.approx(expected, rel=0.01)
    assert np.abs(trace).max() <= 1.05 * expected


# --- default gains in simulation: a 2-link arm under gravity ----------------------------------


@pytest.fixture
def arm(tmp_path) -> tuple[Model, mujoco.MjModel, mujoco.MjData]:
    model = convert(tmp_path, two_link_arm(ARM_CONTROL))
    m, d, _ = compile_model(model)
    return model, m, d


def test_two_link_arm_holds_its_home_pose_under_gravity_within_the_sag_tolerance(arm):
    model, m, d = arm
    assert not messages(model, "warning")
    adr = [m.joint(n).qposadr[0] for n in ("shoulder", "elbow")]
    home = d.qpos[adr].copy()
    worst = np.zeros(2)
    for _ in range(int(3.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        worst = np.maximum(worst, np.abs(d.qpos[adr] - home))
    sag = np.abs(d.qpos[adr] - home)
    assert np.all(sag <= THETA_TOL), f"static sag {sag} rad"
    assert np.all(sag > 0.2 * THETA_TOL), "the arm is loaded: gravity does sag it"
    assert np.all(worst <= 1.05 * THETA_TOL), f"transient sag {worst} rad"
    assert np.abs(d.qvel).max() < 1e-6, "at rest: no divergence, no drift"
    assert not any(w.number for w in d.warning)


@pytest.mark.parametrize("name", ["shoulder", "elbow"])
@pytest.mark.parametrize("step", [0.2, -0.2])
def test_two_link_arm_step_command_settles_without_overshoot(arm, name, step):
    _, m, d = arm
    qadr = m.joint(name).qposadr[0]
    target = d.qpos[qadr] + step
    d.ctrl[m.actuator(name).id] = target
    trace = simulate(m, d, 2.0, qadr)
    final = trace[-1]
    assert abs(final - target) <= THETA_TOL, "settles at the target, within the sag"
    overshoot = np.max((trace - final) * np.sign(step)) / abs(step)
    assert overshoot < 0.02, f"overshoot {overshoot:.2%}"
    err = trace - final
    crossings = np.count_nonzero(np.diff(np.sign(err[np.abs(err) > 1e-3 * abs(step)])))
    assert crossings <= 1, "no oscillation"
    settle = np.argmax(np.abs(err) < 0.02 * abs(step)) * m.opt.timestep
    assert settle < 0.5, f"settles in {settle} s"


def test_gravcomp_removes_the_sag(tmp_path):
    model = convert(tmp_path, two_link_arm(ARM_CONTROL), gravcomp=True)
    assert dict(model.gravcomp) == {"link1": 1.0, "link2": 1.0}, "only links a joint moves"
    m, d, _ = compile_model(model)
    adr = [m.joint(n).qposadr[0] for n in ("shoulder", "elbow")]
    home = d.qpos[adr].copy()
    worst = 0.0
    for _ in range(int(3.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        worst = max(worst, float(np.abs(d.qpos[adr] - home).max()))
    assert worst < 1e-4


def test_gravcomp_true_in_the_file_is_the_gravcomp_option(tmp_path):
    by_file = convert(tmp_path, two_link_arm(ARM_CONTROL), "gravcomp: true\n")
    by_option = convert(tmp_path, two_link_arm(ARM_CONTROL), gravcomp=True)
    assert dict(by_file.gravcomp) == dict(by_option.gravcomp) == {"link1": 1.0, "link2": 1.0}


def test_gravcomp_fractions_from_the_file_reduce_the_load_the_gains_are_sized_for(tmp_path):
    full = actuator_map(convert(tmp_path, two_link_arm(ARM_CONTROL)))
    half = convert(tmp_path, two_link_arm(ARM_CONTROL), 'gravcomp: {"link*": 0.5}\n')
    assert dict(half.gravcomp) == {"link1": 0.5, "link2": 0.5}
    assert actuator_map(half)["shoulder"].kp == pytest.approx(full["shoulder"].kp / 2, rel=0.01)


# --- velocity actuators ------------------------------------------------------------------------


def rail_and_lift() -> str:
    return robot(
        BASE,
        joint("rail", "prismatic", "base_link", "carriage", axis="1 0 0", limit=limit(-5, 5, 500, 0.5)),
        block("carriage", 10.0, 0.2),
        joint("lift", "prismatic", "carriage", "stage", axis="0 0 1", limit=limit(-1, 1, 1000, 0.5)),
        block("stage", 20.0, 0.2),
        ros2_control(rc_joint("rail", "velocity"), rc_joint("lift", "velocity")),
    )  # fmt: skip


def test_velocity_actuator_tracks_a_commanded_velocity(tmp_path):
    model = convert(tmp_path, rail_and_lift())
    m, d, _ = compile_model(model)
    rail, lift = m.joint("rail").dofadr[0], m.joint("lift").dofadr[0]
    d.ctrl[m.actuator("rail").id] = 0.2
    for _ in range(int(1.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert d.qvel[rail] == pytest.approx(0.2, rel=1e-3)
    drift = ActuatorConfig().drift_tolerance
    assert abs(d.qvel[lift]) <= drift, "a vertical velocity axis barely drifts under gravity"
    d.ctrl[m.actuator("lift").id] = -0.1
    for _ in range(int(1.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    assert d.qvel[lift] == pytest.approx(-0.1, abs=drift)


# --- no tags -----------------------------------------------------------------------------------


def test_robot_without_control_tags_or_options_is_returned_unchanged(tmp_path):
    model = upstream(tmp_path, two_link_arm())
    assert run(model, ActuatorConfig(), robot_tree) is model
    assert compile_model(model)[0].nu == 0
