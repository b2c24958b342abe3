"""The 33 bytes rmw_zenoh attaches to every sample, query and reply.

Little-endian int64 sequence number, int64 source timestamp (ns since the UNIX
epoch), one byte for the GID's length (16, how Zenoh's serializer writes an array's
length, as a LEB128 varint) and the 16 bytes of the writer's GID (for a service's
reply: the client's GID and sequence number from its request).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

GID_SIZE = 16
_HEAD = struct.Struct("<qqB")
SIZE = _HEAD.size + GID_SIZE


@dataclass(frozen=True)
class Attachment:
    sequence: int
    timestamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        if len(self.gid) != GID_SIZE:
            raise ValueError(f"a GID is {GID_SIZE} bytes, not {len(self.gid)}")
        return _HEAD.pack(self.sequence, self.timestamp_ns, GID_SIZE) + self.gid


def decode(data: bytes) -> Attachment:
    """An attachment's fields, else ValueError (wrong size or GID length)."""
    if len(data) != SIZE:
        raise ValueError(f"an rmw_zenoh attachment is {SIZE} bytes, not {len(data)}")
    sequence, stamp, size = _HEAD.unpack_from(data)
    if size != GID_SIZE:
        raise ValueError(f"GID length {size}, not {GID_SIZE}")
    return Attachment(sequence, stamp, bytes(data[_HEAD.size :]))
