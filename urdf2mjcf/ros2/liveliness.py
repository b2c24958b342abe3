"""rmw_zenoh's graph: the liveliness tokens a node and each of its endpoints declare.

``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/
<node name>`` for a node (kind ``NN``, entity id = node id), the same followed by
``/<mangled topic>/<DDS type name>/<type hash>/<qos>`` for a publisher (``MP``), a
subscription (``MS``), a service server (``SS``) or client (``SC``); names mangled
(``/`` -> ``%``; an empty namespace or enclave is ``%``). ``ros2 node list`` and
``ros2 topic list -t`` on an rmw_zenoh system read these.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

from .keyexpr import QoS, check_name, dds_type_name, mangle
from .type_hash import type_hash

PREFIX = "@ros2_lv"
KINDS = ("NN", "MP", "MS", "SS", "SC")


@dataclass(frozen=True)
class Node:
    """A node of one Zenoh session."""

    domain: int
    session_id: str
    """The Zenoh session id, as Zenoh writes it (lowercase hex)."""
    name: str
    namespace: str = "/"
    node_id: int = 0
    enclave: str = "/"

    def prefix(self, entity_id: int, kind: str) -> str:
        if kind not in KINDS:
            raise ValueError(f"entity kind {kind!r}; one of {', '.join(KINDS)}")
        return "/".join(
            [
                PREFIX,
                str(self.domain),
                self.session_id,
                str(self.node_id),
                str(entity_id),
                kind,
                mangle(self.enclave) if self.enclave != "/" else "%",
                mangle(self.namespace) if self.namespace != "/" else "%",
                self.name,
            ]
        )

    def token(self) -> str:
        """The node's own token."""
        return self.prefix(self.node_id, "NN")

    def endpoint(self, entity_id: int, kind: str, name: str, type_name: str, qos: QoS) -> str:
        """The token of the node's endpoint ``entity_id`` on topic or service ``name``."""
        check_name(name)
        return "/".join(
            [
                self.prefix(entity_id, kind),
                mangle(name),
                dds_type_name(type_name),
                type_hash(type_name),
                qos.keyexpr(),
            ]
        )


def gid(token: str) -> bytes:
    """An endpoint's 16-byte GID, derived from its token as rmw_zenoh derives its own
    (there with XXH3-128; any stable 16 bytes serve: peers read GIDs, never recompute
    them)."""
    return hashlib.sha256(token.encode()).digest()[:16]


@dataclass(frozen=True)
class Entity:
    """A token read back: what a graph cache learns from it."""

    domain: int
    session_id: str
    node_id: str
    entity_id: str
    kind: str
    enclave: str
    namespace: str
    node_name: str
    topic: str | None = None
    type_name: str | None = None
    type_hash: str | None = None
    qos: str | None = None


def parse(token: str) -> Entity:
    """A token's parts (names demangled), else ValueError."""
    parts = token.split("/")
    if parts[0] != PREFIX or len(parts) not in (9, 13) or parts[5] not in KINDS:
        raise ValueError(f"not an rmw_zenoh liveliness token: {token!r}")
    demangle = lambda s: s.replace("%", "/")  # noqa: E731
    topic = None
    if len(parts) == 13:
        topic = demangle(parts[9])
    return Entity(
        domain=int(parts[1]),
        session_id=parts[2],
        node_id=parts[3],
        entity_id=parts[4],
        kind=parts[5],
        enclave=demangle(parts[6]),
        namespace=demangle(parts[7]),
        node_name=parts[8],
        topic=topic,
        type_name=parts[10] if topic else None,
        type_hash=parts[11] if topic else None,
        qos=parts[12] if topic else None,
    )
