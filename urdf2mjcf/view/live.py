"""A run shown live in the browser viewer (``facility-demo --view``,
``rover-drive --view``), paced to real time.

A step hook (:meth:`LiveView.step`, called after every physics step) copies the run's
state out and, once per frame, hands it to a sender thread that passes it to the
viewer process; nothing in the run is changed and nothing it does waits for the viewer.
The viewer shows a copy of the model (written as MJB and loaded by the viewer), so
what the browser does (Reset, a dragged body, Physics Settings) touches only that copy.
The only effect on the run is time: the hook sleeps so that ``pace`` simulated seconds
pass per wall-clock second (the run is slower, never different).
"""

from __future__ import annotations

import base64
import tempfile
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import click

from .studio import Studio, ViewerError, open_browser

FPS = 30.0
"""States sent to the viewer per wall-clock second, at most."""
PACE_MAX = 1000.0
"""The fastest pace asked for (simulated seconds per wall-clock second)."""


class LiveView:
    """The viewer of one run of ``model``/``data``: call :meth:`step` after every step,
    :meth:`close` at the end. ``origins``: those the viewer answers besides its own page
    (``--allow-origin``)."""

    def __init__(
        self,
        model: Any,
        data: Any,
        *,
        pace: float = 1.0,
        port: int = 0,
        browser: bool = True,
        what: str = "the run",
        origins: Iterable[str] = (),
    ) -> None:
        import mujoco

        self.m, self.d, self.pace = model, data, pace
        self._sig = int(mujoco.mjtState.mjSTATE_INTEGRATION)
        self._state = mujoco.mj_stateSize(model, self._sig)
        self._folder = tempfile.TemporaryDirectory(prefix="urdf2mjcf-live-")
        copy = Path(self._folder.name) / "run.mjb"
        mujoco.mj_saveModel(model, str(copy), None)
        self._sender: threading.Thread | None = None
        try:
            self.studio = Studio(port=port, live=True, origins=origins)
        except BaseException:
            self._folder.cleanup()
            raise
        try:
            if not self.studio.load(copy):
                raise ViewerError("the viewer could not load the run's model", element="--view")
        except BaseException:
            self.close()
            raise
        click.echo(
            f"viewing {what} at {self.studio.url} (pace {pace:g}: simulated s per wall s)",
            err=True,  # stdout stays what the run prints without --view
        )
        if browser and self.studio.url:
            open_browser(self.studio.url)
        self._latest: str | None = None
        self._ready = threading.Event()
        self._done = False
        self._sender = threading.Thread(target=self._send, daemon=True)
        self._sender.start()
        self._t0: float | None = None
        self._sim0 = 0.0
        self._next_frame = 0.0
        self.frames = 0
        """States handed to the sender."""
        self._offer()

    def _offer(self) -> None:
        import mujoco
        import numpy as np

        state = np.empty(self._state, np.float64)
        mujoco.mj_getState(self.m, self.d, state, self._sig)
        self._latest = base64.b64encode(state.tobytes()).decode("ascii")
        self.frames += 1
        self._ready.set()

    def _send(self) -> None:
        while not self._done:
            self._ready.wait()
            self._ready.clear()
            encoded, self._latest = self._latest, None
            if encoded is None:
                continue
            try:
                self.studio.state(encoded)
            except Exception:  # noqa: BLE001 - a closed page never stops the run
                return

    def step(self) -> None:
        """After a physics step: pace to real time, and offer a frame when one is due."""
        now = time.perf_counter()
        if self._t0 is None:
            self._t0, self._sim0 = now, float(self.d.time)
        ahead = (float(self.d.time) - self._sim0) / self.pace - (now - self._t0)
        if ahead > 0:
            time.sleep(ahead)
            now += ahead
        if now >= self._next_frame:
            self._next_frame = now + 1.0 / FPS
            self._offer()

    def close(self) -> None:
        """Shows the last state, then stops the viewer."""
        if self._sender is not None and not self._done:
            self._offer()
            self._done = True
            self._ready.set()
            self._sender.join(5)
        self.studio.close()
        self._folder.cleanup()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
