"""One way to read and check our YAML inputs (recipes, component tables, actuator
configs, waypoints files, rock settings): every error names the file, the key and,
where the key is in the file, its line.

:func:`load` reads a file with PyYAML's safe loader and keeps the line of every
key and list item; a :class:`Source` turns a dotted key (``placements.trainer.yaw``,
``steps[3].pose``) into ``file: key: message (line N)``. A key that is not in
the file (a missing one, or one a ``--set`` changed) gets the line of the nearest
enclosing key that is, unless a ``--set`` changed it: then no line, since the file
does not hold the value that is wrong.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from . import untrusted
from .errors import ForgeError, InputError

Key = tuple[str, ...]


def split_key(key: str) -> Key:
    """A key as our errors spell it, as a path: ``placements.trainer.yaw``,
    ``steps[3] 'grasp'.kind`` (a list index and the item's label) or
    ``joints: finger_.*: class`` (a mapping path whose names may hold dots)."""
    if ": " in key:
        return tuple(key.split(": "))
    key = re.sub(r" '[^']*'", "", key)
    key = re.sub(r"\[(\d+)\]", r".\1", key)
    return tuple(part for part in key.split(".") if part)


@dataclass
class Source:
    """A file read by :func:`load`: its path and the line of each key in it."""

    file: Path | str | None
    lines: dict[Key, int] = field(default_factory=dict)
    overridden: set[Key] = field(default_factory=set)
    """Keys whose value came from elsewhere (``--set``): they get no line."""
    error: type[ForgeError] = InputError

    def line(self, key: str) -> int | None:
        """The line of ``key`` (or of the nearest enclosing key in the file)."""
        path = split_key(key)
        if any(path[:n] in self.overridden for n in range(1, len(path) + 1)):
            return None
        for n in range(len(path), 0, -1):
            if path[:n] in self.lines:
                return self.lines[path[:n]]
        return None

    def fail(self, key: str, message: str) -> ForgeError:
        """The error for ``key``: ``file: key: message (line N)`` (the line last, so that
        the error's file and element stay a path and a key)."""
        line = self.line(key) if key else None
        text = f"{message} (line {line})" if line else message
        # the key may be a stranger's (a mapping key of any length): shown shortened
        shown = _quote(key, 120) if key else None
        return self.error(text, file=self.file or "input", element=shown)

    def number(self, value: Any, key: str) -> float:
        """A finite float (:func:`urdf2mjcf.untrusted.parse_number`), or an error naming
        the file and the key."""
        try:
            return untrusted.parse_number(value)
        except untrusted.BadNumber as exc:
            raise self.fail(key, str(exc)) from None

    def mapping(self, value: Any, key: str, what: str = "a mapping of keys to values") -> dict:
        """An optional mapping (None: {}), its keys as text."""
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            raise self.fail(key, f"'{_quote(value)}' is not {what}")
        return {str(k): v for k, v in value.items()}

    def known(self, data: Mapping, valid: Iterable[str], key: str = "") -> None:
        """Every key of ``data`` is one of ``valid``; else an error naming the first other."""
        valid = list(valid)
        for name in data:
            if str(name) not in valid:
                where = f"{key}.{_quote(name, 60)}" if key else _quote(name, 60)
                raise self.fail(where, f"unknown key; valid: {', '.join(valid) or 'none'}")

    def text(self, value: Any, key: str, *, required: bool = False) -> str | None:
        if value is None or value == "":
            if required:
                raise self.fail(key, "is required")
            return None
        if not isinstance(value, str):
            raise self.fail(key, f"'{_quote(value)}' is not text")
        return value


def _quote(value: Any, limit: int = 80) -> str:
    """What an error line may show of a value read from a file: one short line
    (a file that is not YAML parses as one long string; it is not echoed whole)."""
    return untrusted.excerpt(str(value), limit)


# -- the one YAML reader ---------------------------------------------------------------

_STR, _INT, _FLOAT, _BOOL = (f"tag:yaml.org,2002:{t}" for t in ("str", "int", "float", "bool"))
_NULL, _MERGE, _TIMESTAMP = (f"tag:yaml.org,2002:{t}" for t in ("null", "merge", "timestamp"))
_AMBIGUOUS = "tag:urdf2mjcf,2025:yaml-1.1"
"""A plain scalar YAML 1.1 and YAML 1.2 read differently: refused when it is built."""

_INT_TEXT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)")
_FLOAT_TEXT = re.compile(
    r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN)"
)
_LEADING_ZERO = re.compile(r"[-+]?0[0-9]+")
_BOOL_TEXT = frozenset(("true", "True", "TRUE", "false", "False", "FALSE"))
_BASE_12 = re.compile(r"[-+]?0(?:o[0-7]+|x[0-9a-fA-F]+)")
"""Octal and hexadecimal integers of YAML 1.2 (``0o17`` is text to YAML 1.1)."""
_YAML_11 = yaml.resolver.Resolver()
"""PyYAML's own (YAML 1.1) reading of a plain scalar, to find where it differs."""


def plain_tag(value: str) -> str:
    """The tag we read a plain (unquoted) scalar as: YAML 1.2's core schema (``true``,
    ``false``, decimal integers without a leading zero, decimal floats, ``.inf``,
    ``.nan``, ``null``; timestamps and ``<<`` merges as PyYAML reads them), and
    :data:`_AMBIGUOUS` where YAML 1.1 reads a boolean or a number that YAML 1.2 does
    not (``yes``, ``on``, ``1:30``, ``017``, ``1_000``, ``0b11``, ``0x10``) or YAML 1.2
    reads a number YAML 1.1 does not (``0o17``). Either reading would be a guess."""
    if _INT_TEXT.fullmatch(value):
        ours = _INT
    elif _LEADING_ZERO.fullmatch(value):
        return _AMBIGUOUS  # 017: 15 to YAML 1.1, 17 to YAML 1.2; 09: text, 9
    elif _FLOAT_TEXT.fullmatch(value):
        ours = _FLOAT
    elif value in _BOOL_TEXT:
        ours = _BOOL
    else:
        ours = _STR
    if len(value) > untrusted.NUMBER_TEXT_MAX:
        return _STR if ours in (_INT, _FLOAT) else ours  # too long: text, refused as a number
    old = _YAML_11.resolve(yaml.ScalarNode, value, (True, False))
    if ours == _STR and old in (_NULL, _MERGE, _TIMESTAMP):
        return old
    if (old in (_BOOL, _INT, _FLOAT) and old != ours) or _BASE_12.fullmatch(value):
        return _AMBIGUOUS
    return ours


class _Resolver(yaml.resolver.BaseResolver):
    def resolve(self, kind: Any, value: Any, implicit: Any) -> Any:
        if kind is yaml.ScalarNode and implicit[0]:
            return plain_tag(value)
        return super().resolve(kind, value, implicit)


class Refused(yaml.MarkedYAMLError):
    """A YAML document we do not guess at: a key given twice in one mapping, or a plain
    scalar YAML 1.1 and YAML 1.2 read differently."""


def _ambiguous(value: str) -> str:
    """Why the plain scalar ``value`` is refused, with what to write instead."""
    shown = untrusted.excerpt(value, 40)
    quote = "or quote it for text"
    sign, digits = ("-", value[1:]) if value[:1] == "-" else ("", value.lstrip("+"))
    if _LEADING_ZERO.fullmatch(value):
        octal = f"octal {sign}{int(digits, 8)}" if set(digits) <= set("01234567") else "text"
        return (
            f"'{shown}' has a leading zero ({octal} to YAML 1.1, {sign}{int(digits)} to "
            f"YAML 1.2): write the number without it, {quote}"
        )
    if _BASE_12.fullmatch(value):
        n = int(sign + digits[2:], 16 if digits[1] == "x" else 8)
        return f"'{shown}' is {n} in base {16 if digits[1] == 'x' else 8}: write {n}, {quote}"
    try:
        old = yaml.load(value, Loader=yaml.SafeLoader)  # noqa: S506 (the safe loader)
    except Exception:  # noqa: BLE001 (only the hint is lost)
        old = None
    if isinstance(old, bool):
        word = str(old).lower()
        return f"'{shown}' is {word} to YAML 1.1 and text to YAML 1.2: write {word}, {quote}"
    if isinstance(old, (int, float)):
        return (
            f"'{shown}' is the number {old:g} to YAML 1.1 and text to YAML 1.2: write "
            f"{old:g}, {quote}"
        )
    return f"'{shown}' is read differently by YAML 1.1 and YAML 1.2: {quote}"


class _Constructor(yaml.constructor.SafeConstructor):
    def construct_object(self, node: Any, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep)
        except yaml.YAMLError:
            raise
        except (ValueError, KeyError, TypeError, AttributeError, OverflowError) as exc:
            # an explicit tag PyYAML cannot build (!!int abc, !!bool maybe, !!timestamp x)
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"cannot read {node.tag} '{untrusted.excerpt(str(node.value), 40)}'"
                f" ({type(exc).__name__})",
                node.start_mark,
            ) from None

    def construct_bounded_number(self, node: Any) -> Any:
        """An int or float; text when it is longer than any number we read (a 5,000-digit
        integer is refused by the field's number reader, as any bad number is)."""
        if isinstance(node.value, str) and len(node.value) > untrusted.NUMBER_TEXT_MAX:
            return node.value
        if node.tag == _INT:
            return super().construct_yaml_int(node)
        x = super().construct_yaml_float(node)
        if math.isinf(x) and "inf" not in str(node.value).lower():
            return node.value  # 1e999: shown as written when it is refused
        return x

    def construct_ambiguous(self, node: Any) -> Any:
        raise Refused(None, None, _ambiguous(node.value), node.start_mark)


_Constructor.yaml_constructors = {  # our own table: xacro's units never reach it
    **yaml.constructor.SafeConstructor.yaml_constructors,
    _INT: _Constructor.construct_bounded_number,
    _FLOAT: _Constructor.construct_bounded_number,
    _AMBIGUOUS: _Constructor.construct_ambiguous,
}


class Loader(
    yaml.reader.Reader,
    yaml.scanner.Scanner,
    yaml.parser.Parser,
    yaml.composer.Composer,
    _Constructor,
    _Resolver,
):
    """Our YAML loader: PyYAML's safe constructor (no Python objects), YAML 1.2's reading
    of plain scalars (:func:`plain_tag`), no number longer than
    :data:`urdf2mjcf.untrusted.NUMBER_TEXT_MAX` characters. Every file we read goes
    through :func:`parse`, which adds the alias-bomb and duplicate-key checks; a loader
    with tags of its own (xacro's units) may subclass this one."""

    def __init__(self, stream: Any) -> None:
        yaml.reader.Reader.__init__(self, stream)
        yaml.scanner.Scanner.__init__(self)
        yaml.parser.Parser.__init__(self)
        yaml.composer.Composer.__init__(self)
        _Constructor.__init__(self)
        _Resolver.__init__(self)


def _key_text(loader: Loader, node: Any) -> str:
    if isinstance(node, yaml.ScalarNode):
        return str(loader.construct_object(node))
    return untrusted.excerpt(str(node.value), 40)


def _unique(loader: Loader, node: yaml.MappingNode, path: Key) -> None:
    """Each key of the mapping ``node`` once (a merge's keys are overridden on purpose):
    else :class:`Refused` naming both lines. Keys equal as Python keys (``1``, ``1.0``,
    ``true``) or as our text (``1``, ``'1'``) are the same key."""
    seen: dict[Any, tuple[int, int]] = {}
    for key_node, _ in node.value:
        if key_node.tag == _MERGE or not isinstance(key_node, yaml.ScalarNode):
            continue  # a non-scalar key is refused when it is built (unhashable)
        key = loader.construct_object(key_node)
        names: list[Any] = [("text", str(key))]
        try:
            hash(key)
            names.append(("value", key))
        except TypeError:
            pass
        mark = key_node.start_mark
        at = (mark.line + 1, mark.column + 1)
        first = next((seen[n] for n in names if n in seen), None)
        if first is not None:
            where = untrusted.excerpt(".".join(path + (str(key),)), 60)
            lines = (
                f"lines {first[0]} and {at[0]}"
                if first[0] != at[0]
                else f"line {at[0]}, columns {first[1]} and {at[1]}"
            )
            raise Refused(None, None, f"duplicate key on {lines}: {where}", mark)
        for n in names:
            seen[n] = at


def _index(loader: Loader, root: Any) -> dict[Key, int]:
    """The line of every key and list item of the composed document ``root``, its
    mappings checked for duplicate keys (:func:`_unique`); iterative (a deep document
    must not exhaust Python's stack). A key a merge (``<<``) brings in gets the line
    of its own mapping, unless the mapping merged into gives it."""
    lines: dict[Key, int] = {}
    checked: set[int] = set()
    stack: list[tuple[Any, Key]] = [(root, ())]
    while stack:
        node, path = stack.pop()
        if isinstance(node, yaml.MappingNode):
            if id(node) not in checked:
                checked.add(id(node))
                _unique(loader, node, path)
            merged: list[Any] = []
            for key_node, value_node in node.value:
                if key_node.tag == _MERGE:
                    merged.extend(
                        value_node.value
                        if isinstance(value_node, yaml.SequenceNode)
                        else [value_node]
                    )
                    continue
                key = path + (_key_text(loader, key_node),)
                lines.setdefault(key, key_node.start_mark.line + 1)
                stack.append((value_node, key))
            stack.extend((m, path) for m in reversed(merged))
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                key = path + (str(i),)
                lines.setdefault(key, item.start_mark.line + 1)
                stack.append((item, key))
    return lines


def parse(text: str | bytes, loader_type: type[Loader] = Loader) -> tuple[Any, dict[Key, int]]:
    """YAML text's data and the line of each key, read by our :class:`Loader` (or
    ``loader_type``, a subclass with tags of its own);
    yaml.YAMLError when it is not YAML, when its aliases expand it past
    :data:`urdf2mjcf.untrusted.YAML_MAX_NODES` nodes (a 'billion laughs' document:
    refused before it is built), and :class:`Refused` (a YAMLError) when a mapping
    holds a key twice or a plain scalar is read differently by YAML 1.1 and 1.2."""
    loader = loader_type(text)
    try:
        node = loader.get_single_node()
        if node is not None:
            try:
                untrusted.check_yaml_size(node)
            except untrusted.YamlBombError as exc:
                raise yaml.YAMLError(str(exc)) from None
        lines = _index(loader, node) if node is not None else {}
        data = loader.construct_document(node) if node is not None else None
    except RecursionError:  # PyYAML composes recursively
        raise yaml.YAMLError("nested too deeply") from None
    finally:
        loader.dispose()
    return data, lines


def load(path: Path | str, what: str, error: type[ForgeError] = InputError) -> tuple[Any, Source]:
    """A YAML file's data and its :class:`Source`; an ``error`` naming the file (and the
    line) when it is missing, unreadable, not text or not YAML."""
    # regular files only, at most the yaml size limit: a FIFO or /dev/zero is refused
    try:
        raw = untrusted.read_file(path, "yaml", error=error, what="file")
    except ForgeError as exc:
        raise error(f"cannot read {what}: {exc.detail}", file=path) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise error(f"cannot read {what}: not a text file", file=path) from None
    try:
        data, lines = parse(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        problem = getattr(exc, "problem", None) or (str(exc).splitlines() or ["?"])[0]
        raise error(
            f"{what} is not valid YAML: {_quote(problem)}", file=path, element=where
        ) from None
    return data, Source(path, lines, error=error)
