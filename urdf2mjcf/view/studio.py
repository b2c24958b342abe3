"""MuJoCo Studio in a child process (:mod:`urdf2mjcf.view.child`): start it, read its
address, tell it which model to show (or which state, for a live run), stop it."""

from __future__ import annotations

import importlib.util
import os
import queue
import subprocess
import sys
import threading
import webbrowser
from collections.abc import Iterable
from pathlib import Path

from ..errors import ViewerError

STARTUP_S = 150.0
"""Seconds the viewer may take to start (the child's own limit is a little shorter)."""
LOAD_S = 120.0
"""Seconds one model may take to load in the viewer (a facility's meshes, compiled)."""


def has_display() -> bool:
    """Whether a desktop window (or a browser on this machine) can be shown here."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_studio() -> None:
    """The error that says MuJoCo Studio is missing (it came with MuJoCo 4), where it is."""
    try:
        found = importlib.util.find_spec("mujoco.studio") is not None
    except ImportError:
        found = False
    if not found:
        raise ViewerError(
            "the viewer is MuJoCo Studio, which comes with MuJoCo 4: pip install 'mujoco>=4'",
            element="mujoco.studio",
        )


def check_desktop() -> None:
    """The error that says the desktop viewer cannot open here, where it cannot."""
    if not has_display():
        raise ViewerError(
            "no display here for the desktop viewer (DISPLAY and WAYLAND_DISPLAY are "
            "unset); leave out --desktop to use the browser viewer",
            element="--desktop",
        )


def open_browser(url: str) -> bool:
    """Opens ``url`` in a browser where a display exists; never fails the command."""
    if not has_display():
        return False
    try:
        return bool(webbrowser.open(url, new=2))
    except Exception:  # noqa: BLE001 - no browser is not an error: the address is printed
        return False


class Studio:
    """One viewer: the browser viewer (``url``), or the desktop one (``desktop``).

    ``live``: the viewer shows the states it is sent (:meth:`state`) and steps nothing.
    ``port``: the browser viewer's port (0: the first free one from 8080 up).
    ``origins``: the origins, besides the viewer's own page, it answers (``--allow-origin``).
    ``url`` carries the run's token: the page's address, to print and open."""

    def __init__(
        self,
        *,
        port: int = 0,
        desktop: bool = False,
        live: bool = False,
        origins: Iterable[str] = (),
    ) -> None:
        if desktop:
            check_desktop()
        check_studio()
        args = [sys.executable, "-m", "urdf2mjcf.view.child", "--port", str(port)]
        args += ["--desktop"] * desktop + ["--live"] * live
        for origin in origins:
            args += ["--allow-origin", origin]
        self.proc = subprocess.Popen(
            args,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,  # the Studio's log; our own lines say what matters
            start_new_session=True,  # Ctrl-C reaches us; we stop the viewer ourselves
        )
        self._answers: queue.Queue[str | None] = queue.Queue()
        self._lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()
        first = self._answer(STARTUP_S, "start")
        if first.startswith("error "):
            self.close()
            raise ViewerError(f"the viewer did not start: {first[6:]}", element="viewer")
        self.url = first[4:] if first.startswith("url ") else None

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            self._answers.put(raw.decode("utf-8", "replace").rstrip("\n"))
        self._answers.put(None)

    def _answer(self, timeout: float, doing: str) -> str:
        try:
            line = self._answers.get(timeout=timeout)
        except queue.Empty:
            self.close()
            raise ViewerError(f"the viewer did not {doing} within {timeout:.0f} s") from None
        if line is None:
            self.close()
            raise ViewerError(f"the viewer stopped (exit code {self.proc.poll()})")
        return line

    def _send(self, line: str) -> None:
        assert self.proc.stdin is not None
        with self._lock:
            try:
                self.proc.stdin.write(line.encode() + b"\n")
                self.proc.stdin.flush()
            except (BrokenPipeError, ValueError):
                raise ViewerError("the viewer stopped") from None

    def load(self, path: Path) -> bool:
        """Shows the model file ``path`` (the page reloads); False where the viewer
        could not load it (it keeps the model it had)."""
        self._send(f"load {Path(path).resolve()}")
        while True:  # answers to earlier lines come first
            line = self._answer(LOAD_S, "load the model")
            if line.endswith(str(Path(path).resolve())):
                return line.startswith("loaded ")

    def log(self, level: str, message: str) -> None:
        """A line in the page's console (``info``, ``warning``, ``error``)."""
        self._send(f"log {level} {' '.join(message.split())}")

    def state(self, encoded: str) -> None:
        """Shows a state (``mjSTATE_INTEGRATION``, float64, base64) of the model loaded."""
        self._send(f"state {encoded}")

    def alive(self) -> bool:
        return self.proc.poll() is None

    def close(self) -> None:
        """Stops the viewer (end of its input; killed if it does not stop in 10 s)."""
        if self.proc.stdin is not None:
            try:
                self.proc.stdin.close()
            except OSError:
                pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout is not None:
            self.proc.stdout.close()

    def __enter__(self) -> Studio:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
