"""The live Foxglove stream (``rover-drive --foxglove``, ``facility-demo --foxglove``)
read by a WebSocket client as Foxglove reads it: the advertised channels, a subscription,
the binary message frames decoded with rosbags' own ROS 2 Humble definitions, and
checked against the recording of the same run and against MuJoCo replaying the drive."""

from __future__ import annotations

import asyncio
import json
import struct
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from urdf2mjcf.command_runner import run_command
from urdf2mjcf.runner.cdr import encoder
from urdf2mjcf.runner.foxglove_live import FoxgloveStream
from urdf2mjcf.runner.load import load
from urdf2mjcf.runner.record import Recorder, facility_sources, msgdef
from urdf2mjcf.runner.rover.cli import rover_drive_command
from urdf2mjcf.runner.rover.sim import RoverSim
from urdf2mjcf.runner.rover.tasks import Straight

websockets = pytest.importorskip("websockets")

HUMBLE = get_typestore(Stores.ROS2_HUMBLE)
SUBPROTOCOL = "foxglove.sdk.v1"
"""What the Foxglove app offers first (our server speaks the older foxglove.websocket.v1 too)."""
DRIVE = ["--distance", "1", "--settle", "0.2"]
TIMEOUT = 120.0


@pytest.fixture(scope="module")
def mira(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-floor")


def command(main: str, *args: str) -> list[str]:
    return [sys.executable, "-c", f"from urdf2mjcf.cli import {main}; {main}()", *args]


async def _listen(url: str, topics: list[str] | None) -> tuple[dict, dict]:
    """Channels advertised (topic -> advertisement) and, per subscribed topic, the
    message frames (log time, payload) until the server closes the connection."""
    frames: dict[str, list[tuple[int, bytes]]] = {}
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        channels: dict[str, dict] = {}
        # Every topic has its channel when the address is printed: one advertisement.
        while not channels or not set(topics or ()) <= set(channels):
            m = json.loads(await asyncio.wait_for(ws.recv(), TIMEOUT))
            if m["op"] == "advertise":
                channels.update({c["topic"]: c for c in m["channels"]})
        wanted = list(channels) if topics is None else topics
        subs = {i: t for i, t in enumerate(wanted)}
        await ws.send(
            json.dumps(
                {
                    "op": "subscribe",
                    "subscriptions": [
                        {"id": i, "channelId": channels[t]["id"]} for i, t in subs.items()
                    ],
                }
            )
        )
        try:
            while True:
                m = await asyncio.wait_for(ws.recv(), TIMEOUT)
                if isinstance(m, bytes) and m[0] == 1:  # message data (2: the server's time)
                    sub, log_time = struct.unpack_from("<IQ", m, 1)
                    frames.setdefault(subs[sub], []).append((log_time, m[13:]))
        except websockets.exceptions.ConnectionClosed:
            pass  # the run ended: the server stopped
    return channels, frames


def stream(args: list[str], topics: list[str] | None = None) -> tuple[dict, dict, str]:
    """Run a command with ``--foxglove 0 --foxglove-wait``, listen to ``topics``
    (default: all); the channels, the frames and the command's stdout."""
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        assert line.startswith("streaming to Foxglove at ws://127.0.0.1:"), line
        channels, frames = asyncio.run(_listen(line.split()[-1], topics))
        out, err = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode in (0, 1), err
    return channels, frames, out


def stamp_ns(msg: object) -> int:
    s = msg.header.stamp  # type: ignore[attr-defined]
    return s.sec * 1_000_000_000 + s.nanosec


def recording(path: Path) -> dict[str, list[tuple[int, str, bytes]]]:
    """Topic -> (log time, type, CDR payload) of every message of an MCAP file."""
    out: dict[str, list[tuple[int, str, bytes]]] = {}
    with AnyReader([path]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, conn.msgtype, bytes(raw)))
    return out


@pytest.fixture(scope="module")
def live_drive(mira: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """rover-drive streaming (every topic subscribed) and recording the same run."""
    folder = tmp_path_factory.mktemp("live")
    args = command(
        "rover_drive_main",
        str(mira),
        *DRIVE,
        "--foxglove",
        "0",
        "--foxglove-wait",
        "--pace",
        "1000",
        "--record",
        str(folder / "live.mcap"),
        "--report",
        str(folder / "live.json"),
    )
    channels, frames, out = stream(args)
    return {"channels": channels, "frames": frames, "stdout": out, "folder": folder}


def test_the_stream_serves_the_recordings_topics_and_messages(live_drive: dict) -> None:
    recorded = recording(live_drive["folder"] / "live.mcap")
    channels, frames = live_drive["channels"], live_drive["frames"]
    assert set(channels) == set(recorded) >= {"/joint_states", "/tf", "/rover/imu/data"}
    for topic, ch in channels.items():
        datatype = recorded[topic][0][1]
        assert (ch["schemaName"], ch["encoding"], ch["schemaEncoding"]) == (
            datatype,
            "cdr",
            "ros2msg",
        )
        assert ch["schema"] == msgdef(datatype)
        # Every message of the run (the client subscribed before the drive began), the
        # same bytes at the same simulated times as the recording.
        assert [(t, payload) for t, _, payload in recorded[topic]] == frames[topic], topic


def test_joint_states_match_mujoco_replaying_the_drive(live_drive: dict, mira: Path) -> None:
    msgs = [
        (t, HUMBLE.deserialize_cdr(payload, "sensor_msgs/msg/JointState"))
        for t, payload in live_drive["frames"]["/joint_states"]
    ]
    stamps = [stamp_ns(m) for _, m in msgs]
    assert [t for t, _ in msgs] == stamps  # log time = header stamp = simulated time
    assert stamps[0] == 0 and all(b > a for a, b in zip(stamps, stamps[1:], strict=False))
    # The same drive, in MuJoCo here (settle, then 1 m straight), its state at every step.
    sim = RoverSim(mira)
    rover = next(iter(sim.rovers.values()))
    wheels = rover.roles["wheels"]
    names = [*wheels["left"], *wheels["right"], *rover.roles["arm_joints"]]
    adr = [sim.m.jnt_qposadr[sim.m.joint(n).id] for n in names]
    states = {0: sim.d.qpos[adr].copy()}
    sim.on_step.append(lambda: states.setdefault(round(sim.d.time * 1e9), sim.d.qpos[adr].copy()))
    sim.settle(0.2)
    sim.run({n: Straight(1.0, speed=0.5) for n in sim.rovers})
    end = round(sim.d.time * 1e9)
    assert stamps[-1] <= end < stamps[-1] + 10_000_000  # to the drive's end
    for _, m in msgs:  # at 100 Hz, each message the state at its stamp
        assert list(m.name) == names
        np.testing.assert_array_equal(m.position, states[stamp_ns(m)])
    moved = np.abs(np.array(msgs[-1][1].position) - msgs[0][1].position)
    assert moved[: len(wheels["left"]) + len(wheels["right"])].min() > 1.0  # rad: wheels turned


def test_streaming_changes_neither_the_run_nor_its_recording(live_drive: dict, mira: Path) -> None:
    folder = live_drive["folder"]
    alone = folder / "alone.mcap"
    args = [str(mira), *DRIVE, "--record", str(alone), "--report", str(folder / "alone.json")]
    res = CliRunner().invoke(rover_drive_command, args)
    assert res.exit_code == 0, res.output
    assert recording(alone) == recording(folder / "live.mcap")
    assert (folder / "alone.json").read_bytes() == (folder / "live.json").read_bytes()
    lines = lambda out: [x for x in out.splitlines() if not x.startswith("recorded ")]  # noqa: E731
    assert lines(res.output) == lines(live_drive["stdout"])


def test_a_missing_live_extra_is_one_error_line(
    mira: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setitem(sys.modules, "websockets", None)  # import websockets: ImportError
    report = tmp_path / "r.json"
    with pytest.raises(SystemExit) as exit:
        run_command(rover_drive_command, [str(mira), "--foxglove", "--report", str(report)])
    assert exit.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "error: rover-drive --foxglove needs the live extra: "
        "pip install 'mjcf-forge[live]' (missing: websockets)"
    ]
    assert not report.exists()


def test_bad_foxglove_options_are_refused(mira: Path, capsys: pytest.CaptureFixture) -> None:
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        for args, message in (
            (["--foxglove", "70000"], "70000"),
            (["--foxglove-wait"], "--foxglove-wait needs --foxglove"),
            (["--foxglove", str(port)], f"cannot serve on 127.0.0.1:{port}"),
        ):
            with pytest.raises(SystemExit) as exit:
                run_command(rover_drive_command, [str(mira), *DRIVE, *args])
            assert exit.value.code == 2, args
            err = capsys.readouterr().err
            assert message in err and err.startswith("error:"), err


def _every_type() -> dict[str, dict]:
    stamp = {"sec": 3, "nanosec": 5}
    head = {"stamp": stamp, "frame_id": "cam"}
    vec = {"x": 0.5, "y": -1.25, "z": 2.0}
    quat = {"x": 0.0, "y": 0.6, "z": 0.0, "w": 0.8}
    return {
        "sensor_msgs/msg/JointState": {
            "header": {"stamp": stamp, "frame_id": ""},
            "name": ["a", "bcd"],
            "position": [1.0, -2.0],
            "velocity": [0.5, 0.25],
            "effort": [],
        },
        "tf2_msgs/msg/TFMessage": {
            "transforms": [
                {
                    "header": {"stamp": stamp, "frame_id": "world"},
                    "child_frame_id": "base_link",
                    "transform": {"translation": vec, "rotation": quat},
                }
            ]
            * 2
        },
        "sensor_msgs/msg/Image": {
            "header": head,
            "height": 2,
            "width": 3,
            "encoding": "16UC1",
            "is_bigendian": 0,
            "step": 6,
            "data": bytes(range(12)),
        },
        "sensor_msgs/msg/CameraInfo": {
            "header": head,
            "height": 2,
            "width": 3,
            "distortion_model": "plumb_bob",
            "d": [0.0] * 5,
            "k": [float(i) for i in range(9)],
            "r": [1.0] * 9,
            "p": [float(i) for i in range(12)],
            "binning_x": 0,
            "binning_y": 1,
            "roi": {"x_offset": 1, "y_offset": 2, "height": 3, "width": 4, "do_rectify": True},
        },
        "geometry_msgs/msg/WrenchStamped": {
            "header": head,
            "wrench": {"force": vec, "torque": vec},
        },
        "sensor_msgs/msg/Imu": {
            "header": head,
            "orientation": quat,
            "orientation_covariance": [0.0] * 9,
            "angular_velocity": vec,
            "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": vec,
            "linear_acceleration_covariance": [0.0] * 9,
        },
    }


def _as_dict(value: object) -> object:
    """A rosbags message as plain Python (dicts, lists, bytes)."""
    if isinstance(value, np.ndarray):
        return value.tobytes() if value.dtype == np.uint8 else value.tolist()
    if hasattr(value, "__dataclass_fields__"):
        return {
            k: _as_dict(getattr(value, k))
            for k in value.__dataclass_fields__  # type: ignore[attr-defined]
            if k != "__msgtype__"
        }
    if isinstance(value, list):
        return [_as_dict(v) for v in value]
    return value


@pytest.mark.parametrize("datatype", list(_every_type()))
def test_cdr_encoding_is_what_ros2_humble_decodes(datatype: str) -> None:
    msg = _every_type()[datatype]
    payload = encoder(datatype, msgdef(datatype))(msg)
    back = _as_dict(HUMBLE.deserialize_cdr(payload, datatype))
    assert back == msg
    assert payload == HUMBLE.serialize_cdr(HUMBLE.deserialize_cdr(payload, datatype), datatype)


def test_cdr_fields_left_out_take_the_definitions_defaults() -> None:
    # The recorder leaves CameraInfo's binning and roi out; Quaternion's w defaults to 1.
    info = HUMBLE.deserialize_cdr(
        encoder("sensor_msgs/msg/CameraInfo", msgdef("sensor_msgs/msg/CameraInfo"))(
            {"height": 4, "k": [2.0] * 9}
        ),
        "sensor_msgs/msg/CameraInfo",
    )
    assert (info.height, info.binning_x, info.roi.do_rectify, info.header.frame_id) == (
        4,
        0,
        False,
        "",
    )
    assert info.k.tolist() == [2.0] * 9 and info.p.tolist() == [0.0] * 12 and len(info.d) == 0
    imu = HUMBLE.deserialize_cdr(
        encoder("sensor_msgs/msg/Imu", msgdef("sensor_msgs/msg/Imu"))({}), "sensor_msgs/msg/Imu"
    )
    assert (imu.orientation.x, imu.orientation.w) == (0.0, 1.0)


def _short_demo(folder: Path, tmp_path: Path) -> Path:
    """A demo of one gripper step (about 1 s simulated)."""
    fac = load(folder)
    roles = fac.manifest.components["robot"].roles
    bag = fac.manifest.components["ctb"].prefix
    m = fac.model
    named = (m.geom(g).name for g in range(m.ngeom) if m.geom_bodyid[g] == fac.body(bag))
    spec = {
        "bag": {"body": bag, "geom": next(n for n in named if n)},
        "stowage": {"body": bag, "inside": [0.1, 0.1, 0.1]},
        "final_wait": 0.3,
        "steps": [{"name": "open", "kind": "gripper", "action": "open", "seconds": 0.5}],
    }
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(spec))
    assert roles["cameras"]
    return path


@pytest.fixture(scope="module")
def imetro(imetro_bundle: Path) -> Path:
    return imetro_bundle


def test_facility_demo_streams_joints_images_and_wrench(imetro: Path, tmp_path: Path) -> None:
    waypoints = _short_demo(imetro, tmp_path)
    fac = load(imetro)
    roles = fac.manifest.components["robot"].roles
    topics = ["/joint_states", "/wrist_camera/color/image_raw", "/ft_frame/wrench"]
    args = command(
        "facility_demo_main",
        str(imetro),
        "--waypoints",
        str(waypoints),
        "--foxglove",
        "0",
        "--foxglove-wait",
        "--pace",
        "1000",
    )
    channels, frames, out = stream(args, topics)
    assert "recorded" not in out  # a stream, no file
    assert {"/tf", "/lift_camera/color/camera_info"} <= set(channels)
    joints = [HUMBLE.deserialize_cdr(p, "sensor_msgs/msg/JointState") for _, p in frames[topics[0]]]
    assert roles["gripper"]["joints"][0] in joints[0].name
    span = stamp_ns(joints[-1]) * 1e-9
    assert span >= 0.5 and len(joints) == int(span * 100 + 1e-6) + 1  # 100 Hz from 0
    images = [HUMBLE.deserialize_cdr(p, "sensor_msgs/msg/Image") for _, p in frames[topics[1]]]
    w, h = (int(x) for x in fac.model.cam_resolution[fac.robot.cameras["wrist"]])
    assert len(images) == int(span * 10 + 1e-6) + 1
    assert {(i.width, i.height, i.encoding, len(i.data)) for i in images} == {
        (w, h, "rgb8", w * h * 3)
    }
    assert np.ptp(images[-1].data) > 0  # a picture, not a blank
    wrench = HUMBLE.deserialize_cdr(frames[topics[2]][-1][1], "geometry_msgs/msg/WrenchStamped")
    assert wrench.header.frame_id == "ft_frame" and stamp_ns(wrench) == stamp_ns(joints[-1])


def test_a_stream_nobody_watches_builds_nothing(imetro: Path) -> None:
    fac = load(imetro)
    stream = FoxgloveStream(fac.data, 0, pace=None)
    try:
        rec = Recorder(fac.model, fac.data, facility_sources(fac), None, sinks=[stream])
        rec.step()  # the start: every topic, its channel made
        stream.start()
        for _ in range(round(0.25 / fac.model.opt.timestep)):
            mujoco.mj_step(fac.model, fac.data)
            rec.step()
        rec.close()
    finally:
        stream.close()
    # No client: after the start's, no message built, no camera rendered, nothing sent.
    assert {"/joint_states", "/tf", "/ft_frame/wrench", "/wrist_camera/color/image_raw"} <= set(
        rec.counts
    )
    assert set(rec.counts.values()) == {1}
    assert stream.sent == 0
