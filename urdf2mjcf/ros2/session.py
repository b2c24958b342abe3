"""One ROS 2 node on one Zenoh session, as rmw_zenoh makes one: its liveliness tokens,
publishers, subscriptions and service servers, CDR in and out.

Callbacks (a sample, a query) run on Zenoh's threads: they get the decoded message
and must only hand it on (the server queues it for its simulation thread).
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..runner import cdr
from . import attachment, interfaces, keyexpr, liveliness

log = logging.getLogger(__name__)

ROUTER = "tcp/localhost:7447"
"""Where rmw_zenoh's router (``rmw_zenohd``) listens by default."""


@dataclass(frozen=True)
class Endpoints:
    """Where the session listens and what it connects to (Zenoh endpoints,
    ``tcp/HOST:PORT``)."""

    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()


def zenoh_config(endpoints: Endpoints) -> Any:
    """A peer's configuration as rmw_zenoh's default session one: no multicast
    scouting, gossip on, timestamps (the latched topics' caches need them)."""
    import zenoh

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps(list(endpoints.listen)))
    conf.insert_json5("connect/endpoints", json.dumps(list(endpoints.connect)))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "true")
    conf.insert_json5("timestamping/enabled", "true")
    return conf


class Publisher:
    def __init__(self, node: Node, name: str, type_name: str, qos: keyexpr.QoS) -> None:
        import zenoh.ext

        self.name, self.type_name = name, type_name
        self._encode = cdr.encoder(type_name, interfaces.definition_text(type_name))
        token = node.declare((node.next_id(), "MP"), name, type_name, qos)
        self._gid = liveliness.gid(token)
        key = keyexpr.data_keyexpr(node.info.domain, name, type_name)
        self._pub: Any
        if qos.durability == keyexpr.TRANSIENT_LOCAL:
            # a late subscriber (rmw_zenoh's advanced one) queries this cache
            self._pub = zenoh.ext.declare_advanced_publisher(
                node.session,
                key,
                cache=zenoh.ext.CacheConfig(max_samples=qos.depth),
                publisher_detection=True,
            )
        else:
            self._pub = node.session.declare_publisher(key)
        self._sequence = 0

    @property
    def matched(self) -> bool:
        """Whether a subscriber matches (a latched topic's cache: always)."""
        status = getattr(self._pub, "matching_status", None)
        return True if status is None else bool(status.matching)

    def publish(self, msg: dict[str, Any]) -> None:
        self._sequence += 1
        att = attachment.Attachment(self._sequence, time.time_ns(), self._gid)
        self._pub.put(self._encode(msg), attachment=att.encode())


class Node:
    """A ROS 2 node named ``name`` in ``namespace`` on a new Zenoh session."""

    def __init__(self, endpoints: Endpoints, domain: int, name: str, namespace: str = "/") -> None:
        import zenoh

        self.session = zenoh.open(zenoh_config(endpoints))
        self.info = liveliness.Node(domain, str(self.session.zid()), name, namespace)
        self._ids = 0
        self._held: list[Any] = []  # tokens, subscribers, queryables: alive while held
        self._held.append(self.session.liveliness().declare_token(self.info.token()))

    def next_id(self) -> int:
        self._ids += 1
        return self._ids

    def declare(self, kind: tuple[int, str], name: str, type_name: str, qos: keyexpr.QoS) -> str:
        entity_id, what = kind
        token = self.info.endpoint(entity_id, what, name, type_name, qos)
        self._held.append(self.session.liveliness().declare_token(token))
        return token

    def publisher(self, name: str, type_name: str, qos: keyexpr.QoS = keyexpr.DEFAULT) -> Publisher:
        return Publisher(self, name, type_name, qos)

    def subscribe(
        self,
        name: str,
        type_name: str,
        callback: Callable[[dict[str, Any]], None],
        qos: keyexpr.QoS = keyexpr.DEFAULT,
        on_bad: Callable[[str], None] | None = None,
    ) -> None:
        """``callback(message)`` for each sample on ``name``; a payload that does not
        decode goes to ``on_bad(reason)`` instead."""
        decode = cdr.decoder(type_name, interfaces.definition_text(type_name))
        self.declare((self.next_id(), "MS"), name, type_name, qos)

        def sample(s: Any) -> None:
            try:
                msg = decode(s.payload.to_bytes())
            except ValueError as exc:
                if on_bad is not None:
                    on_bad(f"{name}: {exc}")
                return
            callback(msg)

        key = keyexpr.data_keyexpr(self.info.domain, name, type_name)
        self._held.append(self.session.declare_subscriber(key, sample))

    def service(
        self,
        name: str,
        type_name: str,
        handler: Callable[[dict[str, Any]], dict[str, Any]],
        on_bad: Callable[[str], None] | None = None,
    ) -> None:
        """A service server: ``handler(request) -> response`` for each query (run on
        Zenoh's thread; it may block until the simulation has answered)."""
        self.deferred_service(name, type_name, lambda req, reply: reply(handler(req)), on_bad)

    def deferred_service(
        self,
        name: str,
        type_name: str,
        handler: Callable[[dict[str, Any], Callable[[dict[str, Any]], None]], None],
        on_bad: Callable[[str], None] | None = None,
    ) -> None:
        """A service server whose ``handler(request, reply)`` may answer later, from any
        thread, by ``reply(response)`` (an action's get_result waits for its goal's end
        that way without holding Zenoh's thread)."""
        decode = cdr.decoder(
            f"{type_name}_Request", interfaces.definition_text(f"{type_name}_Request")
        )
        encode = cdr.encoder(
            f"{type_name}_Response", interfaces.definition_text(f"{type_name}_Response")
        )
        self.declare((self.next_id(), "SS"), name, type_name, keyexpr.DEFAULT)

        def query(q: Any) -> None:
            try:
                request = decode(q.payload.to_bytes() if q.payload is not None else b"")
                asked = attachment.decode(q.attachment.to_bytes()) if q.attachment else None
            except ValueError as exc:
                if on_bad is not None:
                    on_bad(f"{name}: {exc}")
                return

            def reply(response: dict[str, Any]) -> None:
                # the reply carries the request's sequence number and client GID back
                att = attachment.Attachment(
                    asked.sequence if asked else 0,
                    time.time_ns(),
                    asked.gid if asked else bytes(attachment.GID_SIZE),
                )
                try:
                    q.reply(q.key_expr, encode(response), attachment=att.encode())
                finally:
                    q.drop()  # the query's end: the client's get returns

            try:
                handler(request, reply)
            except Exception:  # noqa: BLE001 - a bug: said, and the client times out
                log.exception("%s: the service failed", name)

        key = keyexpr.data_keyexpr(self.info.domain, name, type_name)
        self._held.append(self.session.declare_queryable(key, query, complete=True))

    def close(self) -> None:
        """Tokens withdrawn (the graph forgets the node), the session closed."""
        for h in reversed(self._held):
            try:
                h.undeclare()
            except Exception:  # noqa: BLE001 - already gone with a closing session
                pass
        self._held.clear()
        self.session.close()
