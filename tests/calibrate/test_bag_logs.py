"""Logs as ROS 2 bags (rosbag2, MCAP and SQLite, written here with rosbags): JointState
messages and a forward command controller's Float64MultiArray, written out of time order,
calibrate as the same log as CSV does, and so do a joint trajectory controller's
JointTrajectory messages; a bag with no command messages is one error."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.calibrate import arm
from tests.security.attack import assert_one_error, run


@pytest.fixture(scope="module")
def case(tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("bags")
    nominal = arm.convert(folder)
    truth = {"shoulder": {"damping": 1.5}, "elbow": {"damping": 0.9}}
    real = arm.perturbed(nominal, folder / "real.xml", truth, {})
    return nominal, arm.record(real, folder / "log.csv", seconds=6.0, amplitude=0.5)


def _bag(csv: Path, dest: Path, storage: str, *, commands: bool = True) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    js, arr = (
        store.types["sensor_msgs/msg/JointState"],
        store.types["std_msgs/msg/Float64MultiArray"],
    )
    header_t = store.types["std_msgs/msg/Header"]
    time_t = store.types["builtin_interfaces/msg/Time"]
    layout = store.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(dest, version=8, storage_plugin=plugin) as w:
        states = w.add_connection("/joint_states", js.__msgtype__, typestore=store)
        cmds = w.add_connection("/position_controller/commands", arr.__msgtype__, typestore=store)
        order = np.arange(len(data))
        order[100:110] = order[100:110][::-1]  # a few written out of order
        for i in order:
            t, q, v, u = data[i, 0], data[i, 1:3], data[i, 3:5], data[i, 5:7]
            ns = int(round(t * 1e9))
            stamp = time_t(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
            msg = js(header=header_t(stamp=stamp, frame_id=""), name=list(arm.JOINTS),
                     position=q, velocity=v, effort=np.zeros(0))  # fmt: skip
            w.write(states, ns, store.serialize_cdr(msg, js.__msgtype__))
            if commands:
                w.write(cmds, ns, store.serialize_cdr(arr(layout=layout, data=u), arr.__msgtype__))
    return dest


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_bag_calibrates_as_its_csv_does(case, tmp_path, storage):
    nominal, csv = case
    bag = _bag(csv, tmp_path / "run", storage)
    found = {}
    for name, log in (("bag", bag), ("csv", csv)):
        res = run(
            "urdf2mjcf",
            "calibrate",
            str(nominal),
            str(log),
            "-o",
            name,
            "--free",
            "damping",
            cwd=tmp_path,
        )
        assert res.returncode == 0, res.stderr
        report = json.loads((tmp_path / name / "report.json").read_text())
        found[name] = {p["name"]: p["after"] for p in report["parameters"]}
    assert found["bag"]["shoulder.damping"] == pytest.approx(1.5, rel=0.1)
    assert found["bag"] == pytest.approx(found["csv"], rel=1e-3)


def test_a_bag_with_no_command_messages_is_one_error(case, tmp_path):
    nominal, csv = case
    bag = _bag(csv, tmp_path / "run", "mcap", commands=False)
    res = run("urdf2mjcf", "calibrate", str(nominal), str(bag), "-o", "cal", cwd=tmp_path)
    assert_one_error(res, "run", "lacks u.shoulder, u.elbow")
    assert not (tmp_path / "cal").exists()


def _trajectory_bag(csv: Path, dest: Path, joints: tuple[str, ...]) -> Path:
    """The log as a joint trajectory controller's bag: JointState messages and the commands
    as two JointTrajectory messages (the second replacing the rest of the first)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    js, traj = types["sensor_msgs/msg/JointState"], types["trajectory_msgs/msg/JointTrajectory"]
    point, header_t = types["trajectory_msgs/msg/JointTrajectoryPoint"], types["std_msgs/msg/Header"]
    time_t, dur_t = types["builtin_interfaces/msg/Time"], types["builtin_interfaces/msg/Duration"]
    data = np.loadtxt(csv, delimiter=",", skiprows=1)

    def stamp(ns: int):
        return time_t(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    half = len(data) // 2
    with Writer(dest, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        states = w.add_connection("/joint_states", js.__msgtype__, typestore=store)
        cmds = w.add_connection("/arm_controller/joint_trajectory", traj.__msgtype__, typestore=store)
        for rows in (data[:half], data[half:]):
            t0 = int(round(rows[0, 0] * 1e9))
            points = []
            for r in rows:
                n = int(round(r[0] * 1e9)) - t0
                after = dur_t(sec=n // 1_000_000_000, nanosec=n % 1_000_000_000)
                points.append(point(positions=r[5:7], velocities=np.zeros(0),
                                    accelerations=np.zeros(0), effort=np.zeros(0),
                                    time_from_start=after))  # fmt: skip
            msg = traj(header=header_t(stamp=stamp(t0), frame_id=""), joint_names=list(joints),
                       points=points)  # fmt: skip
            w.write(cmds, t0, store.serialize_cdr(msg, traj.__msgtype__))
        for r in data:
            ns = int(round(r[0] * 1e9))
            msg = js(header=header_t(stamp=stamp(ns), frame_id=""), name=list(arm.JOINTS),
                     position=r[1:3], velocity=r[3:5], effort=np.zeros(0))  # fmt: skip
            w.write(states, ns, store.serialize_cdr(msg, js.__msgtype__))
    return dest


def test_a_joint_trajectory_bag_calibrates_as_its_csv_does(case, tmp_path):
    """A bag whose commands are a joint trajectory controller's JointTrajectory messages
    (what ``urdf2mjcf excite --bag`` writes and ``ros2 bag play`` sends) fits as the CSV
    of the same run does."""
    nominal, csv = case
    bag = _trajectory_bag(csv, tmp_path / "run", arm.JOINTS)
    found = {}
    for name, log in (("bag", bag), ("csv", csv)):
        res = run(
            "urdf2mjcf", "calibrate", str(nominal), str(log), "-o", name, "--free", "damping",
            cwd=tmp_path,
        )  # fmt: skip
        assert res.returncode == 0, res.stderr
        report = json.loads((tmp_path / name / "report.json").read_text())
        found[name] = {p["name"]: p["after"] for p in report["parameters"]}
    assert found["bag"]["shoulder.damping"] == pytest.approx(1.5, rel=0.1)
    assert found["bag"] == pytest.approx(found["csv"], rel=1e-3)


def test_a_trajectory_for_a_joint_without_a_servo_is_one_error(case, tmp_path):
    nominal, csv = case
    bag = _trajectory_bag(csv, tmp_path / "run", ("shoulder", "wrist"))
    res = run("urdf2mjcf", "calibrate", str(nominal), str(bag), "-o", "cal", cwd=tmp_path)
    assert_one_error(res, "run", "joint 'wrist' has no position servo")
    assert not (tmp_path / "cal").exists()


FREE_BODY = """<mujoco><worldbody><body name="chassis" pos="0.3 -0.2 0.5">
  <freejoint name="mount"/><geom type="box" size="0.2 0.1 0.05" mass="3"/>
  <body pos="0.1 0 0.1"><joint name="arm" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.02" mass="0.5"/></body>
</body></worldbody></mujoco>"""


def _odometry_message(store, pose, quat_xyzw, linear, angular, frame: str = "chassis"):
    ty = store.types
    vec, point, quat = (ty[f"geometry_msgs/msg/{n}"] for n in ("Vector3", "Point", "Quaternion"))
    return ty["nav_msgs/msg/Odometry"](
        header=ty["std_msgs/msg/Header"](
            stamp=ty["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="odom"
        ),
        child_frame_id=frame,
        pose=ty["geometry_msgs/msg/PoseWithCovariance"](
            pose=ty["geometry_msgs/msg/Pose"](position=point(*pose), orientation=quat(*quat_xyzw)),
            covariance=np.zeros(36),
        ),
        twist=ty["geometry_msgs/msg/TwistWithCovariance"](
            twist=ty["geometry_msgs/msg/Twist"](linear=vec(*linear), angular=vec(*angular)),
            covariance=np.zeros(36),
        ),
    )


def test_odometry_is_read_as_the_free_joint_holds_the_base():
    """A nav_msgs/Odometry of the base body (its pose in the world, its twist in its own
    frame, taken here from MuJoCo's xpos, xquat and mj_objectVelocity in the body's frame)
    becomes the free joint's qpos and qvel (MuJoCo's: linear velocity in the world,
    angular in the body), at random turned and moving states."""
    import mujoco
    from rosbags.typesys import Stores, get_typestore

    from urdf2mjcf.calibrate import logs, params

    store = get_typestore(Stores.ROS2_HUMBLE)
    m = mujoco.MjModel.from_xml_string(FREE_BODY)
    d = mujoco.MjData(m)
    base = params.floating_base(m)
    assert base == params.Base("mount", "chassis")
    rng = np.random.default_rng(3)
    twist = np.zeros(6)
    for _ in range(20):
        d.qpos[:3] = rng.normal(0, 2, 3)
        d.qpos[3:7] = rng.normal(size=4) / 1.0
        d.qpos[3:7] /= np.linalg.norm(d.qpos[3:7])
        d.qvel[:] = rng.normal(0, 1.5, m.nv)
        mujoco.mj_forward(m, d)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, 1, twist, 1)
        w, x, y, z = d.xquat[1]
        msg = _odometry_message(store, d.xpos[1], (x, y, z, w), twist[3:], twist[:3])
        q, v = logs._odometry(Path("b"), "/odom", msg, base)
        assert q == pytest.approx(d.qpos[:7], abs=1e-9)
        assert v == pytest.approx(d.qvel[:6], abs=1e-9)


def _odometry_bag(dest: Path, messages: dict[str, list]) -> Path:
    """A bag of one JointState and one command per 10 ms and the given Odometry
    messages per topic, one each 10 ms."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    ty = store.types
    js, arr = ty["sensor_msgs/msg/JointState"], ty["std_msgs/msg/Float64MultiArray"]
    header_t, time_t = ty["std_msgs/msg/Header"], ty["builtin_interfaces/msg/Time"]
    layout = ty["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    with Writer(dest, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        states = w.add_connection("/joint_states", js.__msgtype__, typestore=store)
        cmds = w.add_connection("/commands", arr.__msgtype__, typestore=store)
        odoms = {
            topic: w.add_connection(topic, "nav_msgs/msg/Odometry", typestore=store)
            for topic in messages
        }
        n = max(len(v) for v in messages.values())
        for k in range(n):
            ns = k * 10_000_000
            stamp = time_t(sec=0, nanosec=ns)
            msg = js(header=header_t(stamp=stamp, frame_id=""), name=["arm"],
                     position=np.array([0.01 * k]), velocity=np.array([1.0]),
                     effort=np.zeros(0))  # fmt: skip
            w.write(states, ns, store.serialize_cdr(msg, js.__msgtype__))
            u = arr(layout=layout, data=np.array([0.0]))
            w.write(cmds, ns, store.serialize_cdr(u, arr.__msgtype__))
            for topic, conn in odoms.items():
                odom = messages[topic][k]
                odom.header.stamp = stamp
                w.write(conn, ns, store.serialize_cdr(odom, "nav_msgs/msg/Odometry"))
    return dest


def _still(store, n: int, quat=(0.0, 0.0, 0.0, 1.0), frame: str = "chassis") -> list:
    return [_odometry_message(store, (0, 0, 0.5), quat, (0, 0, 0), (0, 0, 0), frame)
            for _ in range(n)]  # fmt: skip


def test_a_bags_odometry_fills_the_base_and_its_faults_are_one_error(tmp_path, caplog):
    """The Odometry topic gives the q.mount.* and v.mount.* columns (a model without a
    free joint ignores it); two Odometry topics, or an orientation that is no quaternion,
    are one error each; odometry of another frame than the base's body is a warning."""
    import mujoco
    from rosbags.typesys import Stores, get_typestore

    from urdf2mjcf.calibrate import logs, params
    from urdf2mjcf.errors import InputError

    store = get_typestore(Stores.ROS2_HUMBLE)
    base = params.floating_base(mujoco.MjModel.from_xml_string(FREE_BODY))
    bag = _odometry_bag(tmp_path / "one", {"/odom": _still(store, 20, frame="base_footprint")})
    with caplog.at_level("WARNING"):
        found = logs.read(bag, ["motor"], {}, base)
    assert "frame base_footprint" in caplog.text and "'chassis'" in caplog.text
    assert set(found.q) == {"arm", *(f"mount.{c}" for c in params.BASE_Q)}
    assert set(found.v) == {"arm", *(f"mount.{c}" for c in params.BASE_V)}
    assert "gaps" not in caplog.text  # three topics' messages at each time are no gap
    assert found.q["mount.qw"][1] == pytest.approx(np.ones(20))
    assert set(logs.read(bag, ["motor"], {}, None).q) == {"arm"}
    two = _odometry_bag(tmp_path / "two", {"/a": _still(store, 5), "/b": _still(store, 5)})
    with pytest.raises(InputError, match="on /a, /b: the base's state must come from one"):
        logs.read(two, ["motor"], {}, base)
    zero = _odometry_bag(tmp_path / "zero", {"/odom": _still(store, 5, quat=(0, 0, 0, 0))})
    with pytest.raises(InputError, match=r"/odom: an Odometry orientation .* \(\|q\| = 0\)"):
        logs.read(zero, ["motor"], {}, base)
