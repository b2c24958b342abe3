"""The viewer process: MuJoCo Studio, driven line by line through stdin.

Run as ``python -m urdf2mjcf.view.child [--desktop] [--live] [--port N] [--browser]
[--allow-origin ORIGIN]...`` by :mod:`urdf2mjcf.view.studio`. Commands (one per line
on stdin):

``load PATH``    load a model file (MJCF, MJB); answers ``loaded PATH`` or ``failed PATH``
``log LEVEL MSG`` a line for the page's console (``info``, ``warning`` or ``error``: the
                 status bar counts the errors); no answer
``state B64``    (``--live``) the run's integration state (``mjSTATE_INTEGRATION``, float64,
                 base64) to show; no answer
end of input     close the viewer and exit

Answers go to stdout, one line each: first ``url http://localhost:PORT/?token=TOKEN``
(the browser viewer, with this run's token) or ``ready`` (the desktop viewer), or
``error MESSAGE`` and exit 1. Everything MuJoCo Studio prints itself goes to stderr.

The browser viewer answers only our own pages (:mod:`.studio_guard`: loopback ``Host``,
our origin or one named with ``--allow-origin``, the token), and loads only the files
``load`` named.

Without ``--live`` the Studio steps the model itself (its Run, Pause and Reset work, as
in ``mujoco-studio``); with ``--live`` nothing steps it: it shows the states it is sent.
"""

from __future__ import annotations

import argparse
import base64
import io
import logging
import os
import queue
import re
import sys
import threading
import time
from typing import Any, TextIO

from ..loopback_guard import new_token
from . import studio_guard

URL = re.compile(r"http://localhost:(\d+)/")
_LEVELS = {"info": logging.INFO, "warning": logging.WARNING, "error": logging.ERROR}
STARTUP_S = 120.0
"""How long the viewer may take to come up before the child gives up."""


class _Capture(io.TextIOBase):
    """What the Studio prints: passed on to stderr, its viewer address picked out."""

    def __init__(self, to: TextIO) -> None:
        self.to = to
        self.port: int | None = None

    def write(self, s: str) -> int:  # type: ignore[override]
        if self.port is None:
            found = URL.search(re.sub(r"\x1b\]8;;[^\x1b]*\x1b\\", "", s))
            if found:
                self.port = int(found.group(1))
        self.to.write(s)
        self.to.flush()
        return len(s)

    def flush(self) -> None:
        self.to.flush()


def _reader(into: queue.Queue) -> None:
    for line in sys.stdin.buffer:
        into.put(line.decode("utf-8", "replace").rstrip("\n"))
    into.put(None)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="urdf2mjcf.view.child")
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--desktop", action="store_true")
    parser.add_argument("--live", action="store_true")
    parser.add_argument("--browser", action="store_true")
    parser.add_argument("--allow-origin", action="append", default=[])
    args = parser.parse_args(argv)

    # The answers own stdout; the Studio's own printing goes to stderr.
    answers = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    capture = _Capture(sys.stderr)
    sys.stdout = capture

    def say(line: str) -> None:
        answers.write(line.replace("\n", " ") + "\n")
        answers.flush()

    gate = studio_guard.Gate(new_token(), args.allow_origin)
    named: set[str] = set()
    try:
        handle = _launch(args, capture, gate, named)
    except Exception as exc:  # noqa: BLE001 - the parent shows it as one error line
        say(f"error {' '.join(str(exc).split()) or type(exc).__name__}")
        return 1
    say("ready" if args.desktop else f"url {gate.url(capture.port or 0)}")
    commands: queue.Queue = queue.Queue()
    threading.Thread(target=_reader, args=(commands,), daemon=True).start()
    try:
        _serve(handle, commands, say, named, live=args.live)
    finally:
        handle.close()
    return 0


def _loopback_only() -> None:
    """Bind the browser viewer to 127.0.0.1. MuJoCo Studio 4.0 binds every interface
    (its ``::``, with no setting to change it; its own comment says a host setting is
    to come), and it has no login: anyone who reaches the port could watch, drop a
    model on the page or read the log. A remote user forwards the port (``ssh -L``)."""
    from mujoco.studio.web import web_server

    public = web_server.bind_public_socket
    if getattr(public, "loopback_only", False):
        return

    def loopback(host: str, port: int = 0) -> Any:
        return public("127.0.0.1", port)

    loopback.loopback_only = True  # type: ignore[attr-defined]
    web_server.bind_public_socket = loopback


def _launch(
    args: argparse.Namespace, capture: _Capture, gate: studio_guard.Gate, named: set[str]
) -> Any:
    from mujoco.studio import app as studio_app
    from mujoco.studio import launch_passive, viewer_protocol

    _loopback_only()
    studio_guard.install(gate)

    config = viewer_protocol.ViewerConfig(
        gfx="" if args.desktop else "web", http_port=args.port, open_browser=args.browser
    )
    plugins: list[Any] = [studio_app.App(), studio_guard.named_models_only(named)]
    if not args.live:
        plugins += list(studio_app.SIM_PLUGINS)  # the Studio steps the model, as its own app
    handle = launch_passive.launch(config, plugins=plugins)
    deadline = time.monotonic() + STARTUP_S
    while not args.desktop and capture.port is None:
        if not handle.is_running():  # raises the viewer thread's error, if it had one
            raise RuntimeError("the viewer stopped while starting")
        if time.monotonic() > deadline:
            handle.close()
            raise RuntimeError(f"the viewer did not start within {STARTUP_S:.0f} s")
        time.sleep(0.02)
    return handle


def _serve(handle: Any, commands: queue.Queue, say: Any, named: set[str], *, live: bool) -> None:
    import mujoco
    import numpy as np
    from mujoco.studio import messages

    sig = int(mujoco.mjtState.mjSTATE_INTEGRATION)
    while handle.is_running():
        try:
            # live: wait for the next state; else the Studio's own stepping paces the loop
            line = commands.get(timeout=0.05) if live else commands.get_nowait()
        except queue.Empty:
            line = ""
        state = None
        while line is not None:
            verb, _, rest = line.partition(" ")
            if verb == "load":
                named.add(os.path.abspath(rest))  # the one file the parent names
                before = handle.model
                handle.dispatch(messages.LoadModelEvent(path=rest))
                ok = handle.model is not None and handle.model is not before
                say(f"{'loaded' if ok else 'failed'} {rest}")
            elif verb == "log":
                level, _, message = rest.partition(" ")
                logging.getLogger("urdf2mjcf").log(_LEVELS.get(level, logging.INFO), message)
            elif verb == "state":
                state = rest  # only the newest state of those waiting is shown
            try:
                line = commands.get_nowait()
            except queue.Empty:
                break
        if line is None:
            return
        if state is not None and handle.model is not None:
            values = np.frombuffer(base64.b64decode(state), dtype=np.float64)
            if len(values) == mujoco.mj_stateSize(handle.model, sig):
                mujoco.mj_setState(handle.model, handle.data, values, sig)
                mujoco.mj_forward(handle.model, handle.data)
        handle.sync()


if __name__ == "__main__":
    sys.exit(main())
