"""Foxglove's WebSocket protocol, served by us (``websockets``) on the loopback interface,
answering only the clients :class:`..loopback_guard.Guard` lets in, a bounded number of
them, each with a bounded queue.

Why not foxglove-sdk's server: its Python API (0.30) hands us no request to check (no
``Host``, no ``Origin``, no hook that could refuse a client), bounds a client's queue in
messages, not bytes (a client that subscribes to camera images and never reads grows
the process by tens of MB), prints what a client sent that it could not parse to
stderr as it came, and serves any page of any site. A front of ours before it would
leave its own port open to the same pages (a page can scan the loopback ports).

What we speak is the subset a live stream needs of the protocol
(https://github.com/foxglove/ws-protocol, subprotocol ``foxglove.sdk.v1``, or the
older ``foxglove.websocket.v1``, which the same messages satisfy): ``serverInfo`` with
the ``time`` capability, ``advertise`` of each channel (topic, message encoding,
schema), ``subscribe`` and ``unsubscribe`` from the client, message data (binary
opcode 1: subscription id, log time, payload) and the server's time (opcode 2). A
client's other messages get a ``status`` error; none is printed.
"""

from __future__ import annotations

import asyncio
import collections
import json
import logging
import socket
import struct
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from ..errors import PortError
from ..loopback_guard import SECURITY_HEADERS, Guard

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
"""The subprotocols we speak, the first preferred."""
CLIENTS_MAX = 8
"""Clients at once; one more is refused (HTTP 503)."""
QUEUE_BYTES = 8 * 2**20
"""Bytes of messages waiting for one client; beyond, its oldest messages are dropped."""
CONTROL_MAX = 1024
"""Announcements and answers waiting for one client; beyond, the client is closed."""
MESSAGE_MAX = 64 * 1024
"""Bytes of one message from a client."""
OPEN_TIMEOUT_S = 10.0
"""Seconds a client may take to open its connection."""
STOP_S = 5.0
"""Seconds the server may take to close its clients when it stops."""
_OP_MESSAGE, _OP_TIME = 1, 2
_U32 = 2**32

# websockets' own log of refused handshakes and clients gone away: what a client did,
# not ours to print (a stranger's page can make as many as it likes).
_quiet = logging.getLogger(f"{__name__}.connections")
_quiet.setLevel(logging.CRITICAL + 1)
_quiet.propagate = False


@dataclass(frozen=True)
class Channel:
    """One topic as advertised."""

    id: int
    topic: str
    encoding: str
    schema_name: str
    schema: str
    schema_encoding: str

    def advertised(self) -> dict:
        return {
            "id": self.id,
            "topic": self.topic,
            "encoding": self.encoding,
            "schemaName": self.schema_name,
            "schema": self.schema,
            "schemaEncoding": self.schema_encoding,
        }


class _Client:
    """One connection: its subscriptions and what waits to be sent to it."""

    def __init__(self, ws: Any, loop: asyncio.AbstractEventLoop) -> None:
        self.ws, self.loop = ws, loop
        self.subs: dict[int, int] = {}  # subscription id -> channel id
        self.control: collections.deque[str] = collections.deque()
        self.data: collections.deque[bytes] = collections.deque()
        self.queued = 0
        self.dropped = 0
        self.lock = threading.Lock()
        self.wake = asyncio.Event()
        self.overrun = False

    def _poke(self) -> None:
        self.loop.call_soon_threadsafe(self.wake.set)

    def say(self, message: dict) -> None:
        """A JSON message (never dropped); too many waiting: the client is closed."""
        with self.lock:
            if len(self.control) >= CONTROL_MAX:
                self.overrun = True
            else:
                self.control.append(json.dumps(message, separators=(",", ":")))
        self._poke()

    def send(self, frame: bytes) -> None:
        """A binary message; the oldest are dropped to keep under ``QUEUE_BYTES``."""
        with self.lock:
            if len(frame) > QUEUE_BYTES:
                self.dropped += 1
                return
            while self.data and self.queued + len(frame) > QUEUE_BYTES:
                self.queued -= len(self.data.popleft())
                self.dropped += 1
            was_empty = not self.data
            self.data.append(frame)
            self.queued += len(frame)
        if was_empty:
            self._poke()

    def next(self) -> str | bytes | None:
        with self.lock:
            if self.control:
                return self.control.popleft()
            if self.data:
                frame = self.data.popleft()
                self.queued -= len(frame)
                return frame
            return None


class FoxgloveServer:
    """The server on ``HOST:port`` (0: a free port), running in its own thread from
    the constructor on; :meth:`stop` ends it. ``origins``: the web origins answered
    besides none (the stream serves no page of its own); a client that is not a web
    page sends no ``Origin`` and is answered."""

    HOST = "127.0.0.1"

    def __init__(self, port: int, *, name: str, origins: Iterable[str] = ()) -> None:
        self.name = name
        self._channels: dict[int, Channel] = {}
        self._clients: set[_Client] = set()
        self._watched: dict[int, int] = collections.Counter()  # channel -> subscriptions
        self._lock = threading.Lock()
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((self.HOST, port))
            sock.listen(64)
        except OSError as exc:
            sock.close()
            raise PortError(exc.errno, exc.strerror) from None
        self.port = int(sock.getsockname()[1])
        self.guard = Guard(self.port, frozenset(origins), None, self.HOST)
        self._ready = threading.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread = threading.Thread(
            target=self._run, args=(sock,), name="foxglove-server", daemon=True
        )
        self._thread.start()
        self._ready.wait()

    # -- what the run calls (its own thread) ------------------------------------------

    def add_channel(
        self, topic: str, encoding: str, schema_name: str, schema: str, schema_encoding: str
    ) -> int:
        """A new channel, advertised to every client; its id."""
        with self._lock:
            ch = Channel(len(self._channels) + 1, topic, encoding, schema_name, schema,
                         schema_encoding)  # fmt: skip
            self._channels[ch.id] = ch
            clients = list(self._clients)
        for c in clients:
            c.say({"op": "advertise", "channels": [ch.advertised()]})
        return ch.id

    def watched(self, channel: int) -> bool:
        """Whether a client subscribes to ``channel``."""
        return self._watched.get(channel, 0) > 0

    def log(self, channel: int, payload: bytes, log_time: int) -> int:
        """``payload`` at ``log_time`` (ns) to every subscriber of ``channel``; how many."""
        with self._lock:
            to = [(c, s) for c in self._clients for s, ch in c.subs.items() if ch == channel]
        stamp = struct.pack("<Q", log_time % 2**64)
        for c, sub in to:
            c.send(struct.pack("<BI", _OP_MESSAGE, sub) + stamp + payload)
        return len(to)

    def broadcast_time(self, ns: int) -> None:
        """The server's time (simulated ns) to every client."""
        with self._lock:
            clients = list(self._clients)
        frame = struct.pack("<BQ", _OP_TIME, ns % 2**64)
        for c in clients:
            c.send(frame)

    def clients(self) -> int:
        with self._lock:
            return len(self._clients)

    def queued(self) -> list[int]:
        """Bytes waiting for each client (for the tests: each is within ``QUEUE_BYTES``)."""
        with self._lock:
            return [c.queued for c in self._clients]

    def stop(self) -> None:
        """Close every client (going away) and the server; returns once it is down."""
        if self._loop is not None and self._stop is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(STOP_S + 1)

    # -- the server's thread ------------------------------------------------------------

    def _run(self, sock: socket.socket) -> None:
        try:
            asyncio.run(self._main(sock))
        finally:
            sock.close()
            self._ready.set()

    async def _main(self, sock: socket.socket) -> None:
        from websockets.asyncio.server import serve

        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        async with serve(
            self._serve,
            sock=sock,
            process_request=self._check,
            process_response=self._headers,
            subprotocols=list(SUBPROTOCOLS),  # type: ignore[arg-type]
            max_size=MESSAGE_MAX,
            max_queue=16,
            open_timeout=OPEN_TIMEOUT_S,
            compression=None,
            logger=_quiet,
        ) as server:
            self._ready.set()
            await self._stop.wait()
            server.close(close_connections=True)
            try:
                await asyncio.wait_for(server.wait_closed(), STOP_S)
            except asyncio.TimeoutError:
                pass

    def _check(self, connection: Any, request: Any) -> Any:
        h = request.headers
        refused = self.guard.check(
            request.path, h.get_all("Host"), h.get_all("Origin"), h.get_all("Sec-Fetch-Site")
        )
        if refused is not None:
            return connection.respond(refused.status, refused.reason + "\n")
        upgrade = [v.strip().lower() for x in h.get_all("Upgrade") for v in x.split(",")]
        if "websocket" not in upgrade:
            return connection.respond(426, "a Foxglove WebSocket client connects here\n")
        if self.clients() >= CLIENTS_MAX:
            return connection.respond(503, f"at most {CLIENTS_MAX} clients at once\n")
        return None

    def _headers(self, connection: Any, request: Any, response: Any) -> None:
        response.headers.update(SECURITY_HEADERS)

    async def _serve(self, ws: Any) -> None:
        loop = asyncio.get_running_loop()
        client = _Client(ws, loop)
        with self._lock:
            if len(self._clients) >= CLIENTS_MAX:  # two opened at once past the check
                await ws.close(1013, "too many clients")
                return
            self._clients.add(client)
            channels = [ch.advertised() for ch in self._channels.values()]
        client.say(
            {
                "op": "serverInfo",
                "name": self.name,
                "capabilities": ["time"],
                "metadata": {},
                "sessionId": str(time.time_ns()),
            }
        )
        if channels:
            client.say({"op": "advertise", "channels": channels})
        sender = asyncio.create_task(self._send(client))
        try:
            async for message in ws:
                self._receive(client, message)
        except Exception:  # noqa: BLE001 - a client gone, or its bad frame: it is closed
            pass
        finally:
            sender.cancel()
            with self._lock:
                self._clients.discard(client)
                for ch in client.subs.values():
                    self._watched[ch] -= 1
                client.subs.clear()

    async def _send(self, client: _Client) -> None:
        try:
            while True:
                await client.wake.wait()
                client.wake.clear()
                while (message := client.next()) is not None:
                    await client.ws.send(message)
                if client.overrun:
                    await client.ws.close(1008, "not reading its messages")
                    return
        except Exception:  # noqa: BLE001 - the connection closed under us
            return

    def _receive(self, client: _Client, message: str | bytes) -> None:
        """One message from a client; an error of its own is told to it, not printed."""
        if isinstance(message, bytes):
            client.say(_status("binary messages are not served here (no clientPublish)"))
            return
        try:
            request = json.loads(message)
        except (ValueError, RecursionError):
            client.say(_status("a message that is not JSON"))
            return
        op = request.get("op") if isinstance(request, dict) else None
        if op == "subscribe":
            self._subscribe(client, request.get("subscriptions"))
        elif op == "unsubscribe":
            self._unsubscribe(client, request.get("subscriptionIds"))
        else:
            client.say(_status("unsupported op: this server subscribes and unsubscribes"))

    def _subscribe(self, client: _Client, subs: object) -> None:
        if not isinstance(subs, list):
            client.say(_status("subscribe: 'subscriptions' is a list"))
            return
        for sub in subs:
            sid = sub.get("id") if isinstance(sub, dict) else None
            ch = sub.get("channelId") if isinstance(sub, dict) else None
            with self._lock:
                if not (_uint32(sid) and _uint32(ch)) or ch not in self._channels:
                    problem = "a subscription is {id, channelId} of an advertised channel"
                elif sid in client.subs or ch in client.subs.values():
                    problem = "a subscription id, or a channel, subscribed twice"
                else:
                    problem = ""
                    client.subs[sid] = ch  # type: ignore[index]
                    self._watched[ch] += 1  # type: ignore[index]
            if problem:
                client.say(_status(f"subscribe: {problem}"))

    def _unsubscribe(self, client: _Client, ids: object) -> None:
        if not isinstance(ids, list):
            client.say(_status("unsubscribe: 'subscriptionIds' is a list"))
            return
        with self._lock:
            for sid in ids:
                if _uint32(sid) and sid in client.subs:
                    self._watched[client.subs.pop(sid)] -= 1


def _uint32(x: object) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and 0 <= x < _U32


def _status(message: str) -> dict:
    return {"op": "status", "level": 2, "message": message}
