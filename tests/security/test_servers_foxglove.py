"""The live Foxglove stream (``rover-drive --foxglove``) against a page of another site
and a rebound one in headless Chromium (they would read the stream, and a
``--foxglove-wait`` run would start for them), against clients that subscribe and
never read (each would hold the stream's messages in our memory), too many clients,
and a client whose messages are terminal escape codes (which we would print)."""

from __future__ import annotations

import base64
import json
import os
import socket
import time
from pathlib import Path

import pytest

from tests.security.hostile import EVIL, Served, Site, chromium, hostile_page, run
from urdf2mjcf.runner import foxglove_server
from urdf2mjcf.runner.foxglove_server import CLIENTS_MAX, QUEUE_BYTES, FoxgloveServer

websockets = pytest.importorskip("websockets")

SUBPROTOCOL = "foxglove.sdk.v1"
TIMEOUT = 120.0


@pytest.fixture(scope="module")
def mira(shipped_bundle) -> Path:
    return shipped_bundle("mira3d-floor")


ATTACK = """
const urls = %s;
const subscribe = JSON.stringify({ op: "subscribe",
  subscriptions: [1, 2, 3, 4, 5, 6, 7, 8].map((id) => ({ id, channelId: id })) });
const out = {};
for (const url of urls) out[url] = await socket(url, [subscribe], 3000, ["foxglove.sdk.v1"]);
return out;
"""

ESCAPES = [
    "\x1b]0;owned\x07\x1b[2J\x1b[31mred",
    '{"op": "\x1b[31msubscribe\x1b[0m"}',
    '{"op": "subscribe", "subscriptions": [{"id": "\x1b[1m", "channelId": 1}]}',
    '{"op": "advertise", "channels": [{"topic": "\x1b[5m"}]}',
    "[" * 10000,
]


def test_another_sites_page_gets_no_stream_and_starts_no_run(mira, tmp_path):
    served = Served(
        "rover-drive",
        str(mira),
        "--distance",
        "0.3",
        "--settle",
        "0",
        "--foxglove",
        "0",
        "--foxglove-wait",
        "--pace",
        "1000",
        address="streaming to Foxglove at ",
        cwd=tmp_path,
        stream="stderr",
    )
    try:
        with chromium() as browser:
            with hostile_page(browser) as page:
                urls = [f"ws://127.0.0.1:{served.port}/", f"ws://localhost:{served.port}/"]
                got = run(page, ATTACK % json.dumps(urls))
            with hostile_page(browser, served.port) as page:  # rebound onto the stream's port
                got.update(run(page, ATTACK % json.dumps([f"ws://{EVIL}:{served.port}/"])))
        for url, r in got.items():
            assert r["opened"] is False and r["messages"] == 0, (url, r)
        time.sleep(0.5)
        # the run still waits for a client of ours: it has driven nothing
        assert served.alive() and served.lines["stdout"] == [], served.lines
        # one of ours (a program: no Origin), sending escape codes before subscribing
        statuses, frames = [], 0
        import asyncio

        async def client() -> None:
            nonlocal frames
            url = f"ws://127.0.0.1:{served.port}/"
            async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
                channels: list[int] = []
                while not channels:
                    m = json.loads(await asyncio.wait_for(ws.recv(), TIMEOUT))
                    if m["op"] == "advertise":
                        channels = [c["id"] for c in m["channels"]]
                for bad in ESCAPES:
                    await ws.send(bad)
                await ws.send(b"\x05\x1b[31m")
                subs = [{"id": i, "channelId": c} for i, c in enumerate(channels)]
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                try:
                    while True:
                        m = await asyncio.wait_for(ws.recv(), TIMEOUT)
                        if isinstance(m, str):
                            statuses.append(json.loads(m))
                        elif m[0] == 1:
                            frames += 1
                except websockets.exceptions.ConnectionClosed:
                    pass

        asyncio.run(client())
        assert served.proc.wait(TIMEOUT) == 0
    finally:
        served.stop()
    errors = [s for s in statuses if s.get("op") == "status"]
    assert len(errors) == len(ESCAPES) + 1 and all(s["level"] == 2 for s in errors), statuses
    assert not any("\x1b" in s["message"] for s in errors)
    assert frames > 10  # the run streamed to the client it waited for
    assert "\x1b" not in served.stderr and "\x07" not in served.stderr, repr(served.stderr)
    assert "Traceback" not in served.stderr
    assert served.lines["stderr"][:2] == [
        f"streaming to Foxglove at ws://127.0.0.1:{served.port}",
        "waiting for a Foxglove client to subscribe",
    ], served.lines["stderr"]


def _handshake(
    port: int, origin: str | None = None, protocol: str = SUBPROTOCOL
) -> tuple[socket.socket, int]:
    """A client that opens the WebSocket by hand (and then reads only if it wants to):
    its socket, and the status the server answered."""
    s = socket.create_connection(("127.0.0.1", port), timeout=30)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # a client that reads slowly
    key = base64.b64encode(os.urandom(16)).decode()
    head = (
        f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
        f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
        + (f"Sec-WebSocket-Protocol: {protocol}\r\n" if protocol else "")
        + (f"Origin: {origin}\r\n" if origin else "")
        + "\r\n"
    )
    s.sendall(head.encode())
    answer = b""
    while b"\r\n\r\n" not in answer:
        chunk = s.recv(1)
        if not chunk:
            break
        answer += chunk
    return s, int(answer.split()[1]) if answer else 0


def _send_text(s: socket.socket, text: str) -> None:
    data, mask = text.encode(), os.urandom(4)
    assert len(data) < 126
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
    s.sendall(bytes([0x81, 0x80 | len(data)]) + mask + masked)


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_clients_that_never_read_hold_at_most_their_queue_and_the_count_is_bounded():
    server = FoxgloveServer(0, name="test")
    readers: list[socket.socket] = []
    try:
        ch = server.add_channel("/camera", "cdr", "sensor_msgs/msg/Image", "uint8[] data", "ros2msg")
        for _ in range(CLIENTS_MAX):
            s, status = _handshake(server.port)
            assert status == 101
            _send_text(s, json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": ch}]}))
            readers.append(s)
        deadline = time.monotonic() + 30
        while not server.watched(ch) or server.clients() < CLIENTS_MAX:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        one_more, status = _handshake(server.port)
        assert status == 503
        one_more.close()
        # 100 camera images of 1 MiB to each of the clients, which never read
        before = _rss()
        image = os.urandom(2**20)
        for t in range(100):
            assert server.log(ch, image, t) == CLIENTS_MAX
            time.sleep(0.002)
        time.sleep(1.0)
        grown = _rss() - before
        assert all(q <= QUEUE_BYTES for q in server.queued()), server.queued()
        # what we hold for them: their queues (and the socket buffers), not 100 MiB each
        assert grown < CLIENTS_MAX * (QUEUE_BYTES + 4 * 2**20), grown
    finally:
        for s in readers:
            s.close()
        server.stop()


def test_a_client_without_the_protocol_or_with_a_foreign_origin_is_refused():
    server = FoxgloveServer(0, name="test", origins={"https://app.foxglove.dev"})
    try:
        for origin, protocol, status in [
            (None, "", 400),  # no subprotocol: not a Foxglove client
            (None, "mqtt", 400),
            (f"http://{EVIL}", SUBPROTOCOL, 403),
            ("null", SUBPROTOCOL, 403),
            ("https://app.foxglove.dev.evil.test", SUBPROTOCOL, 403),
            ("https://app.foxglove.dev", SUBPROTOCOL, 101),  # named: answered
            ("https://APP.foxglove.dev:443", SUBPROTOCOL, 101),  # the same origin
            (None, "foxglove.websocket.v1", 101),
        ]:
            s, got = _handshake(server.port, origin, protocol)
            assert got == status, (origin, protocol, got)
            s.close()
    finally:
        server.stop()


def test_an_origin_the_user_names_is_answered_in_a_browser():
    """``--allow-origin`` opens the stream to that origin's pages (Foxglove's own app is
    one), and only to them."""
    site = Site()
    server = FoxgloveServer(0, name="test", origins={site.origin})
    try:
        server.add_channel("/joint_states", "cdr", "x", "", "ros2msg")
        with chromium() as browser:
            page = browser.new_page()
            page.goto(site.origin + "/")
            got = run(page, ATTACK % json.dumps([f"ws://127.0.0.1:{server.port}/"]))
            with hostile_page(browser) as other:  # another port: another origin
                refused = run(other, ATTACK % json.dumps([f"ws://127.0.0.1:{server.port}/"]))
    finally:
        server.stop()
        site.close()
    (r,) = got.values()
    assert r["opened"] and json.loads(r["text"][0])["op"] == "serverInfo", r
    (no,) = refused.values()
    assert no["opened"] is False


def test_nothing_a_client_sends_is_printed(capfd):
    server = FoxgloveServer(0, name="test")
    try:
        s, _ = _handshake(server.port)
        for bad in ("\x1b[31mx", '{"op":"\x1b]0;t\x07"}'):
            _send_text(s, bad)
        s.sendall(b"\x82\x80" + os.urandom(4))  # an empty binary message
        s.sendall(b"\xff\xff\x1b[2J")  # no frame at all
        time.sleep(0.5)
        s.close()
    finally:
        server.stop()
    out, err = capfd.readouterr()
    assert out == "" and err == "", (out, err)
    assert foxglove_server._quiet.level > 50  # websockets' own log of a client's doing
