"""``rover-drive --console``: a browser console and its HTTP/JSON API for a running
simulation of a facility's rovers (docs/mira3d.md, "Console").

The API (everything the page does goes through it)::

    GET  /                         the page
    GET  /state                    time, and per rover: true pose, odometry, IMU, wheels, arm, estop
    GET  /rovers                   per rover: cameras, arm joints with target ranges, wheel range
    GET  /camera/NAME/CAMERA.png   the camera's image at the latest state (header X-Sim-Time)
    POST /command                  {"rover": NAME, "wheels": {"left": rad/s, "right": rad/s},
                                    "arm": {JOINT: rad}} (wheels and/or arm)
    POST /estop, POST /release     {"rover": NAME}, or no body: every rover

A refused request gets a 4xx status and ``{"error": "..."}`` on one line (every
answer, http.server's own refusals too); the simulation runs on. The server listens
on the loopback interface only and answers only what :class:`..loopback_guard.Guard`
lets in: requests addressed to it by a loopback name and its port (a page of another
site that renames itself to 127.0.0.1 gets 403), from its own page or an origin named
with ``--allow-origin``, carrying the run's token (in the printed address, then in
the cookie its answer sets). It serves ``CLIENTS_MAX`` connections at once.
"""

from __future__ import annotations

import json
import signal
import threading
import urllib.parse
from collections.abc import Callable, Iterable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import click
from click.core import ParameterSource

from ...loopback_guard import SECURITY_HEADERS, Guard, new_token
from ..task_kinds import ARM, WHEELS, Param
from ..task_kinds import NUMBER_MAX as NUMBER_MAX  # importable where it was
from .console_camera import Cameras, CameraUnavailable, image_sizes
from .console_page import CSP, PAGE
from .console_sim import CommandError, ConsoleSim
from .roles import RoverError
from .sim import RoverSim

HOST = "127.0.0.1"
BODY_MAX = 16 * 1024
"""Bytes of a request body, at most."""
DRAIN_MAX = 1024 * 1024
"""Bytes of a too-large body read and dropped so the client hears the 413."""
REQUEST_TIMEOUT_S = 10.0
"""A client that sends nothing for this long is dropped."""
BODY_TIMEOUT_S = 2.0
"""Seconds a body may take to arrive once its headers have (16 KiB, from this machine)."""
CLIENTS_MAX = 32
"""Connections served at once (a page holds about 8); one more is answered 503."""
DIGITS_MAX = 40
"""Characters of one number in a request body, at most."""


def _number(value: Any, where: str, param: Param) -> float:
    """``value`` checked as ``param`` (a request field the task registry declares)."""
    x = param.number(value)
    if isinstance(x, str):
        raise CommandError(f"{where}: {x}")
    return x


def _digits(text: str) -> str:
    if len(text) > DIGITS_MAX:
        raise CommandError(f"a number of {len(text)} characters (at most {DIGITS_MAX})")
    return text


def _object(value: Any, where: str, keys: tuple[str, ...]) -> dict:
    if not isinstance(value, dict):
        raise CommandError(f"{where}: expected a JSON object")
    extra = [k for k in value if k not in keys]
    if extra:
        raise CommandError(f"{where}: unknown key {extra[0]!r}; keys: {', '.join(keys)}")
    return value


def _no_constants(name: str) -> Any:
    raise CommandError(f"{name} is not a number")


class Console:
    """The server for ``sim`` on ``port`` (0: a free one) of the loopback interface;
    :meth:`start` starts the simulation and the server, :meth:`close` stops both."""

    def __init__(self, sim: ConsoleSim, port: int = 0, origins: Iterable[str] = ()):
        self.sim = sim
        m = sim.sim.m
        self.server = _Server((HOST, port), _Handler)
        self.server.console = self  # type: ignore[attr-defined]
        self.port = int(self.server.server_address[1])
        self.guard = Guard(self.port, frozenset(origins), new_token(), HOST)
        self.url = self.guard.url()
        """The page's address, with the run's token: the one to print and open."""
        self.cameras = Cameras(m, sim.snapshot, image_sizes(m, sim.sim.manifest))
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self.sim.start()
        self._thread = threading.Thread(
            target=self.server.serve_forever, name="rover-console-http", daemon=True
        )
        self._thread.start()

    def close(self) -> None:
        if self._thread is not None:
            self.server.shutdown()
        self.server.server_close()
        self.sim.stop()
        self.cameras.close()

    def __enter__(self) -> Console:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def address(self, path: str) -> str:
        """The address of the API's ``path`` (``state``, ``command``), with the token."""
        return self.guard.url(path="/" + path.lstrip("/"))

    # -- the API, independent of HTTP ------------------------------------------------

    def get(self, path: str) -> tuple[str, bytes, dict[str, str]]:
        """(content type, body, extra headers) of ``GET path`` (as sent: each part of it
        %-encoded)."""
        parts = [urllib.parse.unquote(p) for p in path.split("/")]
        path = "/".join(parts)
        if path in ("/", "/index.html"):
            return "text/html; charset=utf-8", PAGE.encode(), {"Content-Security-Policy": CSP}
        if path == "/state":
            return _json(self._running(self.sim.state()))
        if path == "/rovers":
            return _json(self.sim.info())
        if len(parts) == 4 and parts[1] == "camera" and parts[3].endswith(".png"):
            name, camera = parts[2], parts[3][: -len(".png")]
            cams = self.sim.driven(name).cameras
            if camera not in cams:
                raise CommandError(f"{name}: no camera {camera!r}; cameras: {', '.join(cams)}", 404)
            try:
                t, png = self.cameras.png(cams[camera])
            except CameraUnavailable as exc:
                raise CommandError(str(exc), 503) from None
            return "image/png", png, {"X-Sim-Time": repr(t)}
        raise CommandError(f"no such path: GET {path}", 404)

    def post(self, path: str, body: Any) -> Any:
        """The answer to ``POST path`` with the JSON ``body`` (None: no body)."""
        path = urllib.parse.unquote(path)
        if path == "/command":
            return self._command(body)
        if path in ("/estop", "/release"):
            names = None
            if body is not None:
                rover = _object(body, path, ("rover",)).get("rover")
                names = None if rover is None else [rover]
            return self.sim.estop(names) if path == "/estop" else self.sim.release(names)
        raise CommandError(f"no such path: POST {path}", 404)

    def _command(self, body: Any) -> Any:
        body = _object(body, "/command", ("rover", "wheels", "arm"))
        name = body.get("rover")
        if name is None and len(self.sim.rovers) == 1:
            name = next(iter(self.sim.rovers))
        self.sim.driven(name)
        wheels = None
        if "wheels" in body:
            w = _object(body["wheels"], "wheels", ("left", "right"))
            if set(w) != {"left", "right"}:
                raise CommandError("wheels: give both 'left' and 'right' (rad/s)")
            left, right = WHEELS.param("left"), WHEELS.param("right")
            wheels = (
                _number(w["left"], "wheels.left", left),
                _number(w["right"], "wheels.right", right),
            )
        arm = None
        if "arm" in body:
            a = body["arm"]
            if not isinstance(a, dict):
                raise CommandError("arm: expected a JSON object {JOINT: rad}")
            arm = {str(j): _number(v, f"arm.{j}", ARM.param("joint")) for j, v in a.items()}
        if wheels is None and arm is None:
            raise CommandError("/command: give 'wheels' and/or 'arm'")
        return self.sim.command(name, wheels, arm)

    def _running(self, answer: Any) -> Any:
        if self.sim.error is not None:
            raise CommandError(f"the simulation stopped: {self.sim.error!r}", 500)
        return answer


def _json(obj: Any) -> tuple[str, bytes, dict[str, str]]:
    return "application/json", json.dumps(obj, allow_nan=False).encode() + b"\n", {}


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    block_on_close = False
    request_queue_size = 64  # a page asks for every camera and the state at once

    def __init__(self, *args: Any, **kw: Any) -> None:
        super().__init__(*args, **kw)
        self._slots = threading.BoundedSemaphore(CLIENTS_MAX)

    def process_request(self, request: Any, client_address: Any) -> None:
        # One thread per connection, CLIENTS_MAX at most: one more hears 503, no thread.
        if not self._slots.acquire(blocking=False):
            _busy(request)
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            self.shutdown_request(request)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def handle_error(self, request: Any, client_address: Any) -> None:
        pass  # a client that went away or misbehaved: nothing of ours to print


def _busy(request: Any) -> None:
    body = json.dumps({"error": f"busy: at most {CLIENTS_MAX} connections at once"}) + "\n"
    head = (
        "HTTP/1.0 503 Service Unavailable\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    )
    try:
        request.setblocking(False)  # never wait on this client: the server's own thread
        request.send((head + body).encode())
    except OSError:
        pass


class _Handler(BaseHTTPRequestHandler):
    server_version = "rover-console"
    timeout = REQUEST_TIMEOUT_S
    _cookie: str | None = None

    @property
    def console(self) -> Console:
        return self.server.console  # type: ignore[attr-defined,no-any-return]

    def log_message(self, format: str, *args: Any) -> None:
        pass  # quiet: the command's output is its address line

    def _send(self, status: int, kind: str, body: bytes, headers: dict[str, str]) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        for k, v in {**SECURITY_HEADERS, **headers}.items():
            self.send_header(k, v)
        if self._cookie is not None:
            self.send_header("Set-Cookie", self._cookie)
        self.end_headers()
        self.wfile.write(body)

    def _error(self, status: int, message: str) -> None:
        self._send(status, *_json({"error": message}))

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """http.server's own refusals (a bad request line, an unknown method, headers too
        long) in JSON, as ours are; what the client sent is not repeated."""
        self.close_connection = True
        if self.request_version == "HTTP/0.9":  # no version read: answer with a status line
            self.request_version = "HTTP/1.0"
        text = {
            400: "a bad HTTP request",
            408: "the request did not arrive in time",
            414: "the request line is too long",
            431: "the request's headers are too long",
            501: "method not allowed: GET or POST",
            505: "HTTP/1.0 or HTTP/1.1, please",
        }.get(code, "refused")
        try:
            self._error(405 if code == 501 else code, text)
        except OSError:  # the client left
            pass

    def _check(self) -> None:
        """The guard: raises CommandError where we do not answer; notes the cookie to set."""
        h = self.headers
        refused = self.console.guard.check(
            self.path,
            h.get_all("Host") or [],
            h.get_all("Origin") or [],
            h.get_all("Sec-Fetch-Site") or [],
            h.get_all("Cookie") or [],
        )
        if refused is not None:
            raise CommandError(refused.reason, refused.status)
        if self.command == "GET" and self.console.guard.token_in(self.path):
            self._cookie = self.console.guard.set_cookie()

    def _handle(self, answer: Callable[[str], tuple[str, bytes, dict[str, str]]]) -> None:
        try:
            self._check()
            path = urllib.parse.urlsplit(self.path).path
            status, (kind, body, headers) = 200, answer(path)
        except CommandError as exc:
            self._cookie = None
            status, (kind, body, headers) = exc.status, _json({"error": str(exc)})
        except Exception as exc:  # noqa: BLE001 - a bug answers 500, the server goes on
            self._cookie = None
            status, (kind, body, headers) = 500, _json({"error": f"internal error: {exc!r}"})
        try:
            self._send(status, kind, body, headers)
        except OSError:  # the client left (a closed page): nothing to tell it
            self.close_connection = True

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        self._handle(self.console.get)

    def do_POST(self) -> None:  # noqa: N802
        self._handle(lambda path: _json(self.console.post(path, self._body())))

    def _not_allowed(self) -> None:
        self._error(405, f"method {self.command} not allowed")

    do_PUT = do_DELETE = do_PATCH = do_HEAD = do_OPTIONS = _not_allowed  # noqa: N815

    def _body(self) -> Any:
        if self.headers.get("Transfer-Encoding"):
            raise CommandError("send a Content-Length, not a chunked body", 411)
        lengths = self.headers.get_all("Content-Length") or []
        if len(set(lengths)) > 1:
            raise CommandError("more than one Content-Length")
        try:
            size = int(lengths[0]) if lengths else 0
        except ValueError:
            raise CommandError("Content-Length is not a number") from None
        if size < 0:
            raise CommandError("Content-Length is negative")
        if size > BODY_MAX:
            if size <= DRAIN_MAX:  # read it, so the client gets to read our answer
                self._read(size)
            self.close_connection = True
            raise CommandError(f"body of {size} bytes is over {BODY_MAX}", 413)
        raw = self._read(size) if size else b""
        if len(raw) < size:
            self.close_connection = True
            raise CommandError(f"the body ended after {len(raw)} of its {size} bytes")
        if not raw.strip():
            return None
        try:
            return json.loads(raw, parse_constant=_no_constants, parse_int=_int, parse_float=_float)
        except CommandError:  # a number refused while parsing: its own message
            raise
        except (ValueError, RecursionError) as exc:  # UnicodeDecodeError is a ValueError
            raise CommandError(f"body is not JSON: {exc}") from None

    def _read(self, size: int) -> bytes:
        """``size`` bytes of the body, or those that came within ``BODY_TIMEOUT_S``."""
        self.connection.settimeout(BODY_TIMEOUT_S)
        try:
            return self.rfile.read(size)
        except TimeoutError:
            self.close_connection = True
            raise CommandError(
                f"the body did not arrive within {BODY_TIMEOUT_S:g} s (is Content-Length "
                "its size?)",
                408,
            ) from None
        finally:
            self.connection.settimeout(REQUEST_TIMEOUT_S)


def _int(text: str) -> int:
    return int(_digits(text))


def _float(text: str) -> float:
    return float(_digits(text))


def run(
    sim: ConsoleSim, port: int, echo: Callable[[str], None], origins: Iterable[str] = ()
) -> None:
    """Serve the console for ``sim`` until Ctrl-C or SIGTERM (then return normally);
    ``origins``: those it answers besides its own page."""
    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with Console(sim, port, origins) as console:
            echo(f"console at {console.url} (pace {sim.pace:g}; Ctrl-C to stop)")
            while not stop.wait(0.2):
                if sim.error is not None:
                    raise RuntimeError(f"the simulation stopped: {sim.error!r}")
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


CONSOLE_OPTIONS = {"scene", "names", "settle", "pace", "console", "port", "debug", "allow_origins"}
"""rover-drive's parameters that mean something with --console; any other is refused."""


def check_console_options(ctx: click.Context, console: bool) -> bool:
    """Whether rover-drive serves the console; a drive option given with ``--console``,
    or ``--port`` without it, is a usage error."""
    given = [
        p
        for p in ctx.command.params
        if p.name and ctx.get_parameter_source(p.name) == ParameterSource.COMMANDLINE
    ]
    if not console:
        if any(p.name == "port" for p in given):
            raise click.UsageError("--port is for --console")
        return False
    other = [p for p in given if p.name not in CONSOLE_OPTIONS]
    if other:
        raise click.UsageError(f"--console runs no drive: {other[0].opts[0]} is not for it")
    return True


def serve_console(
    scene: Path,
    names: tuple[str, ...],
    settle: float,
    pace: float,
    port: int,
    origins: Iterable[str] = (),
) -> None:
    """``rover-drive SCENE --console``: the rovers ``names`` (default: all) of the facility,
    settled for ``settle`` s, served until Ctrl-C or SIGTERM; ``origins``: those it
    answers besides its own page."""
    try:
        sim = RoverSim(scene)
        for n in names:
            sim.rover(n)
        sim.settle(settle)
    except RoverError as exc:
        raise click.ClickException(str(exc)) from None
    try:
        run(ConsoleSim(sim, list(names) or None, pace), port, click.echo, origins)
    except OSError as exc:
        if exc.filename is None and exc.strerror:  # binding the port
            raise click.ClickException(f"--port {port}: {exc.strerror}") from None
        raise
