"""ROS 2 recordings read back with an independent reader (rosbags, with its own ROS 2
Humble message definitions) and checked against the simulation they recorded: topics
and types, counts against the rates, stamps equal to simulated times, frame ids,
joint positions, transforms, images, camera intrinsics, wrench and IMU values."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from urdf2mjcf.runner.cli import facility_demo_command
from urdf2mjcf.runner.control import Controller
from urdf2mjcf.runner.load import load
from urdf2mjcf.runner.record import Rates, Recorder, facility_sources, rover_sources
from urdf2mjcf.runner.rover.cli import rover_drive_command
from urdf2mjcf.runner.rover.sim import RoverSim
from urdf2mjcf.runner.rover.tasks import Straight

HUMBLE = get_typestore(Stores.ROS2_HUMBLE)


@pytest.fixture(scope="module")
def imetro(imetro_bundle: Path) -> Path:
    return imetro_bundle


@pytest.fixture(scope="module")
def mira(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-floor")


def ns(t: float) -> int:
    return int(round(t * 1e9))


class Truth:
    """The simulation's state after every step, by stamp (ns of simulated time)."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData):
        self.m, self.d = m, d
        self.at: dict[int, dict[str, np.ndarray]] = {}
        self()

    def __call__(self) -> None:
        d = self.d
        self.at[ns(d.time)] = {
            "qpos": d.qpos.copy(),
            "xpos": d.xpos.copy(),
            "xquat": d.xquat.copy(),
            "sensordata": d.sensordata.copy(),
            "cam_xpos": d.cam_xpos.copy(),
            "cam_xmat": d.cam_xmat.copy(),
        }


def read(path: Path) -> dict[str, list[tuple[int, object]]]:
    """Every message by topic, decoded with rosbags' own Humble definitions (not the
    definitions in the file: a layout that differs from ROS 2's fails here)."""
    out: dict[str, list[tuple[int, object]]] = defaultdict(list)
    with Reader(path) as reader:
        for conn, t, raw in reader.messages():
            out[conn.topic].append((t, HUMBLE.deserialize_cdr(raw, conn.msgtype)))
    return out


def types(path: Path) -> dict[str, str]:
    """Topic -> type, with AnyReader checking the definitions stored in the file (and the
    container saying what rosbag2's MCAP storage plugin looks for: the ros2 profile, ros2msg
    schemas, CDR messages; every chunk's CRC valid)."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        reader = make_reader(f, validate_crcs=True)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert sum(1 for _ in reader.iter_messages()) == summary.statistics.message_count
    with AnyReader([path]) as reader:
        for conn in reader.connections:  # what the file says is what ROS 2 Humble says
            assert reader.typestore.hash_rihs01(conn.msgtype) == HUMBLE.hash_rihs01(conn.msgtype)
        return {c.topic: c.msgtype for c in reader.connections}


def stamp_ns(msg: object) -> int:
    """The header's stamp; a TFMessage's: the one stamp all its transforms share."""
    if hasattr(msg, "transforms"):
        stamps = {stamp_ns(t) for t in msg.transforms}
        assert len(stamps) == 1
        return stamps.pop()
    s = msg.header.stamp  # type: ignore[attr-defined]
    return s.sec * 1_000_000_000 + s.nanosec


def expected_count(span_ns: int, rate: float) -> int:
    return int(math.floor(span_ns * 1e-9 * rate + 1e-6)) + 1


VISIBLE = np.array([1, 1, 1, 0, 0, 0], np.uint8)
"""Geom groups a MuJoCo camera renders by default (0-2: not the collision group 3)."""


def last_tf_before(tfs: list[tuple[int, object]], t: int) -> object:
    return [tf for when, tf in tfs if when <= t][-1]


def world_poses(tf: object) -> dict[str, tuple[np.ndarray, Rotation]]:
    """Every frame's pose in the world, composed along the tree (scipy, not MuJoCo)."""
    edges = {t.child_frame_id: t for t in tf.transforms}  # type: ignore[attr-defined]
    poses: dict[str, tuple[np.ndarray, Rotation]] = {"world": (np.zeros(3), Rotation.identity())}

    def pose(frame: str) -> tuple[np.ndarray, Rotation]:
        if frame not in poses:
            t = edges[frame]
            p0, r0 = pose(t.header.frame_id)
            tr, q = t.transform.translation, t.transform.rotation
            poses[frame] = (
                p0 + r0.apply([tr.x, tr.y, tr.z]),
                r0 * Rotation.from_quat([q.x, q.y, q.z, q.w]),
            )
        return poses[frame]

    for frame in edges:
        pose(frame)
    return poses


def test_message_definitions_are_ros2_humbles():
    from urdf2mjcf.runner.record import msgdef

    for datatype in (
        "sensor_msgs/msg/JointState",
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CameraInfo",
        "sensor_msgs/msg/Imu",
        "geometry_msgs/msg/WrenchStamped",
        "tf2_msgs/msg/TFMessage",
    ):
        from rosbags.typesys import get_types_from_msg

        store = get_typestore(Stores.EMPTY)
        text = msgdef(datatype)
        # the "=====" / "MSG: pkg/Name" layout ros2 bag writes, read by rosbags' msg parser
        parts = text.split("=" * 80 + "\n")
        store.register(get_types_from_msg(parts[0], datatype))
        for part in parts[1:]:
            head, body = part.split("\n", 1)
            pkg, name = head.removeprefix("MSG: ").split("/")
            store.register(get_types_from_msg(body, f"{pkg}/msg/{name}"))
        assert store.hash_rihs01(datatype) == HUMBLE.hash_rihs01(datatype)


def test_facility_recording_matches_the_simulation(imetro, tmp_path, gl_context):
    fac = load(imetro)
    m, d = fac.model, fac.data
    roles = fac.manifest.components["robot"].roles
    ctl = Controller(fac, np.full(len(fac.robot.joints), 1.0))
    path = tmp_path / "run.mcap"
    rec = Recorder(m, d, facility_sources(fac), path, rates=Rates(images=5.0))
    rec.step()
    truth = Truth(m, d)
    ctl.on_step += [rec.step, truth]
    target = ctl.target.copy()
    target[2:] = np.clip(target[2:] + 0.15, fac.robot.lower[2:], fac.robot.upper[2:])
    ctl.move_to(target, 0.8)  # joints move: positions and transforms change over the run
    ctl.wait(0.2)
    rec.close()
    duration = ns(d.time) - min(truth.at)

    cams = {c.name: c for c in fac.manifest.cameras}
    ft = roles["force_torque"]
    wrench_topic = f"/{ft['site']}/wrench"
    topics = types(path)
    want = {"/joint_states": "sensor_msgs/msg/JointState", "/tf": "tf2_msgs/msg/TFMessage"}
    want[wrench_topic] = "geometry_msgs/msg/WrenchStamped"
    for role in roles["cameras"]:
        for kind in ("color", "aligned_depth_to_color"):
            want[f"/{role}_camera/{kind}/image_raw"] = "sensor_msgs/msg/Image"
            want[f"/{role}_camera/{kind}/camera_info"] = "sensor_msgs/msg/CameraInfo"
    assert topics == want

    msgs = read(path)
    rates = {"/joint_states": 100, "/tf": 100, wrench_topic: 100}
    for topic in want:
        stamps = [stamp_ns(msg) for _, msg in msgs[topic]]
        assert [t for t, _ in msgs[topic]] == stamps  # log time = header stamp
        assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False))
        assert set(stamps) <= set(truth.at)  # every stamp is a simulated time we stepped to
        rate = rates.get(topic, 5.0)
        assert len(stamps) == expected_count(duration, rate), topic
        period = 1e9 / rate
        assert np.allclose(np.diff(stamps), period, atol=1e3)

    # joint positions: the simulation's qpos, by the names in the manifest's roles
    names = [*roles["joints"], *roles["gripper"]["joints"]]
    adr = {n: m.jnt_qposadr[fac.joint(n)] for n in names}
    moved = 0.0
    for _, msg in msgs["/joint_states"]:
        assert msg.name == names and msg.header.frame_id == ""
        q = truth.at[stamp_ns(msg)]["qpos"]
        assert np.array_equal(msg.position, [q[adr[n]] for n in names])
        moved = max(
            moved,
            float(np.abs(msg.position[2:8] - msgs["/joint_states"][0][1].position[2:8]).max()),
        )
    assert moved > 0.1

    # TF: the robot's tree from the world, and world -> ctb; composed poses = MuJoCo's
    robot_bodies = {m.body(b).name for b in fac.robot.bodies}
    for _, tf in msgs["/tf"][::25]:
        poses = world_poses(tf)
        state = truth.at[stamp_ns(tf)]
        parents = {t.child_frame_id: t.header.frame_id for t in tf.transforms}
        assert parents["ctb"] == "world"
        assert robot_bodies <= set(parents)
        for name in [*robot_bodies, "ctb"]:
            b = fac.body(name)
            p, r = poses[name]
            assert np.allclose(p, state["xpos"][b], atol=1e-9)
            w, x, y, z = state["xquat"][b]
            assert (r.inv() * Rotation.from_quat([x, y, z, w])).magnitude() < 1e-7
        # optical frames: z forward (MuJoCo cameras look along their -z), y down
        for cam_name in cams:
            c = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, cam_name)
            R = poses[cam_name][1].as_matrix()
            mj = state["cam_xmat"][c].reshape(3, 3)
            assert np.allclose(R, mj @ np.diag([1.0, -1.0, -1.0]), atol=1e-7)

    # wrench: the force-torque sensors' readings, in the sensor site's frame
    f_adr = m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, ft["force"])]
    t_adr = m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, ft["torque"])]
    for _, msg in msgs[wrench_topic]:
        s = truth.at[stamp_ns(msg)]["sensordata"]
        assert msg.header.frame_id == ft["site"]
        w = msg.wrench
        assert [w.force.x, w.force.y, w.force.z] == s[f_adr : f_adr + 3].tolist()
        assert [w.torque.x, w.torque.y, w.torque.z] == s[t_adr : t_adr + 3].tolist()

    # images: size from the manifest, encodings as RealSense's ROS driver, K from fovy
    for role, cam_name in roles["cameras"].items():
        width, height = cams[cam_name].resolution
        f = (height / 2) / math.tan(math.radians(cams[cam_name].fovy) / 2)
        base = f"/{role}_camera"
        for kind, encoding, size in (("color", "rgb8", 3), ("aligned_depth_to_color", "16UC1", 2)):
            for (_, img), (_, info) in zip(
                msgs[f"{base}/{kind}/image_raw"], msgs[f"{base}/{kind}/camera_info"], strict=True
            ):
                assert (img.height, img.width, img.encoding) == (height, width, encoding)
                assert img.step == width * size and len(img.data) == height * width * size
                assert img.header.frame_id == info.header.frame_id == cam_name
                assert stamp_ns(img) == stamp_ns(info)
                assert np.allclose(info.k, [f, 0, (width - 1) / 2, 0, f, (height - 1) / 2, 0, 0, 1])
                assert info.distortion_model == "plumb_bob" and not np.any(info.d)
        # depth (mm) through pixel centres, by K and the optical frame = MuJoCo's ray cast
        _, img = msgs[f"{base}/aligned_depth_to_color/image_raw"][-1]
        depth = np.frombuffer(img.data, "<u2").reshape(height, width)
        _, info = msgs[f"{base}/aligned_depth_to_color/camera_info"][-1]
        d.qpos[:] = truth.at[stamp_ns(img)]["qpos"]  # the scene as it was at that frame
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        origin, optical = world_poses(last_tf_before(msgs["/tf"], stamp_ns(img)))[cam_name]
        assert np.allclose(origin, d.cam_xpos[m.camera(cam_name).id], atol=1e-9)
        near = m.vis.map.znear * m.stat.extent
        hits = agree = 0
        for v in np.linspace(20, height - 21, 7).round().astype(int):
            for u in np.linspace(20, width - 21, 7).round().astype(int):
                ray = np.array([(u - info.k[2]) / info.k[0], (v - info.k[5]) / info.k[4], 1.0])
                ray /= np.linalg.norm(ray)
                skip = near / ray[2]  # the renderer clips what is nearer (the camera's housing)
                toward = optical.apply(ray)
                dist = mujoco.mj_ray(
                    m, d, origin + skip * toward, toward, VISIBLE, 1, -1, np.zeros(1, np.int32)
                )
                want = 1000 * (skip + dist) * ray[2] if dist >= 0 else 0.0  # z; 0: none seen
                hits += want > 0
                agree += abs(float(depth[v, u]) - want) <= 2 + 0.005 * want
        assert hits > 10, cam_name  # the camera sees the scene
        assert agree >= 45, (cam_name, agree)  # of 49: a pixel on an edge may differ


def test_a_recording_with_sensor_noise_reads_as_the_sensors_do(imetro, tmp_path, gl_context):
    """With the facility's SensorNoise, recorded wrenches are the simulation's plus this
    seed's bias and white noise of the configured size, and images are not the ideal
    render; joint states stay exact."""
    from urdf2mjcf.runner.noise import SensorNoise

    fac = load(imetro)
    m, d = fac.model, fac.data
    ft = fac.manifest.components["robot"].roles["force_torque"]
    cfg = fac.manifest.noise["wrench"]
    noise = SensorNoise.from_manifest(fac.manifest, 7)
    bias = SensorNoise.from_manifest(fac.manifest, 7)  # the same seed: the same bias
    path = tmp_path / "noisy.mcap"
    rec = Recorder(m, d, facility_sources(fac), path, rates=Rates(images=10.0), noise=noise)
    rec.step()
    truth = Truth(m, d)
    ctl = Controller(fac, np.full(len(fac.robot.joints), 1.0))
    ctl.on_step += [rec.step, truth]
    ctl.wait(1.0)
    rec.close()
    msgs = read(path)
    f_adr = m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, ft["force"])]
    errors = []
    for _, msg in msgs[f"/{ft['site']}/wrench"]:
        s = truth.at[stamp_ns(msg)]["sensordata"]
        w = msg.wrench.force
        errors.append(np.array([w.x, w.y, w.z]) - s[f_adr : f_adr + 3])
    errors = np.array(errors)
    assert len(errors) == 101  # the start and 1 s at 100 Hz
    assert np.linalg.norm(bias.force_bias) > 0.5 * cfg["force_bias"]
    np.testing.assert_allclose(errors.mean(axis=0), bias.force_bias, atol=0.2)  # 4 sigma
    assert 0.4 < errors.std(axis=0).mean() / cfg["force_std"] < 1.6
    # images: the noisy camera differs from an ideal render of the same state
    role, cam_name = next(iter(fac.manifest.components["robot"].roles["cameras"].items()))
    _, img = msgs[f"/{role}_camera/color/image_raw"][-1]
    rgb = np.frombuffer(img.data, np.uint8).reshape(img.height, img.width, 3)
    from urdf2mjcf.runner.perception import Camera

    ideal = Camera(m, m.camera(cam_name).id)
    try:
        clean, _ = ideal.rgbd(d)
    finally:
        ideal.close()
    assert np.abs(rgb.astype(int) - clean.astype(int)).mean() > 0.5
    # joint states: exact
    for _, msg in msgs["/joint_states"][:5]:
        q = truth.at[stamp_ns(msg)]["qpos"]
        j = m.joint(msg.name[0])
        assert msg.position[0] == q[j.qposadr[0]]


def test_rover_recording_has_the_imu_and_the_tree(mira, tmp_path):
    sim = RoverSim(mira)
    ((name, rover),) = sim.rovers.items()
    path = tmp_path / "drive.mcap"
    rec = Recorder(sim.m, sim.d, rover_sources(sim.m, sim.manifest, sim.rovers), path)
    rec.step()
    truth = Truth(sim.m, sim.d)
    sim.on_step += [rec.step, truth]
    sim.settle(0.2)
    sim.run({name: Straight(0.3, speed=0.5)})
    rec.close()

    imu_topic = f"/{name}/imu/data"
    assert types(path) == {
        "/joint_states": "sensor_msgs/msg/JointState",
        "/tf": "tf2_msgs/msg/TFMessage",
        imu_topic: "sensor_msgs/msg/Imu",
    }
    msgs = read(path)
    duration = max(truth.at) - min(truth.at)
    imu = rover.roles["imu"]
    m = sim.m
    adr = {
        k: m.sensor_adr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, imu[k])]
        for k in ("accelerometer", "gyro", "orientation")
    }
    assert len(msgs[imu_topic]) == expected_count(duration, 100)
    for _, msg in msgs[imu_topic]:
        s = truth.at[stamp_ns(msg)]["sensordata"]
        o, g, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        assert msg.header.frame_id == imu["site"]
        assert [o.w, o.x, o.y, o.z] == s[adr["orientation"] : adr["orientation"] + 4].tolist()
        assert [g.x, g.y, g.z] == s[adr["gyro"] : adr["gyro"] + 3].tolist()
        assert [a.x, a.y, a.z] == s[adr["accelerometer"] : adr["accelerometer"] + 3].tolist()
    wheels = [*rover.roles["wheels"]["left"], *rover.roles["wheels"]["right"]]
    first, last = msgs["/joint_states"][0][1], msgs["/joint_states"][-1][1]
    assert first.name[:4] == wheels and first.name[4:] == list(rover.roles["arm_joints"])
    assert np.all(np.abs(last.position[:4] - first.position[:4]) > 1.0)  # 0.3 m: > 1 rad
    base = m.body(rover.base).name
    _, tf = msgs["/tf"][-1]
    p, r = world_poses(tf)[base]
    state = truth.at[stamp_ns(tf)]
    assert np.allclose(p, state["xpos"][rover.base], atol=1e-9)
    assert np.linalg.norm(p[:2] - truth.at[min(truth.at)]["xpos"][rover.base][:2]) > 0.25


def test_rover_drive_records_and_replaces_only_its_own_recordings(mira, tmp_path):
    path = tmp_path / "drive.mcap"
    args = [str(mira), "--distance", "0.1", "--settle", "0.1", "--record", str(path)]
    res = CliRunner().invoke(rover_drive_command, args)
    assert res.exit_code == 0, res.output
    assert "recorded" in res.output and path.is_file()
    assert CliRunner().invoke(rover_drive_command, args).exit_code == 0  # ours: replaced
    path.write_text("someone else's file")
    res = CliRunner().invoke(rover_drive_command, args)
    assert res.exit_code != 0 and "not a recording of rover-drive" in str(
        res.exception or res.output
    )
    assert path.read_text() == "someone else's file"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp file left


def short_demo(folder: Path, tmp_path: Path) -> Path:
    """A waypoints file of one gripper step (open if closed, else close) and a short final
    wait, naming only what the facility's manifest names: the recording, not the demo's
    poses, is under test."""
    fac = load(folder)
    m = fac.model
    roles = fac.manifest.components["robot"].roles
    finger = roles["gripper"]["joints"][0]
    start = fac.data.qpos[m.jnt_qposadr[fac.joint(finger)]]
    shut = start > (roles["gripper"]["open"] + roles["gripper"]["closed"]) / 2
    action = "close" if shut else "open"
    bag = fac.manifest.components["ctb"].prefix
    named = (m.geom(g).name for g in range(m.ngeom) if m.geom_bodyid[g] == fac.body(bag))
    geom = next(n for n in named if n)
    spec = {
        "bag": {"body": bag, "geom": geom},
        "stowage": {"body": bag, "inside": [0.1, 0.1, 0.1]},
        "final_wait": 0.3,
        "steps": [{"name": action, "kind": "gripper", "action": action, "seconds": 0.5}],
    }
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_facility_demo_records_a_short_run(imetro, tmp_path, gl_context):
    waypoints = short_demo(imetro, tmp_path)
    roles = load(imetro).manifest.components["robot"].roles
    finger = roles["gripper"]["joints"][0]
    path = tmp_path / "demo.mcap"
    res = CliRunner().invoke(
        facility_demo_command, [str(imetro), "--waypoints", str(waypoints), "--record", str(path)]
    )
    assert res.exit_code in (0, 1), res.output  # the short demo stows nothing: it fails
    assert "recorded" in res.output
    msgs = read(path)
    stamps = [stamp_ns(msg) for _, msg in msgs["/joint_states"]]
    span = stamps[-1] - stamps[0]
    assert span >= ns(0.5), res.output  # the step at least (the final wait when it passed)
    assert len(stamps) == expected_count(span, 100)
    for role in roles["cameras"]:
        assert len(msgs[f"/{role}_camera/color/image_raw"]) == expected_count(span, 10)
    i = msgs["/joint_states"][0][1].name.index(finger)
    opening = [msg.position[i] for _, msg in msgs["/joint_states"]]
    assert abs(opening[-1] - opening[0]) > 0.005  # the gripper moved on the recording


def test_facility_demo_refuses_a_recording_it_cannot_write(imetro, tmp_path):
    waypoints = short_demo(imetro, tmp_path)
    other = tmp_path / "notes.mcap"
    other.write_text("not ours")
    for extra, message in (
        (["--record", str(tmp_path / "run.bag")], "must end in .mcap"),
        (["--record", str(other)], "not a recording of facility-demo"),
        (["--record", str(tmp_path / "x.mcap"), "--trials", "2"], "not --trials"),
    ):
        res = CliRunner().invoke(
            facility_demo_command, [str(imetro), "--waypoints", str(waypoints), *extra]
        )
        assert res.exit_code != 0
        assert message in (res.output + str(res.exception)), res.output
    assert other.read_text() == "not ours"
