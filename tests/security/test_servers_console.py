"""The rover console (``rover-drive --console``) as an attacker meets it: a bundle whose
joint and camera names are markup that would latch the emergency stop if it ran,
opened in the console in headless Chromium; a page of another site, and one that
rebound its name to 127.0.0.1, reading the state and the cameras and posting the stop;
bad numbers, short bodies, unknown methods and a thousand idle connections sent
straight to the socket. The page stays inert, nothing of the user's reaches the other
page, every answer is JSON with a 4xx status, and the command prints nothing."""

from __future__ import annotations

import html
import json
import socket
import struct
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from tests.security.hostile import EVIL, Served, chromium, hostile_page, run

STOP = "fetch('/estop',{method:'POST'})"
PAYLOADS = {
    "ur_shoulder_pan_joint": f'<img src=x onerror="{STOP}">',
    "ur_shoulder_lift_joint": f'<svg onload="{STOP}"></svg>',
    "ur_elbow_joint": f"<script>{STOP}</script>",
    "ur_wrist_1_joint": f'"><img src=x onerror={STOP}>',
    "ur_wrist_2_joint": f"<iframe srcdoc=\"<script>parent.{STOP}</script>\"></iframe>",
    "ur_wrist_3_joint": f'<a id=estop href=# onclick="{STOP}">x</a>',
}
"""The collector's arm joints renamed: each name is markup that latches the stop if run."""
CAMERA = f'<img src=y onerror="{STOP}">'
"""A camera role renamed likewise (it is shown as the image's caption)."""


@pytest.fixture(scope="module")
def pair(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-pair")


def _renamed(value: object, names: dict[str, str]) -> object:
    if isinstance(value, str):
        for old, new in names.items():
            value = value.replace(old, new)
        return value
    if isinstance(value, list):
        return [_renamed(v, names) for v in value]
    if isinstance(value, dict):
        return {_renamed(k, names): _renamed(v, names) for k, v in value.items()}  # type: ignore[misc]
    return value


@pytest.fixture(scope="module")
def hostile_bundle(pair: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The pair as a stranger sends it: the same bundle, names changed to markup (in the
    MJCF, XML-escaped as a file holds them; in facility.json, as JSON)."""
    import shutil

    out = tmp_path_factory.mktemp("hostile") / "pair"
    shutil.copytree(pair, out)
    names = {f"collector_{j}": f"collector_{p}" for j, p in PAYLOADS.items()}
    scene = (out / "scene.xml").read_text()
    for old, new in names.items():
        scene = scene.replace(old, html.escape(new, quote=True))
    (out / "scene.xml").write_text(scene)
    manifest = json.loads((out / "facility.json").read_text())
    manifest = _renamed(manifest, names)
    cams = manifest["components"]["collector"]["roles"]["cameras"]  # type: ignore[index]
    cams[CAMERA] = cams.pop("rear")
    (out / "facility.json").write_text(json.dumps(manifest, indent=1))
    return out


def _console(bundle: Path, tmp: Path, *extra: str) -> Served:
    return Served(
        "rover-drive",
        str(bundle),
        "--console",
        "--port",
        "0",
        "--settle",
        "0",
        "--pace",
        "2",
        *extra,
        address="console at ",
        cwd=tmp,
        stream="stdout",
    )


def _call(served: Served, method: str, path: str, body: bytes | None = None, **headers: str):
    """(status, JSON answer) of a request with the run's token."""
    sep = "&" if "?" in path else "?"
    req = urllib.request.Request(
        f"{served.base}{path.lstrip('/')}{sep}token={served.token}", data=body, method=method
    )
    for k, v in headers.items():
        req.add_header(k.replace("_", "-"), v)
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            status, raw, kind = r.status, r.read(), r.headers.get("Content-Type")
    except urllib.error.HTTPError as e:
        status, raw, kind = e.code, e.read(), e.headers.get("Content-Type")
    assert kind == "application/json", (status, raw[:200])
    return status, json.loads(raw)


def _stopped(served: Served) -> list[bool]:
    status, state = _call(served, "GET", "state")
    assert status == 200
    return [r["estop"] for r in state["rovers"].values()]


def test_a_bundle_with_markup_in_its_names_runs_nothing_in_the_console(hostile_bundle, tmp_path):
    served = _console(hostile_bundle, tmp_path)
    try:
        with chromium() as browser:
            page = browser.new_page()
            page.goto(served.url)
            page.wait_for_function("() => document.querySelectorAll('#arm input').length == 6")
            page.wait_for_function(
                "() => [...document.querySelectorAll('#cameras img')]"
                ".every(i => i.dataset.frames >= 1)"
            )
            page.wait_for_timeout(1500)  # the page polls: markup that ran would have by now
            shown = page.eval_on_selector_all("#arm span", "s => s.map(x => x.textContent)")
            captions = page.eval_on_selector_all("figcaption", "c => c.map(x => x.textContent)")
            elements = page.evaluate(
                "() => [...document.querySelectorAll('#arm *, #cameras *')].map(e => e.tagName)"
            )
            assert page.evaluate("() => document.getElementById('estop').tagName") == "BUTTON"
        # the names are shown as they are, as text; no element of theirs is in the page
        assert shown == list(PAYLOADS.values())
        assert CAMERA in captions
        assert set(elements) == {"LABEL", "SPAN", "INPUT", "OUTPUT", "FIGURE", "IMG", "FIGCAPTION"}
        assert elements.count("IMG") == len(captions)  # the camera images, no other
        assert _stopped(served) == [False, False], "a name's script latched the stop"
        # the page's own policy: its script alone runs, and only the console is reached
        status, _ = _call(served, "GET", "rovers")
        with urllib.request.urlopen(served.url, timeout=60) as r:
            csp = r.headers["Content-Security-Policy"]
        assert "script-src 'sha256-" in csp and "unsafe-inline" not in csp
        assert "default-src 'none'" in csp and "frame-ancestors 'none'" in csp
    finally:
        code = served.stop()
    assert code == 0 and served.stderr == "", served.stderr


ATTACK = """
const victim = %s;
const stop = { method: "POST", body: "{}", headers: { "Content-Type": "text/plain" } };
return {
  state: await read(`http://${victim}/state`),
  state_credentials: await read(`http://${victim}/state`, { credentials: "include" }),
  rovers: await read(`http://${victim}/rovers`),
  page: await read(`http://${victim}/index.html`),
  estop: await read(`http://${victim}/estop`, stop),
  estop_no_cors: await read(`http://${victim}/estop`, { ...stop, mode: "no-cors" }),
  command: await read(`http://${victim}/command`, { ...stop,
    body: JSON.stringify({ rover: "collector", wheels: { left: 7, right: 7 } }) }),
  form: await form(`http://${victim}/estop`, { a: "b" }),
  camera: await image(`http://${victim}/camera/collector/stereo_left.png`),
  socket: await socket(`ws://${victim}/state`),
};
"""


@pytest.mark.parametrize("how", ["cross-origin", "dns-rebinding"])
def test_a_page_of_another_site_neither_reads_nor_drives_the_console(pair, tmp_path, how):
    served = _console(pair, tmp_path)
    try:
        _call(served, "POST", "command", b'{"rover": "printer", "wheels": {"left": 0, "right": 0}}')
        with chromium() as browser:
            port = served.port if how == "dns-rebinding" else None
            with hostile_page(browser, port) as page:
                for victim in (
                    [f"{EVIL}:{served.port}"]
                    if port
                    else [f"127.0.0.1:{served.port}", f"localhost:{served.port}"]
                ):
                    got = run(page, ATTACK % json.dumps(victim))
                    for key in ("state", "state_credentials", "rovers", "page", "estop", "command"):
                        r = got[key]
                        if port:  # same-origin after the rebinding: our refusal, nothing else
                            assert r["status"] == 403 and "rovers" not in r["text"], (key, r)
                            assert "error" in json.loads(r["text"]), (key, r)
                        else:
                            assert "error" in r, (key, r)  # no CORS: nothing readable
                    assert got["estop_no_cors"].get("bytes", 0) == 0 or port
                    assert got["camera"]["loaded"] is False and got["camera"]["width"] == 0
                    assert got["socket"]["opened"] is False
        assert _stopped(served) == [False, False], "another site's page latched the stop"
        _, state = _call(served, "GET", "state")
        assert state["rovers"]["collector"]["targets"]["wheels"] == {"left": 0.0, "right": 0.0}
    finally:
        code = served.stop()
    assert code == 0 and served.stderr == "", served.stderr


def _raw(served: Served, request: bytes, wait: float = 30) -> tuple[int, dict, float]:
    """(status, JSON answer, seconds) of bytes sent as they are on a new connection."""
    start = time.monotonic()
    with socket.create_connection(("127.0.0.1", served.port), timeout=wait) as s:
        s.sendall(request)
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    status = int(head.split()[1])
    assert b"Content-Type: application/json" in head, data[:300]
    return status, json.loads(body), time.monotonic() - start


def _post(served: Served, body: bytes, length: int | None = None) -> bytes:
    return (
        f"POST /command?token={served.token} HTTP/1.1\r\nHost: 127.0.0.1:{served.port}\r\n"
        f"Content-Type: application/json\r\nContent-Length: {len(body) if length is None else length}"
        "\r\n\r\n"
    ).encode() + body


NUMBERS = [
    "1" + "0" * 3999,  # 4,000 digits
    "-" + "9" * 400,
    "1e400",
    "-1e999",
    "1e300",  # finite, far beyond any speed
    "1" + "0" * 60 + ".5",
    "0." + "0" * 100 + "1",
    "NaN",
    "Infinity",
    "-Infinity",
    "1e-400",  # 0.0 in a float: fine as a number, but 400 characters is not
]


@pytest.mark.parametrize("field", ["wheels.left", "wheels.right", "arm"])
def test_every_bad_number_is_a_4xx_json_answer(pair, tmp_path, field):
    served = _console(pair, tmp_path)
    try:
        for n in NUMBERS:
            if field == "arm":
                body = f'{{"rover": "collector", "arm": {{"ur_elbow_joint": {n}}}}}'
            else:
                side, other = field.split(".")[1], "right" if field.endswith("left") else "left"
                body = f'{{"rover": "collector", "wheels": {{"{side}": {n}, "{other}": 0}}}}'
            status, answer, _ = _raw(served, _post(served, body.encode()))
            if n == "1e-400":  # a number of 6 characters: 0, set as it is
                assert status == 200, answer
                continue
            assert 400 <= status < 500 and set(answer) == {"error"}, (n[:20], status, answer)
            assert "internal" not in answer["error"]
        assert _stopped(served) == [False, False]
    finally:
        code = served.stop()
    assert code == 0 and served.stderr == "", served.stderr


def test_malformed_requests_are_4xx_json_answers(pair, tmp_path):
    served = _console(pair, tmp_path)
    try:
        # a body shorter than its Content-Length: refused when it does not come
        status, answer, took = _raw(served, _post(served, b'{"rover"', length=100))
        assert status == 408 and "Content-Length" in answer["error"], answer
        assert took < 9, "answered before the 10 s idle timeout"
        for request, expected in [
            (b"FOO /state HTTP/1.1\r\nHost: 127.0.0.1:PORT\r\n\r\n", 405),
            (b"GARBAGE\r\n\r\n", 400),
            (b"GET /state HTTP/1.1\r\nHost: 127.0.0.1:PORT\r\nX: " + b"y" * 70000 + b"\r\n\r\n", 431),
            (b"GET /state HTTP/9.9\r\nHost: 127.0.0.1:PORT\r\n\r\n", 505),
            (b"BREW /state HTTP/1.1\r\nHost: 127.0.0.1:PORT\r\n\r\n", 405),
            (b"PUT /state HTTP/1.1\r\nHost: 127.0.0.1:PORT\r\n\r\n", 405),
            (
                b"POST /command?token=TOKEN HTTP/1.1\r\nHost: 127.0.0.1:PORT\r\n"
                b"Content-Length: 5\r\nContent-Length: 7\r\n\r\n12345",
                400,
            ),
            (
                b"POST /command?token=TOKEN HTTP/1.1\r\nHost: 127.0.0.1:PORT\r\n"
                b"Content-Length: 99999999999999999999999\r\n\r\n",
                413,
            ),
        ]:
            request = request.replace(b"PORT", str(served.port).encode())
            request = request.replace(b"TOKEN", served.token.encode())
            status, answer, _ = _raw(served, request)
            assert status == expected and set(answer) == {"error"}, (request[:40], answer)
        assert _call(served, "GET", "state")[0] == 200
    finally:
        code = served.stop()
    assert code == 0 and served.stderr == "", served.stderr


def test_a_thousand_idle_connections_print_nothing_and_the_console_serves_on(pair, tmp_path):
    served = _console(pair, tmp_path)
    try:
        # a thousand connections that send half a request, wait, and are reset
        idle = []
        for _ in range(1000):
            s = socket.create_connection(("127.0.0.1", served.port), timeout=30)
            try:
                s.sendall(b"GET /state HTTP/1.1\r\nHost: 127.")
            except OSError:  # refused with 503 and closed at once
                pass
            idle.append(s)
        time.sleep(1.0)
        for s in idle:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            s.close()
        time.sleep(2.0)
        # the console serves on
        deadline = time.monotonic() + 30
        while True:
            try:
                status, _ = _call(served, "GET", "state")
            except (OSError, urllib.error.URLError):
                status = 0
            if status == 200 or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        assert status == 200
    finally:
        code = served.stop()
    assert code == 0
    assert served.stderr == "", served.stderr[:3000]


@pytest.fixture(scope="module")
def running(pair: Path):
    """The console served in this process (the same server the command runs)."""
    from urdf2mjcf.runner.rover import RoverSim
    from urdf2mjcf.runner.rover.console import Console
    from urdf2mjcf.runner.rover.console_sim import ConsoleSim

    sim = RoverSim(pair)
    with Console(ConsoleSim(sim, pace=2.0)) as c:
        yield c


def _json_values():
    from hypothesis import strategies as st

    numbers = st.one_of(
        st.integers(min_value=-(10**60), max_value=10**60),
        st.floats(allow_nan=True, allow_infinity=True),
        st.sampled_from(["1" + "0" * 4000, "1e400", "NaN", "-Infinity", "1e-400", "-0"]).map(
            lambda t: _Raw(t)
        ),
    )
    names = st.sampled_from(["rover", "wheels", "arm", "left", "right", "collector",
                             "printer", "ur_elbow_joint", "ur_shoulder_pan_joint", "x"])  # fmt: skip
    return st.recursive(
        st.one_of(st.none(), st.booleans(), numbers, st.text(max_size=20), names),
        lambda kids: st.one_of(
            st.lists(kids, max_size=4), st.dictionaries(st.one_of(names, st.text(max_size=8)),
                                                        kids, max_size=4)  # fmt: skip
        ),
        max_leaves=12,
    )


class _Raw(str):
    """A number written as it is (JSON has no NaN; a client sends it anyway)."""


def _dump(value: object) -> str:
    if isinstance(value, _Raw):
        return str(value)
    if isinstance(value, float) and value != value:
        return "NaN"
    if isinstance(value, dict):
        return "{" + ",".join(f"{json.dumps(str(k))}:{_dump(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ",".join(_dump(v) for v in value) + "]"
    if isinstance(value, float) and value in (float("inf"), float("-inf")):
        return "Infinity" if value > 0 else "-Infinity"
    return json.dumps(value)


def test_no_body_a_client_can_send_gets_an_internal_error(running):
    from hypothesis import given, settings
    from hypothesis import strategies as st

    bodies = st.one_of(
        _json_values().map(lambda v: _dump(v).encode()),
        st.fixed_dictionaries(
            {"rover": st.sampled_from(["collector", "printer"]), "wheels": _json_values(),
             "arm": _json_values()}  # fmt: skip
        ).map(lambda v: _dump(v).encode()),
        st.binary(max_size=64),
    )

    @settings(max_examples=300, deadline=None)
    @given(st.sampled_from(["command", "estop", "release", "state", "nowhere"]), bodies)
    def probe(path: str, body: bytes) -> None:
        req = urllib.request.Request(running.address(path), data=body, method="POST")
        try:
            with urllib.request.urlopen(req, timeout=60) as r:
                status, raw, kind = r.status, r.read(), r.headers["Content-Type"]
        except urllib.error.HTTPError as e:
            status, raw, kind = e.code, e.read(), e.headers["Content-Type"]
        assert kind == "application/json" and status < 500, (status, raw[:300])
        answer = json.loads(raw)
        assert status == 200 or set(answer) == {"error"}

    try:
        probe()
    finally:
        running.sim.release()
    assert running.sim.running and running.sim.error is None
