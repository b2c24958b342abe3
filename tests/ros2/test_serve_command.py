"""``urdf2mjcf serve``'s refusals: each one ``error:`` line and exit 2, before any
session opens; and the wire-level controllers it drives, against references."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.ros2 import controllers

ROOT = Path(__file__).resolve().parents[2]
MODEL = """<mujoco>
  <option integrator="implicitfast"/>
  <default><joint armature="0.01" damping="0.1"/></default>
  <worldbody>
    <body name="link1"><joint name="j1" range="-1 1"/><geom size="0.1" mass="1"/>
      <body name="link2" pos="0 0 0.3"><joint name="j2"/><geom size="0.1" mass="1"/>
        <body name="link3" pos="0 0 0.3"><joint name="j3"/><geom size="0.1" mass="1"/></body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="j1" joint="j1" kp="100" ctrlrange="-1 1"/>
    <velocity name="j2" joint="j2" kv="10"/>
    <motor name="j3" joint="j3" ctrlrange="-2 2"/>
  </actuator>
</mujoco>
"""
# the import finder of a venv where the ros2 extra was never installed
WITHOUT_ZENOH = """import sys
from importlib.machinery import PathFinder
class Without(PathFinder):
    @classmethod
    def find_spec(cls, name, path=None, target=None):
        return None if name.partition(".")[0] == "zenoh" else super().find_spec(name, path, target)
sys.meta_path[:] = [Without if f is PathFinder else f for f in sys.meta_path]
from urdf2mjcf.cli import urdf2mjcf_main
urdf2mjcf_main()
"""


def _serve(*args: str, code: str | None = None, env: dict | None = None):
    prog = code or "from urdf2mjcf.cli import urdf2mjcf_main; urdf2mjcf_main()"
    return subprocess.run(
        [sys.executable, "-c", prog, "serve", *args],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})},
    )


@pytest.fixture
def model(tmp_path) -> Path:
    path = tmp_path / "robot.xml"
    path.write_text(MODEL)
    return path


@pytest.mark.parametrize(
    ("args", "env", "says"),
    [
        ((), {}, "name the transport: --ros2"),
        (("--ros2", "--zenoh-listen", "tcp/0.0.0.0:7447"), {}, "listens on every interface"),
        (("--ros2", "--zenoh-listen", "tcp/[::]:7447"), {}, "listens on every interface"),
        (("--ros2", "--zenoh-listen", "tcp/example.org:7447"), {}, "not the name"),
        (("--ros2", "--zenoh-connect", "udp/1.2.3.4"), {}, "is not tcp/HOST:PORT"),
        (("--ros2", "--ros-domain", "300"), {}, "--ros-domain"),
        (("--ros2",), {"ROS_DOMAIN_ID": "x"}, "ROS_DOMAIN_ID=x"),
        (("--ros2", "--node-name", "a/b"), {}, "not a ROS node name"),
    ],
)
def test_a_usage_error_is_one_line_and_exit_2(model, args, env, says):
    r = _serve(str(model), *args, env=env)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and says in lines[0], r.stderr


def test_a_model_mujoco_refuses_names_the_file(tmp_path):
    bad = tmp_path / "robot.xml"
    bad.write_text("<mujoco><worldbody><body><joint/></body></worldbody>")
    r = _serve(str(bad), "--ros2", "--zenoh-listen", "tcp/127.0.0.1:0")
    assert r.returncode == 2
    assert r.stderr.startswith(f"error: {bad}: ") and len(r.stderr.strip().splitlines()) == 1


def test_without_the_ros2_extra_one_line_names_it(model):
    r = _serve(str(model), "--ros2", code=WITHOUT_ZENOH)
    assert r.returncode == 2
    assert r.stderr.strip() == (
        "error: urdf2mjcf serve --ros2 needs the ros2 extra: pip install 'mjcf-forge[ros2]' "
        "(missing: zenoh)"
    )


def test_the_groups_are_the_actuators_kinds_in_model_order():
    m = mujoco.MjModel.from_xml_string(MODEL)
    groups = {g.kind: g for g in controllers.groups(m)}
    assert groups["position"].name == "forward_position_controller"
    assert groups["position"].joints == ("j1",)
    assert groups["velocity"].joints == ("j2",) and groups["velocity"].low[0] == -np.inf
    assert groups["effort"].joints == ("j3",) and groups["effort"].high[0] == 2.0


def _group(n: int) -> controllers.Group:
    names = tuple(f"j{i}" for i in range(n))
    return controllers.Group("g", "position", names, tuple(range(n)), -np.ones(n), np.ones(n))


def _point(t: float, positions, velocities=()):
    sec = int(t)
    return {
        "positions": list(positions),
        "velocities": list(velocities),
        "time_from_start": {"sec": sec, "nanosec": round((t - sec) * 1e9)},
    }


def test_a_trajectory_without_velocities_is_straight_between_its_knots():
    g = _group(2)
    msg = {
        "joint_names": ["j1", "j0"],
        "points": [_point(1.0, [0.5, -0.5]), _point(2.0, [1.0, 0.0])],
    }
    traj = controllers.trajectory(g, msg, now=10.0, current=np.array([0.2, 0.0]))
    assert traj.columns == (1, 0)
    for t in np.linspace(9.5, 12.5, 31):
        expect = [
            np.interp(t, [10, 11, 12], [0.0, 0.5, 1.0]),
            np.interp(t, [10, 11, 12], [0.2, -0.5, 0.0]),
        ]
        np.testing.assert_allclose(traj.sample(t), expect, atol=1e-12)


def test_a_trajectory_with_velocities_is_scipys_cubic_hermite_spline():
    scipy_interpolate = pytest.importorskip("scipy.interpolate")
    g = _group(1)
    pts = [_point(0.5, [0.3], [1.0]), _point(1.5, [-0.2], [0.0]), _point(2.0, [0.1], [0.5])]
    traj = controllers.trajectory(g, {"joint_names": ["j0"], "points": pts}, 3.0, np.array([0.0]))
    ref = scipy_interpolate.CubicHermiteSpline(
        [3.0, 3.5, 4.5, 5.0], [0.0, 0.3, -0.2, 0.1], [0.0, 1.0, 0.0, 0.5]
    )
    for t in np.linspace(3.0, 5.0, 41):
        assert traj.sample(t)[0] == pytest.approx(float(ref(t)), abs=1e-12)


@pytest.mark.parametrize(
    ("msg", "says"),
    [
        ({"joint_names": ["j9"], "points": [_point(1, [0])]}, "not in g"),
        ({"joint_names": ["j0"], "points": []}, "without joints or points"),
        ({"joint_names": ["j0"], "points": [_point(1, [0, 1])]}, "one per joint"),
        ({"joint_names": ["j0"], "points": [_point(1, [np.nan])]}, "finite"),
        ({"joint_names": ["j0"], "points": [_point(2, [0]), _point(1, [1])]}, "do not increase"),
        ({"joint_names": ["j0", "j0"], "points": [_point(1, [0, 0])]}, "named twice"),
        ({"joint_names": ["j0"], "points": [_point(1, [0], [1]), _point(2, [1])]}, "some points"),
    ],
)
def test_a_trajectory_that_cannot_be_one_is_refused(msg, says):
    with pytest.raises(controllers.BadCommand, match=says):
        controllers.trajectory(_group(2), msg, 0.0, np.zeros(2))


def test_a_forward_command_of_the_wrong_length_or_not_finite_is_refused():
    g = _group(3)
    np.testing.assert_array_equal(controllers.forward_command(g, [1, 2, 3]), [1.0, 2.0, 3.0])
    for bad in ([1, 2], [1, 2, float("inf")]):
        with pytest.raises(controllers.BadCommand):
            controllers.forward_command(g, bad)


def test_a_folder_that_is_no_bundle_or_a_broken_manifest_is_one_line(tmp_path, model):
    empty = tmp_path / "empty"
    empty.mkdir()
    r = _serve(str(empty), "--ros2", "--zenoh-listen", "tcp/127.0.0.1:0")
    assert r.returncode == 2 and r.stderr.startswith("error: ") and str(empty) in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    (tmp_path / "facility.json").write_bytes(bytes(range(256)))
    r = _serve(str(model), "--ros2", "--zenoh-listen", "tcp/127.0.0.1:0")
    assert r.returncode == 2 and "facility.json" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


CONTROLLERS = """controller_manager:
  ros__parameters:
    update_rate: 500
    joint_state_broadcaster:
      type: joint_state_broadcaster/JointStateBroadcaster
    arm_controller:
      type: joint_trajectory_controller/JointTrajectoryController
    spin_controller:
      type: velocity_controllers/JointGroupVelocityController
    push_controller:
      type: forward_command_controller/ForwardCommandController
    odd_controller:
      type: admittance_controller/AdmittanceController
arm_controller:
  ros__parameters:
    joints: [j1]
    command_interfaces: [position]
    state_interfaces: [position, velocity]
spin_controller:
  ros__parameters:
    joints: [j2]
push_controller:
  ros__parameters:
    joints: [j3]
    interface_name: effort
"""


def test_a_controllers_file_names_the_groups_and_their_interfaces(tmp_path, caplog):
    from urdf2mjcf.ros2 import controller_file

    path = tmp_path / "controllers.yaml"
    path.write_text(CONTROLLERS)
    m = mujoco.MjModel.from_xml_string(MODEL)
    kinds = {a: controllers.actuator_kind(m, a) for a in range(m.nu)}
    got = controller_file.read(path, m, kinds)
    assert [(g.name, g.kind, g.joints) for g in got.trajectory] == [
        ("arm_controller", "position", ("j1",))
    ]
    assert [(g.name, g.kind, g.joints) for g in got.forward] == [
        ("spin_controller", "velocity", ("j2",)),
        ("push_controller", "effort", ("j3",)),
    ]
    assert "AdmittanceController is not served" in caplog.text


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        (
            ("joints: [j2]\npush", "joints: [j1]\npush"),
            "joint 'j1' has a position actuator in the model, not a velocity one",
        ),
        (
            ("joints: [j1]\n    command", "joints: [nowhere]\n    command"),
            "joint 'nowhere' has no actuator",
        ),
        (("interface_name: effort", "interface_name: torque"), "interface 'torque'"),
        (("command_interfaces: [position]", "command_interfaces: [velocity]"), "only [position]"),
    ],
)
def test_a_controllers_file_the_model_cannot_serve_is_one_line(tmp_path, model, edit, says):
    path = tmp_path / "controllers.yaml"
    path.write_text(CONTROLLERS.replace(*edit))
    r = _serve(
        str(model), "--ros2", "--zenoh-listen", "tcp/127.0.0.1:0", "--controllers", str(path)
    )
    assert r.returncode == 2, r.stderr
    (line,) = r.stderr.strip().splitlines()
    assert line.startswith(f"error: {path}: ") and says in line, line
