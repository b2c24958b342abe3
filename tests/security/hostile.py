"""A web page of another site, in a real headless browser, against our local servers.

``evil.test`` is the attacker's site: Chromium resolves it to 127.0.0.1 (its
``--host-resolver-rules``), as a site that rebinds its name to the loopback address
does. :func:`hostile_page` opens the attacker's page at ``http://evil.test:PORT/``:
with ``port`` one of our servers' own, the page is the attacker's (its document
answered by the browser's router, as the attacker's server answered it before the
rebinding) and every later request of the page goes to our server, same-origin,
with ``Host: evil.test:PORT``; without, the page is served by :class:`Site` on a port
of its own, and reaches our servers cross-origin. The page's script is the test's;
``page.evaluate`` runs the attack and returns what the page got.
"""

from __future__ import annotations

import contextlib
import json
import re
import socket
import tempfile
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import pytest

from tests import browser

EVIL = "evil.test"

SOCKET_ONLY = """
// What a WebSocket to `url` gives the page within `ms`: did it open, what came, and
// what happened to what it sent (`send`: messages sent once it opens).
function socket(url, send = [], ms = 3000, protocols = undefined) {
  return new Promise((done) => {
    const got = { opened: false, messages: 0, bytes: 0, text: [], closed: null };
    let ws;
    try { ws = new WebSocket(url, protocols); } catch (e) { got.error = String(e); done(got); return; }
    ws.binaryType = "arraybuffer";
    ws.onopen = () => { got.opened = true; for (const m of send) ws.send(m); };
    ws.onmessage = (e) => {
      got.messages++;
      if (typeof e.data === "string") { got.bytes += e.data.length; got.text.push(e.data.slice(0, 200)); }
      else got.bytes += e.data.byteLength;
    };
    ws.onclose = (e) => { got.closed = e.code; };
    setTimeout(() => { try { ws.close(); } catch (e) {} done(got); }, ms);
  });
}
"""
"""The attacker's WebSocket probe, alone (to add to a page)."""

HELPERS = """
<!doctype html><title>a page of another site</title>
<script>
""" + SOCKET_ONLY + """
// What a fetch of `url` lets the page read.
async function read(url, init = {}) {
  try {
    const r = await fetch(url, init);
    const body = new Uint8Array(await r.arrayBuffer());
    return { status: r.status, type: r.type, bytes: body.length,
             text: new TextDecoder().decode(body.slice(0, 300)) };
  } catch (e) { return { error: e.name }; }
}
// Whether an <img> of `url` loads (and its size, which a page can read).
function image(url) {
  return new Promise((done) => {
    const img = new Image();
    img.onload = () => done({ loaded: true, width: img.naturalWidth, height: img.naturalHeight });
    img.onerror = () => done({ loaded: false, width: img.naturalWidth });
    img.src = url;
    setTimeout(() => done({ loaded: null }), 5000);
  });
}
// A form posted to `url` (into a frame), as any page can without script.
function form(url, fields) {
  return new Promise((done) => {
    const frame = document.createElement("iframe"); frame.name = "sink" + Math.random();
    document.body.append(frame);
    const f = document.createElement("form");
    Object.assign(f, { method: "POST", action: url, target: frame.name, enctype: "text/plain" });
    for (const [k, v] of Object.entries(fields)) {
      const i = document.createElement("input"); i.name = k; i.value = v; f.append(i);
    }
    document.body.append(f);
    frame.onload = () => done(true);
    f.submit();
    setTimeout(() => done(false), 5000);
  });
}
</script>
"""
"""The attacker's tools, the page's only content."""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Site:
    """The attacker's own web server (127.0.0.1, a port of its own), serving the page."""

    def __init__(self) -> None:
        page = HELPERS.encode()

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802
                self.send_response(200)
                self.send_header("Content-Type", "text/html")
                self.send_header("Content-Length", str(len(page)))
                self.end_headers()
                self.wfile.write(page)

            def log_message(self, *args: Any) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.port = int(self.server.server_address[1])
        self.origin = f"http://{EVIL}:{self.port}"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@contextlib.contextmanager
def chromium() -> Iterator[Any]:
    """A headless Chromium that resolves evil.test to 127.0.0.1 (a fresh profile: none
    of the user's cookies), without its own guard of the loopback; skips the test
    where no browser can start."""
    exe = browser.chromium_path()
    if exe is None:
        pytest.skip("no browser: Debian's chromium is not installed (apt install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("no browser driver: playwright is not installed (the test extra has it)")
    args = [
        *browser.CHROMIUM_FLAGS,
        f"--host-resolver-rules=MAP {EVIL} 127.0.0.1",
        # Chromium's own guard of the loopback (Private/Local Network Access) off: other
        # browsers have none, and the test is of our servers, not of Chromium.
        "--disable-features=BlockInsecurePrivateNetworkRequests,"
        "PrivateNetworkAccessSendPreflights,PrivateNetworkAccessRespectPreflightResults,"
        "LocalNetworkAccessChecks,LocalNetworkAccessChecksWebSockets",
    ]
    with sync_playwright() as pw, tempfile.TemporaryDirectory() as profile:
        try:
            context = pw.chromium.launch_persistent_context(
                profile, executable_path=exe, headless=True, args=args
            )
        except Exception as exc:  # no display libraries, a sandbox refusal, ...
            pytest.skip(f"the browser did not start: {str(exc).splitlines()[0]}")
        try:
            yield context
        finally:
            context.close()


@contextlib.contextmanager
def hostile_page(context: Any, port: int | None = None) -> Iterator[Any]:
    """The attacker's page: at ``http://evil.test:PORT/`` rebound onto our server on
    ``port``, or, without ``port``, on the attacker's own server."""
    site = None
    page = context.new_page()
    try:
        if port is None:
            site = Site()
            page.goto(f"{site.origin}/")
        else:
            url = f"http://{EVIL}:{port}/"
            # The page came from the attacker's server; from now on the name is 127.0.0.1.
            page.route(
                re.compile(re.escape(url) + r"(\?.*)?$"),
                lambda route: route.fulfill(status=200, content_type="text/html", body=HELPERS),
            )
            page.goto(url)
        yield page
    finally:
        page.close()
        if site is not None:
            site.close()


def run(page: Any, script: str) -> Any:
    """The attack's result: ``script`` is the body of an async function of the page."""
    return json.loads(page.evaluate(f"(async () => JSON.stringify(await (async () => {{{script}}})()))()"))


class Served:
    """One of our commands, serving: started as a user starts it (a fresh process), its
    address read from the line that prints it; :meth:`stop` sends SIGTERM and collects
    what it printed."""

    def __init__(self, command: str, *args: str, address: str, cwd: Any, stream: str) -> None:
        import queue
        import subprocess
        import sys
        import time

        from tests.security.attack import ENTRY

        entry = ENTRY[command]
        self.proc = subprocess.Popen(
            [sys.executable, "-c", f"from urdf2mjcf.cli import {entry}; {entry}()", *args],
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.lines: dict[str, list[str]] = {"stdout": [], "stderr": []}
        self._q: queue.Queue[tuple[str, str]] = queue.Queue()
        self._readers = [
            threading.Thread(target=self._read, args=(name,), daemon=True)
            for name in ("stdout", "stderr")
        ]
        for t in self._readers:
            t.start()
        deadline = time.monotonic() + 300
        self.line = ""
        while not self.line:
            assert time.monotonic() < deadline, f"no {address!r} line: {self.lines}"
            assert self.proc.poll() is None or not self._q.empty(), self.lines
            try:
                name, line = self._q.get(timeout=1)
            except queue.Empty:
                continue
            if name == stream and address in line:
                self.line = line
        self.url = self.line.split(address, 1)[1].split()[0]
        """The address printed (with the run's token, where there is one)."""
        self.base, _, self.token = self.url.partition("?token=")
        self.port = int(self.base.split("/")[2].rsplit(":", 1)[1])

    def _read(self, name: str) -> None:
        stream = getattr(self.proc, name)
        for raw in stream:
            line = raw.decode("utf-8", "replace").rstrip("\n")
            self.lines[name].append(line)
            self._q.put((name, line))

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 60) -> int:
        import signal

        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(timeout)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            for t in self._readers:
                t.join(10)

    @property
    def stderr(self) -> str:
        return "\n".join(self.lines["stderr"])
