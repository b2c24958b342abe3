"""ROS 2 CDR encoding of a message given as a dict, from its ``ros2msg`` definition.

The live Foxglove stream (:mod:`.foxglove_live`) sends the recording's messages as a
ROS 2 publisher does: little-endian CDR (XCDR1, as Fast DDS and Cyclone DDS write
it), each value aligned to its size from the start of the payload after the 4-byte
encapsulation header. The writer of ``mcap-ros2-support`` does the same but is the
``ros`` extra; the stream needs only ``websockets`` (the ``live`` extra). Definitions are the text
:func:`.record.msgdef` makes (the type, then each type it uses after ``MSG: pkg/Name``).
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable
from typing import Any

Encoder = Callable[[bytearray, Any], None]

HEADER = b"\x00\x01\x00\x00"
"""Encapsulation: CDR, little-endian, no options."""

_PRIMITIVES = {
    "bool": "?",
    "byte": "B",
    "char": "B",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
_ARRAY = re.compile(r"^(.+?)\[(\d*)\]$")


def _align(buf: bytearray, size: int) -> None:
    pad = -(len(buf) - len(HEADER)) % size
    if pad:
        buf.extend(bytes(pad))


def _parse(definition: str, main: str) -> dict[str, list[tuple[str, str, str | None]]]:
    """Type name (``pkg/Name``) -> its fields (type, name, default or None), constants
    and comments left out."""
    types: dict[str, list[tuple[str, str, str | None]]] = {main: []}
    current = main
    for raw in definition.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line or line.startswith("==="):
            continue
        if line.startswith("MSG:"):
            current = line.split()[1]
            types[current] = []
            continue
        parts = line.split()
        if len(parts) < 2 or "=" in parts[1] or (len(parts) > 2 and parts[2].startswith("=")):
            continue  # a constant
        types[current].append((parts[0], parts[1], " ".join(parts[2:]) or None))
    return types


def _scalar(kind: str, package: str, types: dict, cache: dict[str, Encoder]) -> Encoder:
    if kind in _PRIMITIVES:
        s = struct.Struct("<" + _PRIMITIVES[kind])

        def primitive(buf: bytearray, v: Any) -> None:
            _align(buf, s.size)
            buf.extend(s.pack(v))

        return primitive
    if kind == "string":

        def string(buf: bytearray, v: Any) -> None:
            data = v.encode() + b"\0"
            _align(buf, 4)
            buf.extend(struct.pack("<I", len(data)))
            buf.extend(data)

        return string
    full = kind if "/" in kind else f"{package}/{kind}"
    if full not in cache:
        cache[full] = _message(full, types, cache)
    return lambda buf, v: cache[full](buf, v)


def _field(kind: str, package: str, types: dict, cache: dict[str, Encoder]) -> Encoder:
    m = _ARRAY.match(kind)
    if m is None:
        return _scalar(kind, package, types, cache)
    item, size = m.group(1), m.group(2)
    one = _scalar(item, package, types, cache)
    bytewise = item in ("uint8", "byte", "char")

    def array(buf: bytearray, v: Any) -> None:
        if size:
            if len(v) != int(size):
                raise ValueError(f"{kind}: {len(v)} values")
        else:
            _align(buf, 4)
            buf.extend(struct.pack("<I", len(v)))
        if bytewise and isinstance(v, (bytes, bytearray, memoryview)):
            buf.extend(v)  # images: the pixels as they are
            return
        for x in v:
            one(buf, x)

    return array


def _default(kind: str, given: str | None) -> Any:
    """A field's value where a message leaves it out: the definition's default, else
    zero, empty, or the nested message's defaults (as ``mcap-ros2-support`` does)."""
    m = _ARRAY.match(kind)
    if m is not None:
        return [_default(m.group(1), None)] * int(m.group(2)) if m.group(2) else []
    if kind == "string":
        return given.strip("'\"") if given else ""
    if kind == "bool":
        return given in ("true", "True", "1")
    if kind in ("float32", "float64"):
        return float(given) if given else 0.0
    if kind in _PRIMITIVES:
        return int(given, 0) if given else 0
    return {}


def _message(name: str, types: dict, cache: dict[str, Encoder]) -> Encoder:
    package = name.split("/")[0]
    fields = [
        (f, _field(kind, package, types, cache), _default(kind, given))
        for kind, f, given in types[name]
    ]

    def message(buf: bytearray, v: Any) -> None:
        for f, enc, default in fields:
            enc(buf, v.get(f, default))

    return message


def encoder(datatype: str, definition: str) -> Callable[[Any], bytes]:
    """Encoder of ``datatype`` (``pkg/msg/Name``) messages, given as dicts of its fields
    (nested messages as dicts, arrays as lists or, for bytes, ``bytes``; a field left
    out takes its default)."""
    pkg, _, name = datatype.split("/")
    main = f"{pkg}/{name}"
    types = _parse(definition, main)
    cache: dict[str, Encoder] = {}
    top = _message(main, types, cache)

    def encode(msg: Any) -> bytes:
        buf = bytearray(HEADER)
        top(buf, msg)
        return bytes(buf)

    return encode


# -- reading: what a subscriber or a service server takes in ------------------------------

Decoder = Callable[[memoryview, int], tuple[Any, int]]


def _read_align(offset: int, size: int) -> int:
    return offset + (-(offset - len(HEADER)) % size)


def _read_scalar(kind: str, package: str, types: dict, cache: dict[str, Decoder]) -> Decoder:
    if kind in _PRIMITIVES:
        s = struct.Struct("<" + _PRIMITIVES[kind])

        def primitive(buf: memoryview, at: int) -> tuple[Any, int]:
            at = _read_align(at, s.size)
            return s.unpack_from(buf, at)[0], at + s.size

        return primitive
    if kind == "string":

        def string(buf: memoryview, at: int) -> tuple[Any, int]:
            at = _read_align(at, 4)
            (n,) = struct.unpack_from("<I", buf, at)
            at += 4
            if n == 0 or at + n > len(buf) or buf[at + n - 1] != 0:
                raise ValueError("a string without its terminating NUL")
            return bytes(buf[at : at + n - 1]).decode(), at + n

        return string
    full = kind if "/" in kind else f"{package}/{kind}"
    if full not in cache:
        cache[full] = _read_message(full, types, cache)
    return lambda buf, at: cache[full](buf, at)


def _read_field(kind: str, package: str, types: dict, cache: dict[str, Decoder]) -> Decoder:
    m = _ARRAY.match(kind)
    if m is None:
        return _read_scalar(kind, package, types, cache)
    item, size = m.group(1), m.group(2)
    one = _read_scalar(item, package, types, cache)
    width = struct.calcsize("<" + _PRIMITIVES[item]) if item in _PRIMITIVES else 0

    def array(buf: memoryview, at: int) -> tuple[Any, int]:
        if size:
            n = int(size)
        else:
            at = _read_align(at, 4)
            (n,) = struct.unpack_from("<I", buf, at)
            at += 4
        if width and _read_align(at, width) + n * width > len(buf):  # more than it holds
            raise ValueError(f"{kind}: {n} values in {len(buf)} bytes")
        out = []
        for _ in range(n):
            v, at = one(buf, at)
            out.append(v)
        return out, at

    return array


def _read_message(name: str, types: dict, cache: dict[str, Decoder]) -> Decoder:
    package = name.split("/")[0]
    fields = [(f, _read_field(kind, package, types, cache)) for kind, f, _ in types[name]]

    def message(buf: memoryview, at: int) -> tuple[Any, int]:
        out = {}
        for f, dec in fields:
            out[f], at = dec(buf, at)
        return out, at

    return message


def decoder(datatype: str, definition: str) -> Callable[[bytes], dict[str, Any]]:
    """Decoder of ``datatype`` messages in little-endian CDR (what :func:`encoder`
    writes, and what a ROS 2 publisher sends), each to a dict of its fields; a payload
    that is not one (big-endian, cut short) raises ValueError."""
    pkg, _, name = datatype.split("/")
    main = f"{pkg}/{name}"
    types = _parse(definition, main)
    cache: dict[str, Decoder] = {}
    top = _read_message(main, types, cache)

    def decode(payload: bytes) -> dict[str, Any]:
        if payload[:2] != HEADER[:2]:
            raise ValueError(f"not little-endian CDR (header {payload[:4].hex()})")
        try:
            msg, _ = top(memoryview(payload), len(HEADER))
        except (struct.error, UnicodeDecodeError, IndexError) as exc:
            raise ValueError(f"{datatype}: {exc}") from None
        return msg

    return decode
