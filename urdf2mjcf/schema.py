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
from .errors import ConversionError, InputError

Key = tuple[str, ...]


def _walk(node: yaml.Node | None, path: Key, lines: dict[Key, int]) -> None:
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            key = path + (str(key_node.value),)
            lines.setdefault(key, key_node.start_mark.line + 1)
            _walk(value_node, key, lines)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            key = path + (str(i),)
            lines.setdefault(key, item.start_mark.line + 1)
            _walk(item, key, lines)


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
    error: type[ConversionError] = InputError

    def line(self, key: str) -> int | None:
        """The line of ``key`` (or of the nearest enclosing key in the file)."""
        path = split_key(key)
        if any(path[:n] in self.overridden for n in range(1, len(path) + 1)):
            return None
        for n in range(len(path), 0, -1):
            if path[:n] in self.lines:
                return self.lines[path[:n]]
        return None

    def fail(self, key: str, message: str) -> ConversionError:
        """The error for ``key``: ``file: key: message (line N)`` (the line last, so that
        the error's file and element stay a path and a key)."""
        line = self.line(key) if key else None
        text = f"{message} (line {line})" if line else message
        # the key may be a stranger's (a mapping key of any length): shown shortened
        shown = _quote(key, 120) if key else None
        return self.error(text, file=self.file or "input", element=shown)

    def number(self, value: Any, key: str) -> float:
        """A finite float, or an error naming the file and the key."""
        if isinstance(value, bool):
            raise self.fail(key, f"'{value}' is not a number")
        try:
            x = float(value)
        except (TypeError, ValueError, OverflowError):
            raise self.fail(key, f"'{_quote(value)}' is not a number") from None
        if not math.isfinite(x):
            raise self.fail(key, f"'{_quote(value)}' is not finite")
        return x

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


def parse(text: str) -> tuple[Any, dict[Key, int]]:
    """YAML text's data and the line of each key; yaml.YAMLError when it is not YAML,
    or when its aliases expand it past :data:`urdf2mjcf.untrusted.YAML_MAX_NODES`
    nodes (a 'billion laughs' document: refused before it is built)."""
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is not None:
            try:
                untrusted.check_yaml_size(node)
            except untrusted.YamlBombError as exc:
                raise yaml.YAMLError(str(exc)) from None
        data = loader.construct_document(node) if node is not None else None
    except RecursionError:  # PyYAML composes and constructs recursively
        raise yaml.YAMLError("nested too deeply") from None
    finally:
        loader.dispose()
    lines: dict[Key, int] = {}
    _walk(node, (), lines)
    return data, lines


def load(
    path: Path | str, what: str, error: type[ConversionError] = InputError
) -> tuple[Any, Source]:
    """A YAML file's data and its :class:`Source`; an ``error`` naming the file (and the
    line) when it is missing, unreadable, not text or not YAML."""
    # regular files only, at most the yaml size limit: a FIFO or /dev/zero is refused
    try:
        raw = untrusted.read_file(path, "yaml", error=error, what="file")
    except ConversionError as exc:
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
