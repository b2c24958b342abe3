"""``urdf2mjcf serve BUNDLE --ros2`` of an iMETRO bundle: the robot and every mockup's
joints in /joint_states (the digital twin a planner keeps current), as the bundle's
compiled scene has them, through the real command."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh")

from tests.ros2.test_serve_e2e import Served, _free_port, _last, _session, _tokens  # noqa: E402


@pytest.fixture(scope="module")
def imetro(shipped_bundle) -> Path:
    return shipped_bundle("imetro-compact")


def test_the_robot_and_the_mockups_joints_are_served(imetro):
    m = mujoco.MjModel.from_xml_path(str(imetro / "scene.xml"))
    one_dof = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
    expected = [
        m.joint(j).name for j in range(m.njnt) if m.jnt_type[j] in [int(t) for t in one_dof]
    ]
    s = Served(imetro, _free_port())
    client = _session(s.port)
    try:
        assert [t[8] for t in _tokens(client) if t[5] == "NN"] == ["ros2_control_node"]
        js = _last(client, "/joint_states", "sensor_msgs/msg/JointState")
        tf = _last(client, "/tf", "tf2_msgs/msg/TFMessage")
    finally:
        client.close()
        s.stop()
    assert list(js.name) == expected
    assert {"rail", "shoulder_pan_joint", "trainer_lid_joint", "hatch_4060_door_joint"} <= set(
        js.name
    )
    # at rest in the home keyframe: the mockups' doors where the bundle put them
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    door = m.joint("hatch_4060_door_joint")
    assert js.position[list(js.name).index("hatch_4060_door_joint")] == pytest.approx(
        d.qpos[door.qposadr[0]], abs=0.02
    )
    # the CTB is free: its pose is on /tf, from the world
    ctb = [t for t in tf.transforms if t.child_frame_id == "ctb"]
    assert ctb and ctb[0].header.frame_id == "world"
    assert np.isfinite(ctb[0].transform.translation.z)
