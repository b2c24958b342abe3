"""``rover-drive --console``: the browser console of a running MIRA3D simulation and its
HTTP/JSON API, checked against the simulation it serves: ``/state`` is MuJoCo's state,
wheel commands drive the rover (its true pose advances), arm commands move the joint,
the emergency stop brings the wheels to rest within 1 s of simulated time and holds
while commands keep coming, release restores control, bad requests are refused with a
JSON error and the simulation runs on, camera images are MuJoCo's renders of the
state they were taken at; the page in a real headless browser; the command line."""

from __future__ import annotations

import json
import math
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from io import BytesIO
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from PIL import Image

from tests import browser
from tests.test_view import Lines
from urdf2mjcf.command_runner import run_command
from urdf2mjcf.runner.rover import RoverSim, rover_drive_command
from urdf2mjcf.runner.rover.console import BODY_MAX, Console
from urdf2mjcf.runner.rover.console_sim import ConsoleSim

PACE = 4.0
"""Simulated seconds per wall-clock second in the tests: fast, yet light on the CPU."""
TIMEOUT = 120.0
"""Wall-clock seconds any wait may take (a loaded machine), never a measured figure."""
PAN = "ur_shoulder_pan_joint"


@pytest.fixture(scope="module")
def pair(shipped_bundle) -> Path:
    """The pair recipe (collector and printer on the Moon), built once."""
    return shipped_bundle("mira3d-pair")


@pytest.fixture
def console(pair: Path) -> Iterator[Console]:
    sim = RoverSim(pair)
    sim.settle(0.2)
    with Console(ConsoleSim(sim, pace=PACE)) as c:
        yield c


def call(c: Console, path: str, body: Any = None, method: str | None = None, **headers: str):
    """(status, parsed JSON or raw bytes, headers) of a request; ``body``: JSON, or bytes
    sent as they are."""
    data = body if isinstance(body, bytes) else None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(c.address(path), data=data, method=method)
    if data is not None:
        req.add_header("Content-Type", "application/json")
    for k, v in headers.items():
        req.add_header(k.replace("_", "-"), v)
    try:
        with urllib.request.urlopen(req, timeout=TIMEOUT) as r:
            status, raw, h = r.status, r.read(), r.headers
    except urllib.error.HTTPError as e:
        status, raw, h = e.code, e.read(), e.headers
    if h.get("Content-Type") == "application/json":
        assert raw.count(b"\n") == 1 and raw.endswith(b"\n"), "one line of JSON"
        return status, json.loads(raw), h
    return status, raw, h


def state(c: Console) -> dict:
    status, s, _ = call(c, "/state")
    assert status == 200
    return s


def wait_until(c: Console, t: float) -> dict:
    """The state once the simulated time has reached ``t``."""
    deadline = time.monotonic() + TIMEOUT
    while (s := state(c))["time"] < t:
        assert time.monotonic() < deadline, f"the simulation did not reach {t} s"
        time.sleep(0.05)
    return s


def test_state_is_the_simulations_state(console):
    console.sim.stop()  # frozen: what /state says is what MuJoCo holds now
    m, d = console.sim.sim.m, console.sim.sim.d
    s = state(console)
    assert s["time"] == d.time and set(s["rovers"]) == {"collector", "printer"}
    for name, r in s["rovers"].items():
        p = f"{name}_"
        base = d.body(p + "base_link")
        assert r["pose"]["xyz"] == pytest.approx(base.xpos, abs=1e-12)
        w, x, y, z = base.xquat
        assert r["pose"]["yaw"] == pytest.approx(
            math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        )
        assert r["imu"]["orientation"] == pytest.approx(d.sensor(p + "imu_link_orientation").data)
        assert r["imu"]["angular_velocity"] == pytest.approx(d.sensor(p + "imu_link_gyro").data)
        assert r["imu"]["linear_acceleration"] == pytest.approx(
            d.sensor(p + "imu_link_accelerometer").data
        )
        assert np.linalg.norm(r["imu"]["linear_acceleration"]) == pytest.approx(1.62, rel=0.02)
        left = np.mean(
            [d.sensor(p + f"{w}_left_wheel_joint_vel").data[0] for w in ("front", "rear")]
        )
        assert r["wheels"]["left"] == pytest.approx(left)
        assert set(r["arm"]) == {
            PAN,
            "ur_shoulder_lift_joint",
            "ur_elbow_joint",
            "ur_wrist_1_joint",
            "ur_wrist_2_joint",
            "ur_wrist_3_joint",
        }
        for joint, q in r["arm"].items():
            assert q == pytest.approx(d.joint(p + joint).qpos[0])
        # odometry started at the true pose a moment ago: still beside it
        assert r["odometry"]["xyz"][:2] == pytest.approx(r["pose"]["xyz"][:2], abs=0.01)
        assert r["estop"] is False
    info = call(console, "/rovers")[1]
    assert info["collector"]["cameras"] == [
        "stereo_left",
        "stereo_right",
        "rear",
        "left_wheel",
        "right_wheel",
        "arm",
    ]
    elbow = m.joint("collector_ur_elbow_joint").range
    assert info["collector"]["arm"]["ur_elbow_joint"] == pytest.approx(elbow)


def test_wheels_drive_forward_and_the_arm_follows_its_target(console):
    s0 = state(console)
    start = {n: r["pose"] for n, r in s0["rovers"].items()}
    target = s0["rovers"]["collector"]["targets"]["arm"][PAN] + 0.3
    status, done, _ = call(
        console,
        "/command",
        {"rover": "collector", "wheels": {"left": 3, "right": 3}, "arm": {PAN: target}},
    )
    assert status == 200 and done["clipped"] == [] and done["wheels"] == {"left": 3.0, "right": 3.0}
    s = wait_until(console, done["time"] + 2.0)
    c = s["rovers"]["collector"]
    moved = np.subtract(c["pose"]["xyz"], start["collector"]["xyz"])[:2]
    heading = start["collector"]["yaw"]  # east: the pair recipe's collector
    along = moved @ [math.cos(heading), math.sin(heading)]
    assert along > 0.8 and abs(moved @ [-math.sin(heading), math.cos(heading)]) < 0.1 * along
    assert c["wheels"]["left"] == pytest.approx(3.0, abs=0.3)
    # the wheel odometry counted the drive, and the slip of a sudden start on the Moon
    odo = np.subtract(c["odometry"]["xyz"], start["collector"]["xyz"])[:2]
    assert 0.9 * along < odo @ [math.cos(heading), math.sin(heading)] < 1.3 * along
    assert c["arm"][PAN] == pytest.approx(target, abs=0.02)
    # the other rover was not commanded: it stands where it stood
    p = np.subtract(s["rovers"]["printer"]["pose"]["xyz"], start["printer"]["xyz"])
    assert np.linalg.norm(p) < 0.005
    # out of range: clipped, and said so
    status, done, _ = call(
        console,
        "/command",
        {"rover": "collector", "wheels": {"left": 100, "right": -3}, "arm": {"ur_elbow_joint": 9}},
    )
    assert status == 200 and done["clipped"] == ["left", "ur_elbow_joint"]
    assert done["wheels"] == {"left": 7.5, "right": -3.0} and done["arm"][
        "ur_elbow_joint"
    ] == pytest.approx(math.pi)


def test_estop_stops_the_wheels_within_a_second_and_holds_until_released(console):
    status, done, _ = call(
        console, "/command", {"rover": "collector", "wheels": {"left": 3, "right": 3}}
    )
    s = wait_until(console, done["time"] + 1.5)
    assert s["rovers"]["collector"]["wheels"]["left"] > 2.5, "at speed (0.6 m/s)"
    status, stopped, _ = call(console, "/estop", {"rover": "collector"})
    assert status == 200 and stopped["rovers"] == ["collector"]
    t_stop = stopped["time"]
    refused: list[int] = []
    keep_going = threading.Event()

    def push() -> None:  # commands keep coming while it is stopped
        while not keep_going.is_set():
            refused.append(
                call(
                    console, "/command", {"rover": "collector", "wheels": {"left": 3, "right": 3}}
                )[0]
            )

    pusher = threading.Thread(target=push)
    pusher.start()
    try:
        states = [wait_until(console, t_stop + 1.0)]  # from 1 s after the stop to 2 s
        while states[-1]["time"] < t_stop + 2.0 or len(states) < 2:
            states.append(state(console))
        samples = [s["rovers"]["collector"] for s in states]
        at_rest, later = samples[0], samples[-1]
    finally:
        keep_going.set()
        pusher.join()
    assert refused and set(refused) == {409}
    assert all(r["estop"] is True for r in samples)
    # at rest: the wheels turn no more than the chassis rocks on its tyres in lunar
    # gravity (the wheel sensors measure against the chassis), a tenth of the 3 rad/s
    # they ran at; and the rover goes nowhere
    spin = max(max(abs(r["wheels"]["left"]), abs(r["wheels"]["right"])) for r in samples)
    assert spin < 0.3
    xy = np.array([r["pose"]["xyz"][:2] for r in samples])
    assert np.ptp(xy, axis=0).max() < 0.02
    # the arm held where it was
    for joint, q in later["arm"].items():
        assert q == pytest.approx(at_rest["arm"][joint], abs=0.005)
    assert call(console, "/estop", method="POST")[1]["rovers"] == ["collector", "printer"]
    status, released, _ = call(console, "/release", method="POST")
    assert status == 200 and released["estop"] is False
    status, done, _ = call(
        console, "/command", {"rover": "collector", "wheels": {"left": 3, "right": 3}}
    )
    assert status == 200
    again = wait_until(console, done["time"] + 1.0)["rovers"]["collector"]
    assert again["estop"] is False
    assert np.linalg.norm(np.subtract(again["pose"]["xyz"], later["pose"]["xyz"])) > 0.5


BAD = [
    ("bad JSON", "/command", b"{oops", 400),
    ("NaN", "/command", b'{"rover": "collector", "wheels": {"left": NaN, "right": 0}}', 400),
    ("overflow", "/command", b'{"rover": "collector", "wheels": {"left": 1e999, "right": 0}}', 400),
    ("a list", "/command", [1, 2], 400),
    ("unknown rover", "/command", {"rover": "nobody", "wheels": {"left": 1, "right": 1}}, 404),
    ("no rover named", "/command", {"wheels": {"left": 1, "right": 1}}, 404),
    ("unknown joint", "/command", {"rover": "printer", "arm": {"elbow": 1}}, 400),
    ("a bool speed", "/command", {"rover": "printer", "wheels": {"left": True, "right": 1}}, 400),
    ("a string", "/command", {"rover": "printer", "arm": {PAN: "1"}}, 400),
    ("one side", "/command", {"rover": "printer", "wheels": {"left": 1}}, 400),
    ("unknown key", "/command", {"rover": "printer", "speed": 1}, 400),
    ("nothing to do", "/command", {"rover": "printer"}, 400),
    ("deep", "/command", b"[" * 5000 + b"]" * 5000, 400),
    ("too large", "/command", b" " * (BODY_MAX + 1), 413),
    ("estop of nobody", "/estop", {"rover": "nobody"}, 404),
    ("unknown path", "/nowhere", {}, 404),
]


@pytest.mark.parametrize("case", BAD, ids=[b[0] for b in BAD])
def test_bad_requests_get_a_json_error_and_the_simulation_runs_on(console, case):
    _, path, body, expected = case
    t0 = state(console)["time"]
    status, answer, _ = call(console, path, body)
    assert status == expected and set(answer) == {"error"} and answer["error"], answer
    wait_until(console, t0 + 0.2)  # still stepping
    assert console.sim.running and console.sim.error is None


def test_bad_requests_of_other_kinds(console):
    for path, method, headers, expected in [
        ("/nowhere", "GET", {}, 404),
        ("/camera/collector/nope.png", "GET", {}, 404),
        ("/camera/nobody/rear.png", "GET", {}, 404),
        ("/state", "PUT", {}, 405),
        ("/state", "GET", {"Host": "evil.example:80"}, 403),
    ]:
        status, answer, _ = call(console, path, method=method, **headers)
        assert status == expected and set(answer) == {"error"}, (path, answer)
    status, answer, _ = call(console, "/release", {}, Origin="http://evil.example")
    assert status == 403 and "origin" in answer["error"]
    assert console.sim.running and console.sim.error is None


def test_camera_images_are_renders_of_the_state_they_were_taken_at(console, gl_context):
    sim = console.sim.sim
    sig = mujoco.mjtState.mjSTATE_FULLPHYSICS
    size = mujoco.mj_stateSize(sim.m, sig)
    states: dict[float, np.ndarray] = {}

    def keep() -> None:  # every step's state, by its time (called under the console's lock)
        s = np.empty(size)
        mujoco.mj_getState(sim.m, sim.d, s, sig)
        states[float(sim.d.time)] = s
        if len(states) > 20_000:
            del states[next(iter(states))]

    sim.on_step.append(keep)
    done = call(console, "/command", {"rover": "printer", "wheels": {"left": -2, "right": 2}})[1]
    wait_until(console, done["time"] + 0.1)  # every state from here on is kept
    d = mujoco.MjData(sim.m)
    for rover, camera in [("printer", "stereo_left"), ("collector", "arm")]:
        status, png, headers = call(console, f"/camera/{rover}/{camera}.png")
        assert status == 200 and headers["Content-Type"] == "image/png"
        got = np.asarray(Image.open(BytesIO(png)).convert("RGB"))
        when = float(headers["X-Sim-Time"])
        mujoco.mj_setState(sim.m, d, states[when], sig)
        mujoco.mj_forward(sim.m, d)
        h, w = got.shape[:2]
        sensor = (1280, 720) if camera == "stereo_left" else (752, 480)  # docs/mira3d.md
        assert (w, h) == (320, round(320 * sensor[1] / sensor[0])), "the sensor's aspect"
        with mujoco.Renderer(sim.m, h, w) as r:
            r.update_scene(d, camera=sim.rovers[rover].roles["cameras"][camera])
            expected = r.render()
        diff = np.abs(got.astype(int) - expected.astype(int))
        assert diff.mean() < 0.5 and np.mean(diff > 8) < 0.001, (rover, camera, diff.mean())
        assert expected.std() > 5, "an image, not a blank"


def test_the_page_drives_the_rover_and_stops_it(console, tmp_path):
    with browser.page(1280, 900) as page:
        page.goto(console.url)
        page.wait_for_function("() => document.querySelectorAll('#arm input').length == 6")
        assert page.eval_on_selector("#rover", "s => [...s.options].map(o => o.value)") == [
            "collector",
            "printer",
        ]
        start = state(console)["rovers"]["collector"]
        page.evaluate(
            """() => { for (const id of ["left", "right"]) {
                   const s = document.getElementById(id); s.value = 3;
                   s.dispatchEvent(new Event("input")); } }"""
        )
        pan = start["targets"]["arm"][PAN] - 0.4
        page.evaluate(
            f"""() => {{ const s = document.querySelector('input[data-joint="{PAN}"]');
                  s.value = {pan}; s.dispatchEvent(new Event("input")); }}"""
        )
        deadline = time.monotonic() + TIMEOUT
        while state(console)["rovers"]["collector"]["targets"]["wheels"]["right"] != 3:
            assert time.monotonic() < deadline, "the page sent no wheel command"
            time.sleep(0.05)
        moved = wait_until(console, state(console)["time"] + 1.5)["rovers"]["collector"]
        assert moved["pose"]["xyz"][0] - start["pose"]["xyz"][0] > 0.5, "drove east"
        assert moved["arm"][PAN] == pytest.approx(pan, abs=0.05)
        # the page shows the cameras the rover has, as the API serves them
        page.wait_for_function(
            "() => (imgs => imgs.length == 6 && imgs.every(i => i.dataset.frames >= 2))"
            "([...document.querySelectorAll('#cameras img')])"
        )
        srcs = page.eval_on_selector_all("#cameras img", "imgs => imgs.map(i => i.dataset.camera)")
        assert srcs == call(console, "/rovers")[1]["collector"]["cameras"]
        page.wait_for_function("() => document.getElementById('time').textContent != '-'")
        page.screenshot(path=str(tmp_path / "console.png"))
        page.click("#estop")
        deadline = time.monotonic() + TIMEOUT
        while not all(r["estop"] for r in state(console)["rovers"].values()):
            assert time.monotonic() < deadline, "the stop button did nothing"
            time.sleep(0.05)
        page.wait_for_function(
            "() => document.getElementById('banner').textContent.includes('STOP')"
        )
        page.click("#release")
        deadline = time.monotonic() + TIMEOUT
        while any(r["estop"] for r in state(console)["rovers"].values()):
            assert time.monotonic() < deadline, "release did nothing"
            time.sleep(0.05)
    assert (tmp_path / "console.png").stat().st_size > 10_000


def test_a_drag_of_the_slider_leaves_the_last_value_commanded(console):
    """A drag sends a command per step; sent together, they wait on the simulation's lock
    and the last to get it wins, often a stale speed. The page sends them one by one."""
    steps = [round(0.1 * k, 1) for k in range(1, 41)]
    with browser.page(1280, 900) as page:
        page.goto(console.url)
        page.wait_for_function("() => document.querySelectorAll('#arm input').length == 6")
        answered: list[str] = []
        page.on("requestfinished", lambda r: "/command" in r.url and answered.append(r.url))
        with console.sim.lock:  # the simulation busy: commands sent together would queue
            page.evaluate(
                f"""() => {{ const s = document.getElementById("right");
                       for (const v of {steps}) {{ s.value = v; s.dispatchEvent(new Event("input")); }} }}"""
            )
            page.wait_for_timeout(500)
        deadline = time.monotonic() + TIMEOUT
        while len(answered) < len(steps):
            assert time.monotonic() < deadline, f"{len(answered)} of {len(steps)} answered"
            page.wait_for_timeout(50)
        seen = state(console)["rovers"]["collector"]["targets"]["wheels"]["right"]
    assert seen == steps[-1]


def _command(*args: str) -> list[str]:
    code = "from urdf2mjcf.cli import rover_drive_main; rover_drive_main()"
    return [sys.executable, "-c", code, *args]


def test_the_command_line_serves_until_sigterm_and_exits_0(pair):
    proc = subprocess.Popen(
        _command(str(pair), "--console", "--port", "0", "--settle", "0", "--pace", "2"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        line = Lines(proc.stdout).wait_for("console at ")  # type: ignore[arg-type]
        url = line.split()[2]
        assert url.startswith("http://127.0.0.1:") and "/?token=" in url
        base, token = url.split("?")
        with urllib.request.urlopen(f"{base}state?{token}", timeout=TIMEOUT) as r:
            assert set(json.load(r)["rovers"]) == {"collector", "printer"}
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(TIMEOUT) == 0
        assert proc.stderr.read() == b""  # type: ignore[union-attr]
    finally:
        proc.kill()
        proc.wait()


def test_bad_console_options_are_one_error_line(pair, capsys):
    bad = subprocess.run(
        _command(str(pair), "--console", "--pace", "0"), capture_output=True, timeout=TIMEOUT
    )
    lines = bad.stderr.decode().splitlines()
    assert bad.returncode == 2 and len(lines) == 1, lines
    assert lines[0].startswith("error:") and "--pace" in lines[0] and bad.stdout == b""
    with socket.socket() as taken:  # a port in use
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        for args, needle in [
            (["--console", "--distance", "3"], "--distance"),
            (["--port", "8080"], "--port is for --console"),
            (["--console", "--port", "70000"], "--port"),
            (["--console", "--port", str(port), "--settle", "0"], f"--port {port}"),
            (["--console", "--rover", "nobody"], "no rover 'nobody'"),
        ]:
            with pytest.raises(SystemExit) as done:  # as the command runs, in this process
                run_command(rover_drive_command, [str(pair), *args], prog_name="rover-drive")
            out, err = capsys.readouterr()
            assert done.value.code == 2 and out == "", (args, out, err)
            assert err.startswith("error:") and err.count("\n") == 1 and needle in err, (args, err)
