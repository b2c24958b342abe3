"""``urdf2mjcf view``: the model served in MuJoCo's browser viewer, converted again when
the description changes, the last good model kept on an error; and the page, loaded in a
real headless browser, shows the robot.

The served model is read back as the browser reads it (``GET /model``: the viewer's
bundle, an MJB MuJoCo loads) and checked against the xacro's own numbers."""

from __future__ import annotations

import io
import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tests import browser
from urdf2mjcf import api
from urdf2mjcf.view.studio import Studio

STICK = """<?xml version="1.0"?>
<robot name="stick" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="length" default="{length}"/>
  <xacro:include filename="parts.xacro"/>
  <link name="base">
    <visual><geometry><box size="0.2 0.2 0.1"/></geometry></visual>
    <inertial><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <xacro:stick name="arm" length="$(arg length)"/>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.05"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
</robot>
"""
PARTS = """<?xml version="1.0"?>
<robot xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="stick" params="name length">
    <link name="${name}">
      <visual><origin xyz="0 0 ${length/2}"/>
        <geometry><cylinder radius="0.03" length="${length}"/></geometry>
        <material name="orange"><color rgba="1 0.4 0 1"/></material></visual>
      <inertial><origin xyz="0 0 ${length/2}"/><mass value="0.5"/>
        <inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    </link>
  </xacro:macro>
</robot>
"""
TIMEOUT = 120.0


def _write_stick(folder: Path, length: float) -> Path:
    (folder / "parts.xacro").write_text(PARTS)
    source = folder / "stick.urdf.xacro"
    source.write_text(STICK.format(length=length))
    return source


class Lines:
    """A child's output, line by line, read in a thread."""

    def __init__(self, stream: io.BufferedReader) -> None:
        self.q: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream: io.BufferedReader) -> None:
        for raw in stream:
            self.q.put(raw.decode().rstrip("\n"))

    def wait_for(self, start: str) -> str:
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            try:
                line = self.q.get(timeout=1)
            except queue.Empty:
                continue
            self.seen.append(line)
            if line.startswith(start):
                return line
        raise AssertionError(f"no line starting {start!r}; saw {self.seen}")


def at(url: str, path: str) -> str:
    """``path`` (``model``, ``state?sid=x``) of the viewer at ``url``, the address it
    printed: with the run's token, as the page's own requests carry it."""
    base, _, token = url.partition("?")
    return base + path + (("&" if "?" in path else "?") + token if token else "")


def served_model(url: str, tmp: Path) -> mujoco.MjModel:
    """The model the viewer serves to the browser, as MuJoCo loads it."""
    from mujoco.studio.web import state_payload

    bundle = urllib.request.urlopen(at(url, "model"), timeout=30).read()
    mjb, _textures = state_payload.parse_model_bundle(bundle)
    path = tmp / f"served-{time.monotonic_ns()}.mjb"
    path.write_bytes(mjb)
    return mujoco.MjModel.from_binary_path(str(path))


def _cylinder(m: mujoco.MjModel) -> int:
    (cyl,) = np.flatnonzero(m.geom_type == mujoco.mjtGeom.mjGEOM_CYLINDER)
    return int(cyl)


def _has_cylinder(m: mujoco.MjModel) -> bool:
    """The viewer serves its new model a moment after it loaded it (its own thread)."""
    return int(np.sum(m.geom_type == mujoco.mjtGeom.mjGEOM_CYLINDER)) == 1


def _half_length(m: mujoco.MjModel) -> float:
    return float(m.geom_size[_cylinder(m)][1])


def _centre_height(m: mujoco.MjModel) -> float:
    """The cylinder's centre above its body's frame: the xacro's origin z."""
    return float(m.geom_pos[_cylinder(m)][2])


def _served_when(url: str, tmp: Path, ready: Callable[[mujoco.MjModel], bool]) -> mujoco.MjModel:
    """The served model once ``ready(model)`` holds (the viewer loads a new model after
    the conversion line is printed), or the last one served after the timeout."""
    deadline = time.monotonic() + TIMEOUT
    while True:
        m = served_model(url, tmp)
        if ready(m) or time.monotonic() > deadline:
            return m
        time.sleep(0.2)


def _outward_address() -> str | None:
    """An address of this machine other than loopback (None where it has none): the
    source address of a route out, found without sending anything."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("10.255.255.255", 1))
            address = s.getsockname()[0]
    except OSError:
        return None
    return None if address.startswith("127.") or address == "0.0.0.0" else address


def test_view_serves_the_model_converts_again_on_change_and_keeps_the_last_good(tmp_path):
    source = _write_stick(tmp_path, 0.4)
    work_tmp = tmp_path / "tmp"
    work_tmp.mkdir()
    env = {**os.environ, "TMPDIR": str(work_tmp)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "urdf2mjcf", "view", str(source), "--no-browser", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    try:
        out, err = Lines(proc.stdout), Lines(proc.stderr)  # type: ignore[arg-type]
        assert out.wait_for("converted ") == (
            "converted stick: 2 links, 1 joints -> 2 bodies, 2 geoms, 0 meshes"
        )
        assert out.wait_for("certificate: ").startswith("certificate: passed")
        line = out.wait_for("viewing ")
        url = line.split(" at ")[1].split(" ")[0]
        assert url.startswith("http://localhost:") and "/?token=" in url

        page = urllib.request.urlopen(url, timeout=30)
        assert page.status == 200 and b"<canvas" in page.read()
        # loopback only: no other address of the machine answers
        port = int(url.split("/")[2].rsplit(":", 1)[1])
        other = _outward_address()
        if other is not None:
            with pytest.raises(OSError):
                socket.create_connection((other, port), timeout=5).close()
        # the xacro's length, as MuJoCo compiled the served model: a cylinder's half length
        m = _served_when(url, tmp_path, _has_cylinder)
        assert _half_length(m) == pytest.approx(0.2, abs=1e-12)

        # an argument's default changed: converted again, the page serves the new model
        source.write_text(STICK.format(length=0.8))
        assert out.wait_for("converted ").startswith("converted stick:")
        assert out.wait_for("certificate: ").startswith("certificate: passed")
        m = _served_when(url, tmp_path, lambda m: _has_cylinder(m) and _half_length(m) > 0.3)
        assert _half_length(m) == pytest.approx(0.4, abs=1e-12)
        assert _centre_height(m) == pytest.approx(0.4, abs=1e-12)

        # an included file broken: its error line, and the last good model stays up
        (tmp_path / "parts.xacro").write_text(PARTS.replace("${length/2}", "${length/2"))
        assert err.wait_for("error: ").startswith("error: ")
        assert _half_length(served_model(url, tmp_path)) == pytest.approx(0.4, abs=1e-12)

        # fixed again (the include is still watched): converted and shown
        (tmp_path / "parts.xacro").write_text(PARTS.replace("length/2", "length/4"))
        out.wait_for("converted ")
        m = _served_when(url, tmp_path, lambda m: _has_cylinder(m) and _centre_height(m) < 0.3)
        assert _centre_height(m) == pytest.approx(0.2, abs=1e-12)  # 0.8 / 4
        assert _half_length(m) == pytest.approx(0.4, abs=1e-12)
    finally:
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(30)
    assert code == 0
    assert list(work_tmp.iterdir()) == []  # the working folder is gone


def test_view_desktop_without_a_display_is_one_error_line(tmp_path):
    source = _write_stick(tmp_path, 0.4)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run(
        [sys.executable, "-m", "urdf2mjcf", "view", str(source), "--desktop"],
        capture_output=True,
        text=True,
        env=env,
        timeout=TIMEOUT,
    )
    assert res.returncode == 2
    assert res.stdout == ""
    (line,) = res.stderr.splitlines()
    assert line.startswith("error: ") and "no display" in line


def screenshot(page: object, url: str) -> np.ndarray:
    """The viewer's page once its model is loaded and drawn, as RGB pixels."""
    from PIL import Image

    loaded = threading.Event()
    page.on(  # type: ignore[attr-defined]
        "console", lambda m: "scene initialized successfully" in m.text and loaded.set()
    )
    page.goto(url)  # type: ignore[attr-defined]
    deadline = time.monotonic() + TIMEOUT
    while not loaded.is_set() and time.monotonic() < deadline:
        page.wait_for_timeout(250)  # type: ignore[attr-defined]
    assert loaded.is_set(), "the page never loaded the model"
    page.wait_for_timeout(1500)  # type: ignore[attr-defined]  # a few frames drawn
    png = page.screenshot()  # type: ignore[attr-defined]
    page.goto("about:blank")  # type: ignore[attr-defined]  # the viewer closes at once
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)


def orange(img: np.ndarray) -> np.ndarray:
    """Pixels of the stick's material (rgba 1 0.4 0), lit: red high, blue low."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 150) & (b < 40) & (r - g > 50) & (g > 40)


def test_the_page_shows_the_robot_in_a_real_browser(tmp_path):
    """The stick in the viewer against the same viewer serving the same scene without
    the robot: the robot's orange appears only where the robot is served."""
    source = _write_stick(tmp_path, 0.8)
    api.convert(source, tmp_path / "out" / "robot.xml")
    scene = tmp_path / "out" / "scene.xml"
    empty = scene.with_name("empty.xml")
    text = scene.read_text()
    assert '<include file="robot.xml"/>' in text
    empty.write_text(text.replace('<include file="robot.xml"/>', ""))
    shots = {}
    with browser.page(640, 480) as page:  # small: software WebGL draws every pixel
        for name, path in (("robot", scene), ("empty", empty)):
            with Studio() as studio:
                assert studio.load(path)
                assert studio.url is not None
                # served once the viewer has it: the floor (and the stick)
                want = _has_cylinder if name == "robot" else (lambda m: m.ngeom > 0)
                _served_when(studio.url, tmp_path, want)
                shots[name] = screenshot(page, studio.url)
    robot, bare = orange(shots["robot"]), orange(shots["empty"])
    assert bare.sum() == 0, "the empty scene has no orange"
    assert robot.sum() > 300, f"the robot covers {robot.sum()} pixels"
    # and the two pages differ where the robot is, not only somewhere
    differ = np.abs(shots["robot"] - shots["empty"]).sum(axis=2) > 60
    assert differ[robot].mean() > 0.9
