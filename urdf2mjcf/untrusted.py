"""Reading input written by a stranger: regular files only, within a size, YAML
without alias bombs, numbers that are finite and in range, text safe for a terminal.

Every reader of a file a description, recipe, cache entry or user names goes
through :func:`read_file` (or :func:`check_regular` where a library opens the
path itself): a FIFO, a device or a socket is refused before it is opened (a
FIFO would block forever, ``/dev/zero`` would fill memory), and a regular file
larger than its kind's limit is refused before it is read.

The limits (megabytes) are in :data:`LIMITS_MB`, each overridable by an
environment variable ``URDF2MJCF_MAX_<KIND>_MB`` (``docs/security.md`` lists
them from this table).
"""

from __future__ import annotations

import math
import numbers
import os
import re
import stat
import unicodedata
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .errors import BadNumber, ConversionError, ForgeError, InputError, YamlBombError

LIMITS_MB: dict[str, tuple[float, str]] = {
    "description": (64, "a URDF, xacro or MJCF file and each file it includes"),
    "mesh": (512, "a mesh file (STL, OBJ, DAE, PLY) and the files it pulls in (.mtl)"),
    "texture": (256, "an image file a material or an MJCF asset names"),
    "yaml": (16, "a recipe, actuator config, waypoints or component YAML file"),
    "cache_entry": (2048, "one cache entry (the whole cache: $URDF2MJCF_CACHE_MAX_MB)"),
    "report": (64, "a JSON file we read back (an earlier manifest or report)"),
    "log": (1024, "a robot's log that calibrate reads (CSV, or a bag's .mcap or .db3 file)"),
}
"""Each kind of file's default size limit in MB, and what it covers."""

YAML_MAX_NODES = 200_000
"""A YAML document may expand to at most this many nodes, aliases counted each time
they are used (a 'billion laughs' document is a few hundred bytes and 10**9 nodes)."""

_KIND_ENV = "URDF2MJCF_MAX_{}_MB"


def limit_env(kind: str) -> str:
    """The environment variable that overrides ``kind``'s limit."""
    return _KIND_ENV.format(kind.upper())


def limit_bytes(kind: str) -> int:
    """``kind``'s size limit in bytes, from its environment variable or the default."""
    default, _ = LIMITS_MB[kind]
    name = limit_env(kind)
    raw = os.environ.get(name, "").strip()
    mb = float(default)
    if raw:
        mb = env_number(name, raw, low=0.001, high=1e7)
    return int(mb * 1024 * 1024)


def env_number(name: str, raw: str, *, low: float, high: float) -> float:
    """An environment variable's value as a finite number in [low, high]; an InputError
    naming the variable otherwise (the error contract: one line, exit 2)."""
    try:
        return read_number(raw, low=low, high=high)
    except BadNumber as exc:
        raise InputError(str(exc), file=f"${name}") from None


def _kind_of(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_regular(
    path: Path | str,
    kind: str,
    *,
    error: type[ForgeError] = InputError,
    element: str | None = None,
    what: str = "file",
) -> int:
    """The size of ``path`` (symlinks followed), or ``error`` when it is missing, not a
    regular file or larger than ``kind``'s limit. Opens nothing."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{what} not found: {path}", file=path, element=element) from None
    except OSError as exc:
        raise error(
            f"cannot read {what} {path}: {exc.strerror or exc}", file=path, element=element
        ) from None
    if not stat.S_ISREG(st.st_mode):
        raise error(
            f"{what} {path} is {_kind_of(st.st_mode)}, not a regular file; refused",
            file=path,
            element=element,
        )
    limit = limit_bytes(kind)
    if st.st_size > limit:
        raise error(
            f"{what} {path} is {st.st_size / 2**20:.1f} MB, over the {kind} limit of "
            f"{limit / 2**20:g} MB (set ${limit_env(kind)} to raise it)",
            file=path,
            element=element,
        )
    return st.st_size


def read_file(
    path: Path | str,
    kind: str,
    *,
    error: type[ForgeError] = InputError,
    element: str | None = None,
    what: str = "file",
) -> bytes:
    """The bytes of the regular file ``path``, at most ``kind``'s limit; ``error`` for
    anything else. The check is repeated on the open descriptor (no blocking open:
    a FIFO swapped in after the first check cannot hang us)."""
    check_regular(path, kind, error=error, element=element, what=what)
    limit = limit_bytes(kind)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise error(f"{what} not found: {path}", file=path, element=element) from None
    except OSError as exc:
        raise error(
            f"cannot read {what} {path}: {exc.strerror or exc}", file=path, element=element
        ) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise error(
                f"{what} {path} is {_kind_of(st.st_mode)}, not a regular file; refused",
                file=path,
                element=element,
            )
        chunks = []
        total = 0
        while True:
            chunk = os.read(fd, min(1 << 22, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > limit:  # grew since the check
                raise error(
                    f"{what} {path} is over the {kind} limit of {limit / 2**20:g} MB "
                    f"(set ${limit_env(kind)} to raise it)",
                    file=path,
                    element=element,
                )
        return b"".join(chunks)
    except OSError as exc:
        raise error(
            f"cannot read {what} {path}: {exc.strerror or exc}", file=path, element=element
        ) from None
    finally:
        os.close(fd)


def is_regular(path: Path | str) -> bool:
    """Whether ``path`` (symlinks followed) is a regular file; never raises."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


# -- YAML --------------------------------------------------------------------------------


def check_yaml_size(node: Any, limit: int = YAML_MAX_NODES) -> None:
    """Raise :class:`YamlBombError` when the composed node graph ``node`` expands (each
    alias counted every time it is used) to more than ``limit`` nodes. Linear in the
    graph: each node's expanded size is computed once."""
    import yaml

    sizes: dict[int, int] = {}
    # iterative post-order: a 100,000-deep document must not exhaust Python's stack
    stack: list[tuple[Any, bool]] = [(node, False)]
    while stack:
        n, done = stack.pop()
        if n is None or id(n) in sizes:
            continue
        if isinstance(n, yaml.MappingNode):
            children = [c for pair in n.value for c in pair]
        elif isinstance(n, yaml.SequenceNode):
            children = list(n.value)
        else:
            children = []
        if done:
            total = 1 + sum(sizes.get(id(c), 0) for c in children)
            sizes[id(n)] = total
            if total > limit:
                raise YamlBombError(
                    f"expands to more than {limit} nodes through its aliases (refused)"
                )
            continue
        stack.append((n, True))
        stack.extend((c, False) for c in children if id(c) not in sizes)


# -- numbers -----------------------------------------------------------------------------

NUMBER_TEXT_MAX = 100
"""Characters of a number written as text (the longest double needs 24): a longer one is
refused as a bad number, never parsed (``int()`` of 5,000 digits raises, of 100,000
takes seconds)."""

_DECIMAL = re.compile(r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
"""A number as text: decimal digits, a point, an exponent. Not ``0x10``, ``1_000``,
``1:30`` or ``infinity``, which Python's ``float`` or YAML 1.1 would read as numbers."""
_LEADING_ZERO = re.compile(r"[-+]?0[0-9]")
_INTEGER = re.compile(r"[-+]?[0-9]+")


def shown(value: Any, limit: int = 40) -> str:
    """``value`` as an error line quotes it: short, one line, printable (an integer too
    long for ``str`` is described, not converted)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 4000:
        return f"an integer of {value.bit_length():,} bits"
    return excerpt(str(value), limit)


def parse_number(value: Any) -> float:
    """``value`` as a finite float: an int or float (not a bool), or text of decimal
    digits with an optional point and exponent, at most :data:`NUMBER_TEXT_MAX`
    characters and without a leading zero (``017`` is 15 to YAML 1.1). Else
    :class:`BadNumber` saying why. The one reader of a number from a file, a command
    line, the environment or a request."""
    if isinstance(value, bool):
        raise BadNumber(f"'{value}' is not a number")
    if isinstance(value, str):
        text = value.strip()
        if len(text) > NUMBER_TEXT_MAX:
            raise BadNumber(
                f"'{excerpt(text, 40)}' is not a number ({len(text):,} characters; "
                f"at most {NUMBER_TEXT_MAX})"
            )
        if not _DECIMAL.fullmatch(text):
            if text.lower().lstrip("+-") in ("inf", "infinity", "nan", ".inf", ".nan"):
                raise BadNumber(f"'{excerpt(text, 40)}' is not finite")
            raise BadNumber(f"'{excerpt(text, 40)}' is not a number")
        if _LEADING_ZERO.match(text) and _INTEGER.fullmatch(text):
            raise BadNumber(
                f"'{text}' is not a number: a leading zero is octal in YAML 1.1; write it without"
            )
        x = float(text)
    elif isinstance(value, numbers.Real):  # int, float, numpy's
        try:
            x = float(value)
        except OverflowError:  # an integer of 400 digits
            raise BadNumber(f"'{shown(value)}' is out of range") from None
    else:
        raise BadNumber(f"'{shown(value)}' is not a number")
    if not math.isfinite(x):
        raise BadNumber(f"'{shown(value)}' is not finite")
    return x


def range_text(low: float, high: float, low_open: bool = False) -> str:
    """``[low, high]`` in words, as every out-of-range error says it."""
    return f"{'above' if low_open else 'from'} {low:g} to {high:g}"


def read_number(
    value: Any, *, low: float = -math.inf, high: float = math.inf, low_open: bool = False
) -> float:
    """``value`` as a finite float in [low, high] (``(low, high]`` with ``low_open``);
    else :class:`BadNumber` (see :func:`parse_number`). What a reader that answers a
    request (the console) calls: its message is the answer's."""
    x = parse_number(value)
    too_low = x <= low if low_open else x < low
    if too_low or x > high:
        raise BadNumber(f"{x:g} is out of range ({range_text(low, high, low_open)})")
    return x


def read_whole(value: Any, *, low: int, high: int) -> int:
    """``value`` as an integer in [low, high]: an int (not a bool) or its decimal digits
    as text (at most :data:`NUMBER_TEXT_MAX`, no leading zero); else :class:`BadNumber`."""
    n: int | None = None
    if isinstance(value, int) and not isinstance(value, bool):
        n = value
    elif isinstance(value, str):
        text = value.strip()
        if len(text) <= NUMBER_TEXT_MAX and _INTEGER.fullmatch(text):
            if not (_LEADING_ZERO.match(text)):
                n = int(text)
    if n is None or not low <= n <= high:
        raise BadNumber(f"'{shown(value)}' is not a whole number from {low} to {high}")
    return n


def finite(
    value: Any,
    where: str,
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    error: Callable[[str], ConversionError] | None = None,
) -> float:
    """``value`` as a finite float in [low, high] (``(low, high]`` with ``low_open``);
    else ``error(message)`` (default: an InputError naming ``where``)."""
    try:
        return read_number(value, low=low, high=high, low_open=low_open)
    except BadNumber as exc:
        raise (error(str(exc)) if error else InputError(str(exc), file=where)) from None


# -- text for terminals and error lines ----------------------------------------------------

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")
_HIDDEN = frozenset(("Cc", "Cf", "Cs", "Zl", "Zp"))
"""Unicode categories never printed as they are: controls, format characters (the
bidirectional overrides U+202A..U+202E and isolates U+2066..U+2069, zero-width
spaces and joiners, U+FEFF), lone surrogates, line and paragraph separators: each can
make a line read other than it is."""


def _escape(ch: str) -> str:
    n = ord(ch)
    return f"\\x{n:02x}" if n < 0x100 else f"\\u{n:04x}" if n < 0x10000 else f"\\U{n:08x}"


def printable(text: str) -> str:
    """``text`` with control and format characters (ANSI escapes, carriage returns,
    bells, right-to-left overrides, zero-width spaces) shown as ``\\xNN``, ``\\uNNNN``
    escapes: nothing read from a file may drive the user's terminal or reorder a line.
    Tabs and newlines stay."""
    text = str(text)
    if text.isascii():
        return _CONTROL.sub(lambda m: _escape(m.group()), text)
    return "".join(
        _escape(ch) if ch not in "\t\n" and unicodedata.category(ch) in _HIDDEN else ch
        for ch in text
    )


def excerpt(text: str, limit: int = 80) -> str:
    """At most ``limit`` characters of ``text`` on one line, printable: what an error
    line may quote of a file's content."""
    one = " ".join(str(text).split())
    if len(one) > limit:
        one = one[: limit - 3] + "..."
    return printable(one)


_PLAIN = re.compile(r"[A-Za-z0-9_.+-]+")


def is_plain_name(name: Any, *, max_length: int = 255) -> bool:
    """Whether ``name`` is a plain file name: letters, digits, ``_ . + -``, not only
    dots, no separator, no ``..``, no control character, not empty or too long. What a
    name read from a cache entry, a recipe or a manifest must be before it is used as a
    path."""
    return (
        isinstance(name, str)
        and 0 < len(name) <= max_length
        and _PLAIN.fullmatch(name) is not None
        and name.strip(".") != ""
        and ".." not in name
    )


_FOLDER_NAME = re.compile(r"[A-Za-z0-9_.-]+")


def is_folder_name(name: Any, *, max_length: int = 255) -> bool:
    """Whether ``name`` may name a folder we make beside others (a recipe's ``name``:
    ``build/<name>``): letters, digits, ``-``, ``_`` and ``.``, not only dots, not empty
    or too long. Unlike :func:`is_plain_name`, no ``+`` (exactly the documented rule)."""
    return (
        isinstance(name, str)
        and 0 < len(name) <= max_length
        and _FOLDER_NAME.fullmatch(name) is not None
        and name.strip(".") != ""
    )
