"""`urdf2mjcf excite MODEL.xml -o traj.csv`: setpoints within 80 % of each joint's range and
under the speed asked for, that the model follows with every servo under 90 % of its force
range (checked here by stepping it), and that an existing file is not replaced unasked."""

from __future__ import annotations

import mujoco
import numpy as np

from tests.calibrate import arm
from tests.security.attack import assert_one_error, run


def test_the_excitation_is_within_the_limits(tmp_path):
    model = arm.convert(tmp_path / "arm")
    res = run(
        "urdf2mjcf", "excite", str(model), "-o", "traj.csv", "--duration", "8",
        "--amplitude", "1.5", "--max-velocity", "2", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    header, *rows = (tmp_path / "traj.csv").read_text().splitlines()
    assert header == "t,u.shoulder,u.elbow"
    data = np.array([[float(x) for x in r.split(",")] for r in rows])
    t, u = data[:, 0], data[:, 1:]
    assert t[-1] > 7.9 and np.all(np.diff(t) > 0)
    m = mujoco.MjModel.from_xml_path(str(model))
    assert np.all(np.abs(u) <= 0.8 * 2.0 + 1e-9)  # both joints: range [-2, 2]
    assert np.abs(np.diff(u, axis=0) / np.diff(t)[:, None]).max() <= 2.0 * 1.01
    assert np.ptp(u, axis=0).min() > 0.3  # it moves every joint
    assert abs(np.corrcoef(u.T)[0, 1]) < 0.5  # and each its own way
    d = mujoco.MjData(m)
    peak = np.zeros(m.nu)
    for k in range(int(t[-1] / m.opt.timestep)):
        d.ctrl[:] = [np.interp(k * m.opt.timestep, t, u[:, a]) for a in range(m.nu)]
        mujoco.mj_step(m, d)
        peak = np.maximum(peak, np.abs(d.actuator_force))
    assert np.all(peak <= 0.9 * np.abs(m.actuator_forcerange).max(axis=1) * 1.05)
    again = run("urdf2mjcf", "excite", str(model), "-o", "traj.csv", cwd=tmp_path)
    assert_one_error(again, "traj.csv", "--overwrite")


POSTED = """<mujoco model="posted">
  <compiler angle="radian"/>
  <option timestep="0.002"/>
  <worldbody>
    <body name="base">
      <geom name="post" type="cylinder" size="0.05 0.2" pos="{x} {y} 0.3"/>
      <body name="link" pos="0 0 0.3">
        <joint name="shoulder" type="hinge" axis="0 0 1" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.6 0 0" size="0.03" mass="1"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="shoulder" joint="shoulder" kp="200" kv="10" forcerange="-100 100"/>
  </actuator>
</mujoco>
"""


def _angle_clear_of_post(x: float, y: float) -> float:
    """The largest |shoulder| (rad) at which the link (radius 0.03, 0.6 long) stays clear
    of the post (radius 0.05 at x, y): analytic, for the sign of y."""
    r, reach = float(np.hypot(x, y)), 0.03 + 0.05
    return float(np.arctan2(abs(y), x) - np.arcsin(reach / r))


def test_the_excitation_keeps_the_robot_clear_of_itself(tmp_path):
    """A post on the base stands in the link's way at 0.6 rad: asked for 1.5 rad, the
    excitation is cut until the link passes it, by the analytic angle."""
    x, y = 0.35, 0.24
    model = tmp_path / "posted.xml"
    model.write_text(POSTED.format(x=x, y=y))
    res = run(
        "urdf2mjcf", "excite", str(model), "-o", "traj.csv", "--duration", "6",
        "--amplitude", "1.5", "--max-velocity", "60", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    u = np.loadtxt(tmp_path / "traj.csv", delimiter=",", skiprows=1)[:, 1]
    clear = _angle_clear_of_post(x, y)
    assert 0.3 < clear < 0.7
    assert u.max() <= clear + 1e-3 / 0.2  # within SELF_CONTACT_M of touching, at the tip
    assert u.max() > 0.2  # and it still moves
    from urdf2mjcf.calibrate.excite import ExciteConfig, excite

    away = mujoco.MjModel.from_xml_string(POSTED.format(x=5.0, y=5.0))
    free = excite(away, ExciteConfig(duration=6, amplitude=1.5, max_velocity=60))
    assert free.setpoints.max() > 2 * clear  # the post, not another limit, cut it


def test_a_robot_touching_itself_everywhere_is_one_error(tmp_path):
    model = tmp_path / "posted.xml"
    model.write_text(POSTED.format(x=0.3, y=0.0))  # the post through the link at rest
    res = run("urdf2mjcf", "excite", str(model), "-o", "traj.csv", cwd=tmp_path)
    assert_one_error(res, str(model), "keeps the robot clear of itself", "'base' and 'link'")
    assert not (tmp_path / "traj.csv").exists()


def test_the_bag_holds_one_trajectory_for_the_controller(tmp_path):
    """``--bag``: one trajectory_msgs/JointTrajectory on the controller's topic, read back
    with rosbags, the same setpoints as the CSV at their times; a folder that is not a bag
    is never replaced."""
    from pathlib import Path

    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    model = arm.convert(tmp_path / "arm")
    res = run(
        "urdf2mjcf", "excite", str(model), "-o", "traj.csv", "--duration", "3",
        "--bag", "traj", "--controller", "arm_controller", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    data = np.loadtxt(tmp_path / "traj.csv", delimiter=",", skiprows=1)
    store = get_typestore(Stores.ROS2_HUMBLE)
    with AnyReader([Path(tmp_path / "traj")], default_typestore=store) as reader:
        (msg,) = [(c.topic, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages()]
    topic, traj = msg
    assert topic == "/arm_controller/joint_trajectory"
    assert traj.joint_names == ["shoulder", "elbow"]
    times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in traj.points]
    np.testing.assert_allclose(times, data[:, 0], atol=1e-9)
    np.testing.assert_array_equal([p.positions for p in traj.points], data[:, 1:])
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    again = run(
        "urdf2mjcf", "excite", str(model), "-o", "t2.csv", "--bag", "mine", "--overwrite",
        cwd=tmp_path,
    )  # fmt: skip
    assert_one_error(again, "mine", "not replaced")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "mine"
