"""Repairs of URDF bytes that urdfdom (TinyXML2) reads but libxml2 and expat reject.

Found in real descriptions: an XML declaration with a version other than
1.x, whitespace or a comment before the declaration, content after the
root element's end tag (a second ``</robot>``, stray text), and a namespace
prefix used without a declaration (``drake:acceleration`` in Drake's
exports; TinyXML2 knows no namespaces). Each repair is
reported as ``(element, message)``; the caller warns or, with ``--strict``,
fails. A document libxml2 already accepts comes back unchanged, and line
numbers stay those of the file.
"""

from __future__ import annotations

import re
import xml.parsers.expat

from lxml import etree

_BOM = b"\xef\xbb\xbf"
_DECL = re.compile(rb"<\?xml\s.*?\?>", re.S)
_LEADING = re.compile(rb"(?:\s|<!--.*?-->)+", re.S)
_VERSION = re.compile(rb"""(\bversion\s*=\s*)(["'])([^"']*)(["'])""")


def _well_formed(data: bytes) -> bool:
    try:
        etree.fromstring(data, parser=etree.XMLParser(resolve_entities=False))
    except etree.XMLSyntaxError:
        return False
    return True


def _declaration_first(data: bytes) -> tuple[bytes, str | None]:
    """Move a declaration preceded by whitespace or comments to the start."""
    bom = _BOM if data.startswith(_BOM) else b""
    body = data[len(bom) :]
    lead = _LEADING.match(body)
    if lead is None:
        return data, None
    decl = _DECL.match(body, lead.end())
    if decl is None:
        return data, None
    prefix = lead.group(0)
    what = "a comment" if b"<!--" in prefix else "whitespace"
    # The prefix goes after the declaration: comments survive, lines keep their numbers.
    fixed = bom + decl.group(0) + prefix + body[decl.end() :]
    return fixed, f"{what} before the XML declaration; read as if the declaration came first"


def _version(data: bytes) -> tuple[bytes, str | None]:
    """A declaration version libxml2 does not know (``0.0``) is read as 1.0."""
    bom = _BOM if data.startswith(_BOM) else b""
    decl = _DECL.match(data, len(bom))
    if decl is None:
        return data, None
    version = _VERSION.search(decl.group(0))
    if version is None or re.fullmatch(rb"1\.[0-9]+", version.group(3)):
        return data, None
    start, end = decl.start() + version.start(3), decl.start() + version.end(3)
    text = version.group(3).decode("utf-8", "replace")
    return data[:start] + b"1.0" + data[end:], f"version '{text}' is not XML 1.x; read as 1.0"


def _root_end(data: bytes) -> int | None:
    """Byte offset just past the root element's end tag, when junk follows it."""
    parser = xml.parsers.expat.ParserCreate()
    depth, end = 0, None

    def start(_name: str, _attrs: object) -> None:
        nonlocal depth
        depth += 1

    def stop(_name: str) -> None:
        nonlocal depth, end
        depth -= 1
        if depth == 0 and end is None:
            end = parser.CurrentByteIndex  # the '<' of the end tag (or of '/>')

    parser.StartElementHandler = start
    parser.EndElementHandler = stop
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError:
        if end is None:
            return None  # malformed inside the document: not ours to repair
        close = data.find(b">", end)
        return close + 1 if close >= 0 else None
    return None


def _trailing(data: bytes) -> tuple[bytes, str | None]:
    end = _root_end(data)
    if end is None:
        return data, None
    junk = data[end:].strip()
    shown = junk[:40].decode("utf-8", "replace").replace("\n", " ")
    return data[:end] + b"\n", f"content after the root element ('{shown}') ignored"


UNDECLARED_NAMESPACE = "urn:undeclared:{prefix}"
"""The URI an undeclared prefix is bound to: foreign to every pass, so ignored."""
_KNOWN_NAMESPACES = {"xacro": "http://www.ros.org/wiki/xacro"}
"""Prefixes whose meaning is not in doubt get their real namespace."""


def _undeclared(data: bytes) -> tuple[list[str], int | None]:
    """Prefixes used outside any declaration of theirs, first use first, and the
    byte offset just past the root element's name (None when expat cannot tell)."""
    parser = xml.parsers.expat.ParserCreate()  # no namespace processing: prefixes stay text
    scopes: list[set[str]] = []
    used: dict[str, None] = {}
    insert: int | None = None

    def start(name: str, attrs: dict[str, str]) -> None:
        nonlocal insert
        if insert is None:
            at = parser.CurrentByteIndex + 1
            raw = name.encode()
            insert = at + len(raw) if data[at : at + len(raw)] == raw else -1
        scopes.append({k[len("xmlns:") :] for k in attrs if k.startswith("xmlns:")})
        for qname in (name, *attrs):
            prefix, colon, _ = qname.partition(":")
            if not colon or prefix in ("xml", "xmlns") or prefix in used:
                continue
            if not any(prefix in scope for scope in scopes):
                used[prefix] = None

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda _name: scopes.pop()
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError:
        return [], None
    return list(used), insert if insert is not None and insert >= 0 else None


def _namespaces(data: bytes) -> tuple[bytes, list[str]]:
    """Declare each undeclared prefix on the root element, on its first line."""
    prefixes, at = _undeclared(data)
    if not prefixes or at is None:
        return data, []
    decls, messages = b"", []
    for prefix in prefixes:
        uri = _KNOWN_NAMESPACES.get(prefix, UNDECLARED_NAMESPACE.format(prefix=prefix))
        decls += f' xmlns:{prefix}="{uri}"'.encode()
        what = (
            "read as xacro's"
            if prefix in _KNOWN_NAMESPACES
            else f"declared as '{uri}': its elements and attributes are ignored"
        )
        messages.append(f"namespace prefix '{prefix}' is used but never declared; {what}")
    return data[:at] + decls + data[at:], messages


def repair(data: bytes) -> tuple[bytes, list[tuple[str, str]]]:
    """``data`` with the repairs it needs, and ``(element, message)`` for each one."""
    if _well_formed(data):
        return data, []
    fixes: list[tuple[str, str]] = []
    for element, step in (
        ("XML declaration", _declaration_first),
        ("XML declaration", _version),
        ("end of document", _trailing),
    ):
        data, message = step(data)
        if message:
            fixes.append((element, message))
    data, messages = _namespaces(data)
    fixes += [("XML namespaces", message) for message in messages]
    return data, fixes
