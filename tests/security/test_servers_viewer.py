"""The browser viewer (``urdf2mjcf view``) against a page of another site, and against a
page that rebound its own name to 127.0.0.1, in headless Chromium: the page tries to
read the model (``/model``), to watch (``/state``) and to take the controller (``/ui``,
``force_control``), and to drop a model that names the user's own image by absolute
path, so that ``/model`` would serve its pixels. Each is refused or inert: nothing of
the user's reaches the page, the viewer keeps showing the command's model to the
user's own page only, and the image's pixels are nowhere in what it serves."""

from __future__ import annotations

import json
import struct
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.security.hostile import EVIL, Served, chromium, hostile_page, run

ROBOT = """<?xml version="1.0"?>
<robot name="box">
  <link name="base">
    <visual><geometry><box size="0.2 0.3 0.1"/></geometry></visual>
    <inertial><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
</robot>
"""


def _secret(folder: Path) -> tuple[Path, bytes]:
    """The user's own picture (outside any robot folder), and its pixels."""
    rng = np.random.default_rng(7)
    pixels = rng.integers(0, 256, (16, 16, 3), dtype=np.uint8)
    path = folder / "private" / "holiday.png"
    path.parent.mkdir()
    Image.fromarray(pixels).save(path)
    return path, pixels.tobytes()


def _dropped_model(secret: Path) -> list[bytes]:
    """The /drop frames of a model whose texture is the user's picture, by absolute path:
    ``[u32 name length][name][bytes]`` per file, then the empty end marker."""
    xml = f"""<mujoco><asset>
      <texture name="t" type="2d" file="{secret}"/><material name="m" texture="t"/>
    </asset><worldbody><geom type="box" size="1 1 1" material="m"/></worldbody></mujoco>"""
    name = b"evil.xml"
    return [struct.pack("<I", len(name)) + name + xml.encode(), b""]


def _get(url: str, **headers: str) -> tuple[int, bytes]:
    req = urllib.request.Request(url, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


class Roster:
    """The user's own page's view of who watches: the viewer's roster lines, read on
    ``/state`` with the run's token for as long as the test runs."""

    def __init__(self, served: Served) -> None:
        self.url = f"ws://localhost:{served.port}/state?sid=user&token={served.token}"
        self.origin = f"http://localhost:{served.port}"
        self.viewers: list[int] = []
        self.done, self.ready = threading.Event(), threading.Event()
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()
        assert self.ready.wait(60), "the user's page could not watch"

    def _read(self) -> None:
        from websockets.sync.client import connect

        with connect(self.url, max_size=None, origin=self.origin) as ws:  # type: ignore[arg-type]
            self.ready.set()
            while not self.done.is_set():
                try:
                    msg = ws.recv(timeout=0.5)
                except TimeoutError:
                    continue
                except Exception:  # noqa: BLE001 - the viewer closed
                    return
                if isinstance(msg, str) and msg.startswith("viewers="):
                    self.viewers.append(int(msg.split(";")[0].split("=")[1]))
                elif isinstance(msg, bytes):
                    ws.send("state_ack")

    def close(self) -> None:
        self.done.set()
        self.thread.join(5)


@pytest.fixture
def viewer(tmp_path: Path):
    source = tmp_path / "robot" / "box.urdf"
    source.parent.mkdir()
    source.write_text(ROBOT)
    served = Served(
        "urdf2mjcf",
        "view",
        str(source),
        "--no-browser",
        "--port",
        "0",
        address=" at ",
        cwd=tmp_path,
        stream="stdout",
    )
    try:
        yield served
    finally:
        code = served.stop()
        assert code == 0, served.stderr
        assert "Traceback" not in served.stderr


def _model(served: Served, tmp: Path) -> tuple[bytes, tuple]:
    """What the viewer serves the user's page (``/model``, with the token): the bundle's
    bytes and, as MuJoCo loads it, its bodies, geoms, textures and geom sizes, once it
    shows the command's robot (the viewer serves it a moment after it loaded it)."""
    import mujoco
    from mujoco.studio.web import state_payload

    deadline = time.monotonic() + 60
    while True:
        status, body = _get(f"{served.base}model?token={served.token}")
        assert status == 200
        mjb, _ = state_payload.parse_model_bundle(body)
        path = tmp / f"served-{time.monotonic_ns()}.mjb"
        path.write_bytes(mjb)
        m = mujoco.MjModel.from_binary_path(str(path))
        box = [tuple(s) for s in np.round(m.geom_size, 6)]
        if (0.1, 0.15, 0.05) in box or time.monotonic() > deadline:
            return body, (m.nbody, m.ngeom, m.ntex, tuple(box))
        time.sleep(0.2)


ATTACK = """
const [victim, frames] = [%s, %s];
const drop = frames.map((f) => Uint8Array.from(atob(f), (c) => c.charCodeAt(0)));
return {
  model: await read(`http://${victim}/model`),
  model_credentials: await read(`http://${victim}/model`, { credentials: "include" }),
  model_no_cors: await read(`http://${victim}/model`, { mode: "no-cors" }),
  page: await read(`http://${victim}/index.html`),
  state: await socket(`ws://${victim}/state?sid=evil`, ["request_control", "force_control"]),
  ui: await socket(`ws://${victim}/ui?sid=evil`),
  drop: await socket(`ws://${victim}/drop?sid=evil`, drop),
};
"""


def _frames(secret: Path) -> list[str]:
    import base64

    return [base64.b64encode(f).decode() for f in _dropped_model(secret)]


def _assert_refused(got: dict, same_origin: bool) -> None:
    for key in ("model", "model_credentials", "model_no_cors", "page"):
        r = got[key]
        if same_origin:  # the rebound page reads what we answer: our refusal, nothing else
            assert r["status"] == 403 and r["bytes"] < 200, (key, r)
        else:  # no CORS header: the browser lets the page read nothing
            assert "error" in r or (r["type"] == "opaque" and r["bytes"] == 0), (key, r)
    for key in ("state", "ui", "drop"):
        r = got[key]
        assert r["opened"] is False and r["messages"] == 0, (key, r)


@pytest.mark.parametrize("how", ["cross-origin", "dns-rebinding"])
def test_a_page_of_another_site_gets_nothing_from_the_viewer(viewer, tmp_path, how):
    secret, pixels = _secret(tmp_path)
    _, before = _model(viewer, tmp_path)
    roster = Roster(viewer)
    try:
        with chromium() as browser:
            port = viewer.port if how == "dns-rebinding" else None
            with hostile_page(browser, port) as page:
                victim = f"{EVIL}:{viewer.port}" if port else f"localhost:{viewer.port}"
                got = run(page, ATTACK % (json.dumps(victim), json.dumps(_frames(secret))))
                _assert_refused(got, same_origin=port is not None)
                if port is None:  # and the user's own address, by another name
                    got = run(
                        page,
                        ATTACK % (json.dumps(f"127.0.0.1:{viewer.port}"), json.dumps([])),
                    )
                    _assert_refused(got, same_origin=False)
        time.sleep(1.0)  # a drop that got through would be loaded by now
    finally:
        roster.close()
    # nobody joined the user's session, nothing was loaded, the picture is nowhere
    assert roster.viewers and max(roster.viewers) == 1, roster.viewers
    bundle, after = _model(viewer, tmp_path)
    assert after == before  # the robot in its scene, nothing dropped
    assert pixels not in bundle


def test_even_with_the_token_the_viewer_takes_no_dropped_model(viewer, tmp_path):
    """The user's own credentials (token and origin) do not open /drop: the viewer shows
    what the command line names, nothing a page sends."""
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    secret, pixels = _secret(tmp_path)
    _, before = _model(viewer, tmp_path)
    url = f"ws://localhost:{viewer.port}/drop?sid=user&token={viewer.token}"
    with pytest.raises(InvalidStatus) as refused:
        with connect(url, origin=f"http://localhost:{viewer.port}", open_timeout=30) as ws:
            for frame in _dropped_model(secret):
                ws.send(frame)
    assert refused.value.response.status_code == 403
    time.sleep(1.0)
    bundle, after = _model(viewer, tmp_path)
    assert after == before and pixels not in bundle


@pytest.mark.parametrize(
    "headers",
    [
        {"Host": f"{EVIL}:PORT"},  # a rebound name, even with the token
        {"Host": "localhost:1"},  # another port's name
        {"Origin": f"http://{EVIL}"},
        {"Origin": "null"},  # a sandboxed frame, a file: page
        {"Sec-Fetch-Site": "cross-site", "Cookie": "urdf2mjcf-PORT=TOKEN"},
    ],
    ids=["rebound-host", "other-port", "foreign-origin", "null-origin", "cross-site-cookie"],
)
def test_requests_a_browser_of_another_site_would_send_are_refused(viewer, headers):
    for path in ("model", "", "index.html"):
        sent = {k: v.replace("PORT", str(viewer.port)).replace("TOKEN", viewer.token)
                for k, v in headers.items()}  # fmt: skip
        token = "" if "Cookie" in sent else f"?token={viewer.token}"
        status, body = _get(f"http://localhost:{viewer.port}/{path}{token}", **sent)
        assert status == 403 and len(body) < 200, (path, sent, status)


def test_the_viewer_answers_its_own_page_without_wildcard_cors(viewer):
    status, body = _get(viewer.url)
    assert status == 200 and b"<canvas" in body
    req = urllib.request.Request(viewer.url)
    with urllib.request.urlopen(req, timeout=30) as r:
        headers = r.headers
    assert headers.get_all("Access-Control-Allow-Origin") is None
    assert headers["Cross-Origin-Resource-Policy"] == "same-origin"
    cookie = headers["Set-Cookie"]
    assert f"urdf2mjcf-{viewer.port}={viewer.token}" in cookie
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
    # the cookie alone lets the page's own requests in; no token, no cookie: refused
    own = {"Cookie": f"urdf2mjcf-{viewer.port}={viewer.token}", "Sec-Fetch-Site": "same-origin"}
    assert _get(f"{viewer.base}model", **own)[0] == 200
    assert _get(f"{viewer.base}model")[0] == 403
    assert _get(f"{viewer.base}model?token=x{viewer.token}")[0] == 403


PENDULUM = """<mujoco><worldbody><body name="bob" pos="0 0 1">
  <joint type="hinge" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
</body></worldbody></mujoco>"""

DROP = """
const frames = %s.map((f) => Uint8Array.from(atob(f), (c) => c.charCodeAt(0)));
const sid = (window.Module && Module.session_id) || "";
return await socket(`ws://${location.host}/drop?sid=${encodeURIComponent(sid)}`, frames, 3000);
"""


def test_a_drop_that_got_past_the_server_is_not_loaded(tmp_path):
    """The second wall: were /drop open (the guard left out of the viewer's process), the
    user's own page, the controller, drops a model naming the user's picture: the viewer
    refuses to load a file the command line did not name, and serves what it had."""
    import subprocess
    import sys

    from tests.security.hostile import SOCKET_ONLY

    secret, pixels = _secret(tmp_path)
    model = tmp_path / "pendulum.xml"
    model.write_text(PENDULUM)
    code = (
        "import sys; from urdf2mjcf.view import child, studio_guard; "
        "studio_guard.install = lambda gate: None; sys.exit(child.main(sys.argv[1:]))"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, "--port", "0"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    try:
        assert proc.stdin is not None and proc.stdout is not None
        url = proc.stdout.readline().decode().split()[1]
        proc.stdin.write(f"load {model}\n".encode())
        proc.stdin.flush()
        assert proc.stdout.readline().decode().startswith("loaded ")
        base = url.split("?")[0]

        def served() -> tuple[int, bytes]:
            import mujoco
            from mujoco.studio.web import state_payload

            body = urllib.request.urlopen(base + "model", timeout=30).read()
            path = tmp_path / f"m-{time.monotonic_ns()}.mjb"
            path.write_bytes(state_payload.parse_model_bundle(body)[0])
            return mujoco.MjModel.from_binary_path(str(path)).ngeom, body

        with chromium() as browser:
            page = browser.new_page()
            loaded = threading.Event()
            page.on("console", lambda m: "scene initialized" in m.text and loaded.set())
            page.goto(url)
            deadline = time.monotonic() + 120
            while not loaded.is_set() and time.monotonic() < deadline:
                page.wait_for_timeout(250)
            assert loaded.is_set(), "the page never loaded the model"
            ngeom, _ = served()
            page.add_script_tag(content=SOCKET_ONLY)
            sent = run(page, DROP % json.dumps(_frames(secret)))
            assert sent["opened"], sent  # the server took the drop: only the load is left
            page.wait_for_timeout(2000)
        after, bundle = served()
        assert after == ngeom and pixels not in bundle
    finally:
        proc.stdin.close()  # type: ignore[union-attr]
        proc.wait(30)
