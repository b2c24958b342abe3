"""The runtime's one Sim: the demo's controller, the rovers and the environments step
through it, and stepping through it is the physics of a plain ``mujoco.mj_step`` loop
bit for bit (the controls it wrote replayed on a fresh MjData of the same scene);
its callbacks run in their documented order; its noise is SensorNoise's own draw."""

from __future__ import annotations

import copy
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import urdf2mjcf.envs  # noqa: F401  (registers the ids)
from urdf2mjcf.envs import build as env_build
from urdf2mjcf.runner.control import Controller
from urdf2mjcf.runner.demo import Demo, load_waypoints
from urdf2mjcf.runner.load import load
from urdf2mjcf.runner.noise import SensorNoise
from urdf2mjcf.runner.rover.sim import RoverSim
from urdf2mjcf.runner.sim import Sim

ROOT = Path(__file__).resolve().parents[2]
WAYPOINTS = ROOT / "recipes" / "demo" / "imetro.yaml"


@pytest.fixture(scope="session")
def bundles(_session_cache: Path) -> dict[str, Path]:
    """The iMETRO and MIRA3D floor facilities, built once per session in the cache the
    environments' tests build them in (a second session-scoped fixture finds them built)."""
    return {r: env_build.facility_folder(r, root=ROOT)[0] for r in ("imetro", "mira3d-floor")}


def _state(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    size = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION)
    out = np.empty(size)
    mujoco.mj_getState(m, d, out, mujoco.mjtState.mjSTATE_INTEGRATION)
    return out


def _plain(folder: Path, keyframe: str = "home") -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The scene compiled by MuJoCo alone, at its keyframe: the reference."""
    m = mujoco.MjModel.from_xml_path(str(folder / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key(keyframe).id)
    mujoco.mj_forward(m, d)
    return m, d


class _Tape:
    """A hook recording, after every physics step, the control that step ran with and
    the full physics state it left."""

    def __init__(self, sim: Sim):
        self.sim, self.ctrl, self.states = sim, [], []  # type: ignore[var-annotated]

    def __call__(self) -> None:
        self.ctrl.append(self.sim.d.ctrl.copy())  # mj_step never writes ctrl
        self.states.append(_state(self.sim.m, self.sim.d))

    def replay(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """The same controls through a plain mj_step loop: every state bit-identical."""
        assert self.states
        for k, (ctrl, want) in enumerate(zip(self.ctrl, self.states, strict=True)):
            d.ctrl[:] = ctrl
            mujoco.mj_step(m, d)
            got = _state(m, d)
            assert got.tobytes() == want.tobytes(), f"state differs after step {k + 1}"


def test_stepping_through_the_sim_is_a_plain_mj_step_loop(bundles):
    folder = bundles["imetro"]
    sim = Sim.open(folder)
    lo, hi = sim.m.actuator_ctrlrange.T
    k = [0]

    def control() -> None:  # a command that changes every step, inside the ranges
        k[0] += 1
        sim.d.ctrl[:] = lo + (hi - lo) * (0.5 + 0.4 * np.sin(0.05 * k[0] + np.arange(sim.m.nu)))

    sim.control.append(control)
    tape = _Tape(sim)
    sim.on_step.append(tape)
    sim.step(150)
    assert len(tape.states) == 150
    assert sim.time == pytest.approx(150 * sim.dt)
    tape.replay(*_plain(folder))

    # no callbacks: one mj_step(nstep=n), still the loop's physics
    sim.control.clear()
    sim.on_step.clear()
    ref_m, ref_d = _plain(folder)
    mujoco.mj_setState(ref_m, ref_d, _state(sim.m, sim.d), mujoco.mjtState.mjSTATE_INTEGRATION)
    ref_d.ctrl[:] = sim.d.ctrl
    sim.step(40)
    for _ in range(40):
        mujoco.mj_step(ref_m, ref_d)
    assert _state(sim.m, sim.d).tobytes() == _state(ref_m, ref_d).tobytes()


def test_callbacks_run_control_then_step_then_monitor_then_hooks(bundles):
    sim = Sim.open(bundles["imetro"])
    seen: list[tuple[str, float]] = []
    sim.control.append(lambda: seen.append(("control", sim.time)))
    sim.monitor.append(lambda: seen.append(("monitor", sim.time)))
    sim.on_step += [
        lambda: seen.append(("hook", sim.time)),
        lambda: seen.append(("hook2", sim.time)),
    ]
    t0, dt = sim.time, sim.dt
    sim.step(3)
    want = []
    for i in range(3):
        before, after = t0 + i * dt, t0 + (i + 1) * dt
        want += [("control", before), ("monitor", after), ("hook", after), ("hook2", after)]
    assert [s for s, _ in seen] == [s for s, _ in want]
    np.testing.assert_allclose([t for _, t in seen], [t for _, t in want], rtol=0, atol=1e-12)
    sim.step(0)
    assert len(seen) == 12


def test_reset_goes_back_to_the_keyframe(bundles):
    folder = bundles["imetro"]
    sim = Sim.open(folder)
    home = _state(sim.m, sim.d)
    sim.d.ctrl[:] = sim.m.actuator_ctrlrange[:, 1]
    sim.step(20)
    assert _state(sim.m, sim.d).tobytes() != home.tobytes()
    sim.reset("home")
    assert _state(sim.m, sim.d).tobytes() == _state(*_plain(folder)).tobytes()
    with pytest.raises(KeyError, match="no keyframe 'nowhere'"):
        sim.reset("nowhere")


def test_the_noise_is_sensor_noise_seeded_as_given(bundles):
    """The Sim's noise draws what SensorNoise made from the manifest draws, channel by
    channel; reseeding restarts every stream; without sensor noise it passes data through."""
    sim = Sim.open(bundles["imetro"], seed=7)
    ref = SensorNoise.from_manifest(sim.manifest, 7)
    assert sim.noise.config == ref.config and sim.noise.config  # the recipe has noise
    assert (sim.noise.gain, sim.noise.light_scale) == (ref.gain, ref.light_scale)
    f, t = np.array([1.0, -2.0, 3.0]), np.array([0.1, 0.2, -0.3])
    depth = np.full((6, 8), 1.5, np.float32)
    image = np.full((6, 8, 3), 120, np.uint8)
    for noise in (sim.noise, ref):
        noise.wrench(f, t)  # advance both the same way
    for a, b in zip(sim.noise.wrench(f, t), ref.wrench(f, t), strict=True):
        assert a.tobytes() == b.tobytes()
    assert sim.noise.depth(depth, 60.0).tobytes() == ref.depth(depth, 60.0).tobytes()
    assert sim.noise.rgb(image).tobytes() == ref.rgb(image).tobytes()
    assert not np.array_equal(sim.noise.wrench(f, t)[0], f)  # it does add noise

    sim.reseed(8)
    other = SensorNoise.from_manifest(sim.manifest, 8)
    assert sim.noise.force_bias.tobytes() == other.force_bias.tobytes()
    assert sim.noise.rgb(image).tobytes() == other.rgb(image).tobytes()

    ideal = Sim(sim.m, sim.d, sim.manifest, seed=7, sensor_noise=False)
    assert np.array_equal(ideal.noise.wrench(f, t)[0], f)
    assert ideal.noise.rgb(image) is image


def test_roles_and_cameras_come_from_the_bundle(bundles):
    import json

    folder = bundles["mira3d-floor"]
    sim = Sim.open(folder)
    manifest = json.loads((folder / "facility.json").read_text())
    want = {n: c["roles"] for n, c in manifest["components"].items() if c.get("roles")}
    assert {n: r.to_json() for n, r in sim.roles.items()} == want and want
    assert sorted(sim.cameras) == sorted(c["name"] for c in manifest["cameras"])
    for entry in manifest["cameras"]:
        cam = sim.cameras[entry["name"]]
        assert (cam.width, cam.height) == tuple(entry["resolution"])
        assert cam.fovy_deg == entry["fovy"]
        # MuJoCo's own focal length (pixels) of a camera of that fovy
        assert cam.focal == pytest.approx(
            entry["resolution"][1] / 2 / np.tan(np.radians(entry["fovy"]) / 2)
        )
    first = manifest["cameras"][0]
    small = sim.camera(first["name"], (33, 25))
    assert (small.width, small.height, small.fovy_deg) == (33, 25, first["fovy"])
    with pytest.raises(KeyError):
        sim.camera("no_such_camera")


def test_the_demo_steps_through_its_sim(bundles):
    """The demo's controller writes its targets as the Sim's control, its judge is the
    Sim's first monitor, its ``on_step`` is the Sim's hooks: a hook sees every step, after
    the judge, and the physics is a plain loop's."""
    folder = bundles["imetro"]
    fac = load(folder)
    demo = Demo(fac, load_waypoints(WAYPOINTS), log=lambda *_: None)
    try:
        assert isinstance(demo.sim, Sim) and demo.ctl.sim is demo.sim
        assert demo.ctl.on_step is demo.sim.on_step
        # the trial's noise: the facility's seed, as SensorNoise draws it
        ref = SensorNoise.from_manifest(fac.manifest, fac.manifest.seed or 0)
        assert demo.noise is demo.sim.noise
        assert demo.noise.force_bias.tobytes() == ref.force_bias.tobytes()
        order: list[str] = []
        judged = demo.ctl.monitor
        demo.ctl.monitor = lambda: (order.append("judge"), judged())  # type: ignore[func-returns-value]
        tape = _Tape(demo.sim)
        demo.ctl.on_step += [lambda: order.append("hook"), tape]
        goal = np.clip(demo.ctl.target + 0.05, fac.robot.lower, fac.robot.upper)
        demo.ctl.move_to(goal, duration=0.1)
        demo.ctl.wait(0.02)
        n = int(round(0.1 / demo.ctl.dt)) + int(round(0.02 / demo.ctl.dt))
        assert order == ["judge", "hook"] * n and len(tape.states) == n
        np.testing.assert_array_equal(tape.ctrl[-1][fac.robot.actuators], demo.ctl.target)
        tape.replay(*_plain(folder))
    finally:
        demo.close()


def test_a_controller_alone_makes_its_own_sim(bundles):
    fac = load(bundles["imetro"])
    ctl = Controller(fac, np.ones(len(fac.robot.joints)))
    assert isinstance(ctl.sim, Sim) and ctl.sim.m is fac.model and ctl.sim.d is fac.data
    other = Sim.open(bundles["imetro"])
    with pytest.raises(ValueError, match="own model and data"):
        Controller(fac, np.ones(len(fac.robot.joints)), sim=other)


def test_the_rovers_step_through_their_sim(bundles):
    """Arm targets as the Sim's control, odometry as its monitor (updated before any
    hook reads it), ``on_step`` its hooks; the physics a plain loop's."""
    folder = bundles["mira3d-floor"]
    rs = RoverSim(folder)
    assert isinstance(rs.sim, Sim) and rs.on_step is rs.sim.on_step
    assert rs.m is rs.sim.m and rs.d is rs.sim.d
    rover = rs.rover()
    # the hook integrates its own copy of the odometry from the same state: equal only
    # when the Sim's monitor has already integrated this step
    ref = copy.deepcopy(rs.odometry[rover.name])
    start = np.array(ref.fused, float)
    agree: list[bool] = []

    def check() -> None:
        ref.update(rover, rs.d, rs.dt)
        agree.append(ref.fused.tobytes() == rs.odometry[rover.name].fused.tobytes())

    tape = _Tape(rs.sim)
    rs.on_step += [check, tape]
    rs.arm_targets[rover.name] = rs.home[rover.name] + 0.05
    rs.drive(rover, 0.2, 0.1)
    rs.step(60)
    assert len(tape.states) == 60 and agree == [True] * 60
    assert np.linalg.norm(np.asarray(ref.fused) - start) > 1e-4  # it drove
    np.testing.assert_array_equal(tape.ctrl[0][rover.arm], rs.home[rover.name] + 0.05)
    rs.on_step.remove(check)
    rs.settle(0.02)  # a brake each step, through the same Sim
    assert len(tape.states) == 60 + int(round(0.02 / rs.dt))
    tape.replay(*_plain(folder))


def test_the_environment_steps_through_its_sim(bundles):
    """``frame_skip`` Sim steps per env step, each seen by a hook; the Sim's noise is the
    episode's, reseeded by the reset's jitter seed; the physics a plain loop's."""
    env = gym.make("Mira3D-v0", root=ROOT, facility=bundles["mira3d-floor"], frame_skip=5)
    try:
        u = env.unwrapped
        assert isinstance(u.sim, Sim) and u.sim.m is u.model and u.sim.d is u.data
        env.reset(seed=3)
        assert u.noise is u.sim.noise
        ref = SensorNoise.from_manifest(u.manifest, u.jitter_seed)
        assert u.noise.force_bias.tobytes() == ref.force_bias.tobytes()
        start = mujoco.MjData(u.model)
        mujoco.mj_copyData(start, u.model, u.data)
        tape = _Tape(u.sim)
        u.sim.on_step.append(tape)
        rng = np.random.default_rng(0)
        lo, hi = env.action_space.low, env.action_space.high
        for _ in range(4):
            env.step(lo + (hi - lo) * rng.random(lo.shape))
        assert len(tape.states) == 4 * 5
        tape.replay(u.model, start)
    finally:
        env.close()


def test_the_recorder_is_a_hook_of_the_sim(bundles, tmp_path):
    """A Recorder in a Sim's ``on_step`` records the state of the step it follows: read
    back with an independent reader (rosbags, ROS 2 Humble's definitions), every joint
    state's stamp is a stepped time and its positions the qpos of that step."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from urdf2mjcf.runner.record import Rates, Recorder, facility_sources

    fac = load(bundles["imetro"])
    m = fac.model
    ctl = Controller(fac, np.ones(len(fac.robot.joints)))
    path = tmp_path / "run.mcap"
    rates = Rates(tf=0.0, wrench=0.0, imu=0.0, images=0.0)
    rec = Recorder(m, fac.data, facility_sources(fac), path, rates=rates)
    truth: dict[int, np.ndarray] = {}
    ctl.sim.on_step += [
        rec.step,
        lambda: truth.update({round(ctl.sim.time * 1e9): fac.data.qpos.copy()}),
    ]
    goal = np.clip(ctl.target + 0.1, fac.robot.lower, fac.robot.upper)
    ctl.move_to(goal, duration=0.1)
    rec.close()
    assert len(truth) == int(round(0.1 / ctl.dt))

    humble = get_typestore(Stores.ROS2_HUMBLE)
    adr = {m.joint(j).name: int(m.jnt_qposadr[j]) for j in range(m.njnt)}
    stamps = []
    with Reader(path) as reader:
        for conn, _, raw in reader.messages():
            assert conn.topic == "/joint_states"
            msg = humble.deserialize_cdr(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            stamps.append(stamp)
            qpos = truth[stamp]
            assert list(msg.position) == [qpos[adr[n]] for n in msg.name]
    # the first step (the start), then every 10 ms (100 Hz) of the 0.1 s
    assert stamps[0] == min(truth) and len(stamps) == 11
    assert np.allclose(np.diff(stamps[1:]), 1e7, atol=1e3)
