"""Building blocks of the demo runner, each against known answers:
segmentation and back-projection on a rendered red strap, the hinge arc, the IK."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from urdf2mjcf.runner import ik, perception
from urdf2mjcf.runner.hinge import arc, hinge_axis

STRAP = """
<mujoco>
  <visual><global offwidth="640" offheight="480"/></visual>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1"/>
    <geom type="plane" size="2 2 0.1" rgba="0.5 0.5 0.5 1"/>
    <body name="strap" pos="{x} {y} {z}" euler="0 0 {yaw}">
      <geom type="box" size="0.11 0.015 0.006" rgba="0.8 0.05 0.05 1"/>
    </body>
    <camera name="cam" pos="{cx} {cy} {cz}" euler="0 0 {cyaw}" fovy="58" resolution="640 480"/>
  </worldbody>
</mujoco>
"""


def _render(x=0.1, y=-0.05, z=0.3, yaw_deg=30.0, cam=(0.0, 0.0, 0.9), cyaw=0.0):
    xml = STRAP.format(x=x, y=y, z=z, yaw=yaw_deg, cx=cam[0], cy=cam[1], cz=cam[2], cyaw=cyaw)
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    c = perception.Camera(m, m.camera("cam").id, (480, 640))
    rgb, depth = c.rgbd(d)
    c.close()
    return m, d, rgb, depth


def test_segmentation_centroid_axis_and_backprojection(gl_context):
    x, y, z, yaw = 0.1, -0.05, 0.3, 30.0
    m, d, rgb, depth = _render(x, y, z, yaw)
    mask = perception.red_mask(rgb)
    seg = perception.segment(mask)
    assert seg is not None and seg.aspect > 4
    # known pixel: the camera looks straight down along -z, x right, y up
    f = (480 / 2) / math.tan(math.radians(58) / 2)
    top = z + 0.006
    dist = 0.9 - top
    u = 320 + f * x / dist
    v = 240 - f * y / dist
    assert abs(seg.centroid[0] - u) < 1.5 and abs(seg.centroid[1] - v) < 1.5
    # image rows grow downwards: a strap turned +30 deg in the world is at -30 deg in the image
    assert min(abs(seg.angle_deg - (180 - yaw)), abs(seg.angle_deg + yaw)) < 2.0
    g = perception.find_handle(m, d, m.camera("cam").id, rgb, depth)
    assert np.allclose(g.position, [x, y, top], atol=0.003), g.position
    assert abs(abs(math.cos(g.yaw - math.radians(yaw))) - 1) < 1e-3
    assert abs(g.depth - dist) < 0.002


def test_backprojection_of_the_image_centre_is_on_the_optical_axis(gl_context):
    m, d, _, _ = _render(cam=(0.2, 0.3, 1.0), cyaw=40.0)
    cam = m.camera("cam").id
    p = perception.backproject(m, d, cam, 320, 240, 0.5, (480, 640))
    assert np.allclose(p, [0.2, 0.3, 0.5], atol=1e-9)


def test_nothing_red_gives_no_grasp(gl_context):
    m, d, rgb, depth = _render(x=3.0)  # strap far out of view
    assert perception.find_handle(m, d, m.camera("cam").id, rgb, depth) is None


def test_grasp_rotation_fingers_across_the_strap():
    R = perception.grasp_rotation(np.array([1.0, 1.0, 0.0]) / math.sqrt(2), np.eye(3))
    assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1)
    assert np.allclose(R[:, 2], [0, 0, -1])
    assert abs(R[:, 1] @ np.array([1, 1, 0]) / math.sqrt(2)) < 1e-12  # finger axis across


HINGE = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="box" pos="0.3 -0.2 0.5" euler="0 0 0.4">
      <body name="lid">
        <joint name="lid" type="hinge" pos="0.1 0 0.2" axis="0 -1 0"/>
        <geom type="box" size="0.3 0.4 0.01" pos="0.4 0 0.2"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("hold", [True, False])
def test_hinge_arc_lies_on_the_circle_at_the_right_angles(hold):
    m = mujoco.MjModel.from_xml_string(HINGE)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    j = m.joint("lid").id
    body = m.jnt_bodyid[j]
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = d.xmat[body].reshape(3, 3), d.xpos[body]
    anchor, axis = hinge_axis(m, j, pose)
    # MuJoCo's own world anchor and axis of the joint for the body at that pose
    assert np.allclose(anchor, d.xanchor[j]) and np.allclose(axis, d.xaxis[j])
    R0 = d.xmat[m.body("box").id].reshape(3, 3)
    assert np.allclose(axis, R0 @ [0, -1, 0]) and np.allclose(
        anchor, [0.3, -0.2, 0.5] + R0 @ [0.1, 0, 0.2]
    )
    start = anchor + R0 @ np.array([0.7, 0.05, -0.02])
    rot = np.eye(3)
    poses = arc(anchor, axis, start, rot, steps=8, step_deg=11.5, hold_orientation=hold)
    assert len(poses) == 8
    r0 = start - anchor
    radial0 = r0 - (r0 @ axis) * axis
    for k, (ang, p, R) in enumerate(poses, 1):
        assert ang == pytest.approx(math.radians(11.5 * k))
        r = p - anchor
        assert r @ axis == pytest.approx(r0 @ axis)  # same plane across the axis
        radial = r - (r @ axis) * axis
        assert np.linalg.norm(radial) == pytest.approx(np.linalg.norm(radial0))  # on the circle
        c = np.dot(radial, radial0) / np.linalg.norm(radial0) ** 2
        s = np.dot(np.cross(radial0, radial), axis) / np.linalg.norm(radial0) ** 2
        assert math.atan2(s, c) == pytest.approx(ang)  # right-handed about the axis
        assert np.allclose(R, rot if hold else Rotation.from_rotvec(ang * axis).as_matrix() @ rot)
    # turning the lid joint by the same angle carries the start point onto the arc
    d.qpos[0] = poses[-1][0]
    mujoco.mj_forward(m, d)
    lid = m.body("lid").id
    local = d.xmat[lid].reshape(3, 3).T @ (poses[-1][1] - d.xpos[lid])
    d.qpos[0] = 0
    mujoco.mj_forward(m, d)
    assert np.allclose(d.xpos[lid] + d.xmat[lid].reshape(3, 3) @ local, start)


ARM = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="base">
      <joint name="rail" type="slide" axis="1 0 0" range="0 1" limited="true"/>
      <geom type="box" size="0.05 0.05 0.05"/>
      <body name="l1" pos="0 0 0.1">
        <joint name="j1" type="hinge" axis="0 0 1" range="-3 3" limited="true"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03"/>
        <body name="l2" pos="0 0 0.3">
          <joint name="j2" type="hinge" axis="0 1 0" range="-2 2" limited="true"/>
          <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
          <body name="l3" pos="0.4 0 0">
            <joint name="j3" type="hinge" axis="0 1 0" range="-2.5 2.5" limited="true"/>
            <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
            <body name="l4" pos="0.3 0 0">
              <joint name="j4" type="hinge" axis="0 1 0" range="-2 2" limited="true"/>
              <joint name="j5" type="hinge" axis="0 0 1" range="-2 2" limited="true"/>
              <joint name="j6" type="hinge" axis="1 0 0" range="-3 3" limited="true"/>
              <geom type="box" size="0.02 0.02 0.02"/>
              <site name="tool" pos="0.1 0 0"/>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _arm():
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d, np.arange(m.njnt), np.arange(m.nv), m.jnt_range[:, 0], m.jnt_range[:, 1]


def test_ik_reaches_a_reachable_pose_to_a_tenth_of_a_millimetre():
    m, d, qa, da, lo, hi = _arm()
    site = m.site("tool").id
    q_true = np.array([0.4, 0.5, 0.3, -0.8, 0.6, 0.2, -0.4])
    target_p, target_R = ik.site_pose(m, d, site, q_true, qa)
    before = d.qpos.copy()
    res = ik.solve(m, d, site, target_p, target_R, qa, da, lo, hi, q0=np.full(7, 0.1))
    assert res.ok and res.pos_err < 1e-3 and res.rot_err < 2e-3
    p, R = ik.site_pose(m, d, site, res.q, qa)
    assert np.linalg.norm(p - target_p) < 1e-3
    assert np.allclose(d.qpos, before)  # solved on a copy: the simulation did not move


def test_ik_respects_joint_limits():
    m, d, qa, da, lo, hi = _arm()
    site = m.site("tool").id
    # a target beyond the rail's end: the best reach has the rail at its limit
    res = ik.solve(m, d, site, [2.5, 0.0, 0.4], None, qa, da, lo, hi)
    assert not res.ok
    assert np.all(res.q >= lo - 1e-12) and np.all(res.q <= hi + 1e-12)
    assert res.q[0] == pytest.approx(1.0)
    # limits of a hinge: tool position that needs j2 beyond +2 is not taken by passing it
    res = ik.solve(m, d, site, [0.0, 0.0, -0.6], None, qa, da, lo, hi, max_iter=100)
    assert np.all(res.q >= lo - 1e-12) and np.all(res.q <= hi + 1e-12)


def test_ik_prefers_the_solution_nearest_its_seed():
    # 7 joints for a 6D pose: a family of solutions; the posture term picks one near the seed
    m, d, qa, da, lo, hi = _arm()
    site = m.site("tool").id
    q_true = np.array([0.4, 0.5, 0.3, -0.8, 0.6, 0.2, -0.4])
    target_p, target_R = ik.site_pose(m, d, site, q_true, qa)
    seed = q_true + np.array([0.2, -0.1, 0.1, 0.1, -0.1, 0.1, 0.1])
    res = ik.solve(m, d, site, target_p, target_R, qa, da, lo, hi, q0=seed)
    assert res.ok
    assert np.linalg.norm(res.q - seed) <= np.linalg.norm(q_true - seed)


def test_ik_moves_only_its_own_joints():
    m, d, qa, da, lo, hi = _arm()
    site = m.site("tool").id
    q_true = np.array([0.4, 0.5, 0.3, -0.8, 0.6, 0.2, -0.4])
    target_p, _ = ik.site_pose(m, d, site, q_true, qa)
    # without j1 (the base's turn, at 0 in d) the target off the x-z plane is out of reach
    own = np.delete(qa, 1)
    res = ik.solve(m, d, site, target_p, None, own, np.delete(da, 1), lo[own], hi[own])
    assert not res.ok and res.pos_err > 0.05
    p, _ = ik.site_pose(m, d, site, res.q, own)  # j1 still where d has it
    assert np.linalg.norm(p - target_p) == pytest.approx(res.pos_err)
