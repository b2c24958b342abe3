"""REP-2016 type hashes (``RIHS01_<sha256>``), computed from the type descriptions.

A type's description is its fields (name, type id, capacities, nested type name;
no constants, no defaults) and, sorted by name, the descriptions of every type it
uses, nested ones included. The hash is the sha256 of that description as Python's
``json.dumps`` writes it by default (``", "`` and ``": "`` separators, keys in the
order below), which is what ``rosidl_generator_type_description`` hashes. A service
is described as three fields, ``request_message``, ``response_message`` and
``event_message``, the event holding a ``service_msgs/msg/ServiceEventInfo`` and at
most one request and one response.
"""

from __future__ import annotations

import hashlib
import json
import re
from typing import Any

from .interfaces import MESSAGES, SERVICES, fields, full_name, nested, service_parts

# type_description_interfaces/msg/FieldType.msg
_TYPE_ID = {
    "int8": 2,
    "uint8": 3,
    "int16": 4,
    "uint16": 5,
    "int32": 6,
    "uint32": 7,
    "int64": 8,
    "uint64": 9,
    "float32": 10,
    "float64": 11,
    "float128": 12,
    "char": 13,
    "wchar": 14,
    "bool": 15,
    "byte": 16,
    "string": 17,
    "wstring": 18,
}
_NESTED = 1
_BOUNDED_STRING = 21
_ARRAY, _BOUNDED_SEQUENCE, _UNBOUNDED_SEQUENCE = 48, 96, 144
# a .msg file's char is IDL uint8 and its byte is IDL octet (rosidl_adapter)
_MSG_TO_IDL = {"char": "uint8", "byte": "byte"}
_SHAPE = re.compile(r"^(?P<base>[^\[]+)(?:\[(?P<bound><=)?(?P<size>\d*)\])?$")

RIHS01 = "RIHS01_"


def _field(name: str, kind: str, package: str, used: set[str]) -> dict[str, Any]:
    m = _SHAPE.match(kind)
    if m is None:
        raise ValueError(f"field type {kind!r}")
    base, size = m["base"], m["size"]
    increment, capacity = 0, 0
    if m.group(0) != base:  # an array or a sequence
        if not size:
            increment = _UNBOUNDED_SEQUENCE
        else:
            increment = _BOUNDED_SEQUENCE if m["bound"] else _ARRAY
            capacity = int(size)
    string_capacity, nested_name = 0, ""
    sub = nested(base)
    if sub is not None:
        type_id = _NESTED
        nested_name = full_name(sub, package)
        used.add(nested_name)
    elif base.startswith("string<="):
        type_id = _BOUNDED_STRING
        string_capacity = int(base.split("<=")[1])
    else:
        type_id = _TYPE_ID[_MSG_TO_IDL.get(base, base)]
    return {
        "name": name,
        "type": {
            "type_id": type_id + increment,
            "capacity": capacity,
            "string_capacity": string_capacity,
            "nested_type_name": nested_name,
        },
    }


def _bodies(type_name: str) -> dict[str, list[tuple[str, str]]]:
    """Type name -> its (type, name) fields, for ``type_name`` (a message or a
    service) and the parts rosidl makes of a service."""
    if type_name not in SERVICES:
        return {type_name: fields(MESSAGES[type_name])}
    parts = {k: fields(v) for k, v in service_parts(type_name).items()}
    parts[f"{type_name}_Event"] = [
        ("service_msgs/ServiceEventInfo", "info"),
        (f"{type_name}_Request[<=1]", "request"),
        (f"{type_name}_Response[<=1]", "response"),
    ]
    parts[type_name] = [
        (f"{type_name}_Request", "request_message"),
        (f"{type_name}_Response", "response_message"),
        (f"{type_name}_Event", "event_message"),
    ]
    return parts


def description(type_name: str) -> dict[str, Any]:
    """The hashed form of ``type_name``'s type description (``pkg/msg/Name`` or
    ``pkg/srv/Name``)."""
    bodies = _bodies(type_name)
    described: dict[str, dict[str, Any]] = {}
    pending = [type_name]
    while pending:
        name = pending.pop()
        if name in described:
            continue
        body = bodies.get(name) or fields(MESSAGES[name])
        used: set[str] = set()
        package = name.split("/")[0]
        fs = [_field(n, k, package, used) for k, n in body]
        if not fs:  # rosidl gives an empty message one placeholder member
            fs = [_field("structure_needs_at_least_one_member", "uint8", package, used)]
        described[name] = {"type_name": name, "fields": fs}
        pending.extend(sorted(used))
    return {
        "type_description": described[type_name],
        "referenced_type_descriptions": [described[k] for k in sorted(described) if k != type_name],
    }


def type_hash(type_name: str) -> str:
    """``RIHS01_`` and the sha256 (hex) of ``type_name``'s description."""
    text = json.dumps(description(type_name))
    return RIHS01 + hashlib.sha256(text.encode()).hexdigest()


def known_types() -> list[str]:
    """Every message and service type of :mod:`.interfaces`."""
    return sorted([*MESSAGES, *SERVICES])
