"""A run streamed live to Foxglove (``facility-demo --foxglove``, ``rover-drive --foxglove``).

The messages are the recording's (:class:`.record.Recorder` builds each once and hands
it to every sink): the same topics, ROS 2 types and simulated-time stamps as
``--record``. :class:`FoxgloveStream` is such a sink: it serves them through our
Foxglove WebSocket server on 127.0.0.1 (:mod:`.foxglove_server`: only our own clients,
a bounded number, each with a bounded queue), each topic a channel with the ROS 2
definition (``ros2msg``) and CDR payloads, as a ROS 2 bridge serves them, so
Foxglove's panels treat them as ROS 2 topics. After the start, a payload is encoded
only while a client subscribes to its topic (and, through :meth:`wants`, the recorder
builds no message and renders no camera for a stream alone that nobody watches). The
server's clock is the simulated time.

The stream only reads: the run does what it does without it. It paces the run
(``pace`` simulated seconds per wall-clock second) so that one can watch it, and
``wait`` holds the start until a client subscribes. The server stops when the run ends.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any

from ..errors import OutputError, PortError
from .cdr import encoder
from .foxglove_server import FoxgloveServer

HOST = FoxgloveServer.HOST
"""Only this machine: a remote Foxglove reaches it through an SSH tunnel."""
DEFAULT_PORT = 8765
"""Foxglove's default for a WebSocket connection."""
PORT_MAX = 65535
POLL = 0.05
"""s between looks for a subscriber while waiting."""
CLOCK = 10_000_000
"""ns of simulated time between the server's announcements of the time."""


class FoxgloveStream:
    """A WebSocket server streaming a :class:`.record.Recorder`'s messages of the run of
    ``data`` (its MjData): pass it as one of the recorder's ``sinks``, call :meth:`start`
    after the recorder's first step, :meth:`step` after every physics step (it paces the
    run and tells clients the time) and :meth:`close` when the run ends. ``origins``:
    the web origins answered (``--allow-origin``; a client that is no web page is)."""

    def __init__(
        self,
        data: Any,
        port: int = DEFAULT_PORT,
        *,
        pace: float | None = 1.0,
        name: str = "urdf2mjcf",
        origins: Iterable[str] = (),
    ) -> None:
        self.d, self.pace = data, pace
        try:
            self._server = FoxgloveServer(port, name=name, origins=origins)
        except PortError as exc:  # the port is taken, or not ours to bind
            raise OutputError(
                f"cannot serve on {HOST}:{port}: {exc.strerror}", element="--foxglove"
            ) from None
        self.port = self._server.port
        self._channels: dict[str, int] = {}
        self._encoders: dict[str, Callable[[Any], bytes]] = {}
        self._first: dict[str, tuple[bytes, int]] = {}
        self._started = False
        self._time: int | None = None
        self._wall0 = 0.0
        self._sim0: int | None = None
        self.sent = 0
        """Messages handed to the server for a subscriber."""

    @property
    def address(self) -> str:
        return f"ws://{HOST}:{self.port}"

    def _channel(self, topic: str, datatype: str) -> int:
        ch = self._channels.get(topic)
        if ch is None:
            from .record import msgdef  # mujoco: not for the command line's --help

            definition = msgdef(datatype)
            if datatype not in self._encoders:
                self._encoders[datatype] = encoder(datatype, definition)
            ch = self._server.add_channel(topic, "cdr", datatype, definition, "ros2msg")
            self._channels[topic] = ch
        return ch

    def __call__(self, topic: str, datatype: str, msg: dict, ns: int) -> None:
        """The recorder's sink: serve ``msg`` on ``topic`` at simulated time ``ns``."""
        ch = self._channel(topic, datatype)
        if not self._started:
            # The start, kept for a client that subscribes while start() waits.
            payload = self._encoders[datatype](msg)
            self._first[topic] = (payload, ns)
            self._server.log(ch, payload, ns)
        elif self._server.watched(ch):
            if self._server.log(ch, self._encoders[datatype](msg), ns):
                self.sent += 1

    def wants(self, prefix: str) -> bool:
        """Whether a client subscribes to a topic under ``prefix`` (before the start:
        yes, every topic's channel is made then): the recorder builds no message and
        renders no camera that nobody watches."""
        if not self._started:
            return True
        return any(
            self._server.watched(ch)
            for topic, ch in self._channels.items()
            if topic.startswith(prefix)
        )

    def step(self) -> None:
        """After a physics step: announce the time (every ``CLOCK``), keep to the pace."""
        if not self._started:
            return
        ns = int(round(float(self.d.time) * 1e9))
        if self._time is None or ns - self._time >= CLOCK:
            self._time = ns
            self._server.broadcast_time(ns)
        if self.pace is None:
            return
        if self._sim0 is None:
            self._sim0, self._wall0 = ns, time.perf_counter()
            return
        ahead = (ns - self._sim0) * 1e-9 / self.pace - (time.perf_counter() - self._wall0)
        if ahead > 0:
            time.sleep(ahead)

    def start(self, wait: bool = False) -> None:
        """The run begins; with ``wait``, once a client subscribes to a topic (it then
        gets the start's message on every topic it subscribed to)."""
        if wait:
            while not any(self._server.watched(ch) for ch in self._channels.values()):
                time.sleep(POLL)
            time.sleep(POLL)  # a client subscribes to its topics one after another
            for topic, (payload, ns) in self._first.items():
                if self._server.log(self._channels[topic], payload, ns):
                    self.sent += 1
        self._first.clear()
        self._started = True

    def close(self) -> None:
        """Stop the server (clients see the connection close)."""
        self._channels.clear()
        self._server.stop()
