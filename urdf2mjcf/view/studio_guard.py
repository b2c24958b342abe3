"""MuJoCo Studio's web server behind our guard, installed in the viewer's process
(:mod:`.child`) before the Studio starts.

MuJoCo Studio 4.0's server answers any ``Host``, sends ``Access-Control-Allow-Origin: *``,
accepts WebSockets from any origin, takes models dropped on any page (``/drop``: files
of the page's choosing, which may name the user's own files by absolute path, whose
bytes ``/model`` then serves) and has no setting for any of it. Its request handling
is a set of closures handed to ``websockets``' ``serve``, which the Studio's module
looks up when it starts; :func:`install` puts ours in its place, which wraps the
Studio's own: every request passes :class:`..loopback_guard.Guard` first (loopback
``Host``, our origin or one the user named, the run's token), ``/drop`` is closed,
the wildcard CORS header is taken off every answer, and connections, their
messages and their opening are bounded. Whatever the page asks, the Studio loads
only the files the command line named (:class:`NamedModelsOnly`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable
from typing import Any

from ..loopback_guard import SECURITY_HEADERS, Guard
from ..untrusted import printable

CLIENTS_MAX = 64
"""Connections to the viewer at once (pages, their sockets and downloads); one more is 503."""
MESSAGE_MAX = 2**20
"""Bytes of one WebSocket message from a browser (its input and camera: under 1 kB)."""
OPEN_TIMEOUT_S = 10.0
"""Seconds a connection may take to send its request."""
CLOSED_PATHS = ("/drop",)
"""The Studio's endpoints we close: a model dropped on the page."""

_log = logging.getLogger(__name__)


class Gate:
    """Our guard for the Studio's server, made once its port is known."""

    def __init__(self, token: str, origins: Iterable[str] = ()) -> None:
        self.token = token
        self.origins = frozenset(origins)
        self.guard: Guard | None = None

    def url(self, port: int) -> str:
        return Guard(port, self.origins, self.token).url()

    def serve(self, original: Callable[..., Any]) -> Callable[..., Any]:
        """``original`` (websockets' ``serve``) with the Studio's handlers wrapped."""

        def serve(handler: Any, *args: Any, **kw: Any) -> Any:
            guard = self.guard = Guard(kw["sock"].getsockname()[1], self.origins, self.token)
            studio_request = kw.get("process_request")
            studio_response = kw.get("process_response")

            def process_request(connection: Any, request: Any) -> Any:
                h = request.headers
                refused = guard.check(
                    request.path,
                    h.get_all("Host"),
                    h.get_all("Origin"),
                    h.get_all("Sec-Fetch-Site"),
                    h.get_all("Cookie"),
                )
                if refused is not None:
                    return connection.respond(refused.status, refused.reason + "\n")
                if len(connection.server.all_connections) > CLIENTS_MAX:
                    return connection.respond(503, f"at most {CLIENTS_MAX} connections\n")
                if request.path.split("?", 1)[0] in CLOSED_PATHS:
                    return connection.respond(
                        403, "dropping a model is closed: the viewer shows the command's model\n"
                    )
                return studio_request(connection, request) if studio_request else None

            def process_response(connection: Any, request: Any, response: Any) -> Any:
                if studio_response is not None:
                    response = studio_response(connection, request, response) or response
                headers = response.headers  # websockets' Headers: setting a key adds a value
                extra = dict(SECURITY_HEADERS)
                if response.status_code < 400 and guard.token_in(request.path):
                    extra.update({"Set-Cookie": guard.set_cookie(), "Cache-Control": "no-store"})
                for key in ("Access-Control-Allow-Origin", *extra):
                    if key in headers:
                        del headers[key]
                headers.update(extra)
                return response

            async def guarded(ws: Any) -> None:
                if ws.request is not None and ws.request.path.split("?", 1)[0] in CLOSED_PATHS:
                    await ws.close(1008, "closed")  # refused above; never reached
                    return
                await handler(ws)

            kw.update(
                process_request=process_request,
                process_response=process_response,
                max_size=MESSAGE_MAX,
                open_timeout=OPEN_TIMEOUT_S,
            )
            return original(guarded, *args, **kw)

        serve.guarded = True  # type: ignore[attr-defined]
        return serve


def install(gate: Gate) -> None:
    """Put ``gate`` in front of the Studio's web server (before it starts)."""
    from mujoco.studio.web import web_server

    if not getattr(web_server.serve, "guarded", False):
        web_server.serve = gate.serve(web_server.serve)


def named_models_only(named: set[str]) -> Any:
    """A Studio plugin (sim side) that refuses to load any file but those in ``named``
    (absolute paths: the models the command line named), consuming the Studio's
    ``LoadModelEvent`` for any other: a drop that got through, a path the page sent."""
    from mujoco.studio import messages, plugin

    def only_named(self: Any, event: Any) -> bool:
        path = event.path or (self.handle.model_path if self._handle is not None else "")
        if not path or os.path.abspath(path) in named:
            return False  # the Studio's own handler loads it
        _log.warning("refused to load %s: the command line did not name it", printable(path))
        return True

    # The Studio finds the event a handler takes from its annotation: a class, not a string.
    only_named.__annotations__["event"] = messages.LoadModelEvent
    handler = messages.handler(only_named, priority=messages.Priority.CRITICAL)
    return type("NamedModelsOnly", (plugin.SimPlugin,), {"_only_named": handler})()
