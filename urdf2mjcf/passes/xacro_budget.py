"""What one xacro expansion may spend: work in steps, memory in bytes, sizes per value.

Bounds on single values (:data:`MAX_TEXT`, :data:`MAX_ITEMS`, :data:`MAX_INT_BITS`)
stop one operation from making something huge; they do not stop a loop that makes
a thousand values just under them, nor a builtin that loops in C (``sum``,
``sorted``, ``x in range(...)``). So every expansion also has a :class:`Budget`:

* **work**: each operation an expression evaluates (a call, an operator, an
  attribute, a subscript, a comparison, a comprehension iteration) costs
  :data:`OPERATION` steps, each element a builtin or method reads or writes one
  step (a character is ``1/CHARS_PER_STEP`` of one), each element of the
  expanded document :data:`NODE_STEPS`; charged before the work where it can be
  large, so a loop inside a builtin is refused before it runs;
* **memory**: the bytes of every value an expression makes (strings, numbers,
  containers, counted once each however often they are referenced), of the text
  attributes expand to, and of the document's elements.

A value's cost to walk (what comparing, hashing, sorting or printing it costs)
and the text it prints as are its *unfolded* sizes, ``[L] * 1000`` a thousand
times ``L``: :meth:`Budget.measure` computes them once per large value (they
cannot change: expressions may not change values in place).
"""

from __future__ import annotations

import sys
from collections import Counter
from itertools import chain
from typing import Any

MAX_ITEMS = 1_000_000
"""Most items a range, list, tuple, set or dict an expression makes may hold."""
MAX_TEXT = 10_000_000
"""Most characters a string an expression (or an expanded attribute) may hold."""
MAX_INT_BITS = 100_000
"""Largest integer an expression may compute (about 30,000 digits)."""
MAX_WORK = 100_000_000
"""Steps of work one expansion may do, all its expressions and elements together
(the largest description we test, the MIRA3D world with its recipe's arguments,
takes under 16,000,000)."""
MAX_MEMORY = 512 * 2**20
"""Bytes one expansion may make: values, expanded text, elements (the MIRA3D
world makes under 20 MB)."""

OPERATION = 100
"""Steps one evaluated operation costs (about what 100 elements cost in C)."""
CHARS_PER_STEP = 64
"""Characters read or written per step."""
SEARCH_CHARS_PER_STEP = 4
"""Characters searched for a substring per step."""
NODE_STEPS = 100
"""Steps one element, text or comment of the expanded document costs."""
NODE_BYTES = 600
"""Bytes one element, text or comment node holds (xml.dom.minidom, measured)."""
NAME_STEPS = 25
"""Steps one name lookup costs per scope it passes (each macro call nests one)."""
PARSE_STEPS = 250
"""Steps per character of an expression parsed and checked (once per text)."""
PARSE_BYTES = 64
"""Bytes per character an expression's compiled code is kept in."""

_CAP = 1 << 62  # unfolded sizes can be astronomic ([[x] * 1000] * 1000 ...): saturate
_MEMO_ITEMS = 16  # containers this long (or this costly to walk) are measured once
_MEMO_CHARS = 256  # strings and bytes this long are counted in memory once
_DEEPEST = 500


class Refused(Exception):
    """An expression (or a file it reads) a description may not use; ``reason`` is
    the whole explanation, the caller adds file, line and expression."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


def too_big(what: str, bound: str) -> Refused:
    """``what`` (``text of 12 characters``) past ``bound`` (``10,000,000 characters``)."""
    return Refused(f"{what}, over the bound of {bound} (refused: an expression may not make this)")


def text_steps(n: int) -> int:
    return 1 + n // CHARS_PER_STEP


def search_steps(n: int) -> int:
    """Steps to search ``n`` characters for a substring (``in``, ``find``, ``split``)."""
    return 1 + n // SEARCH_CHARS_PER_STEP


def int_walk(bits: int) -> int:
    """Steps to walk an integer of ``bits`` bits: printing it is quadratic in its
    30-bit digits (CPython 3.11), comparing it linear."""
    d = bits // 30
    return 1 + d + d * d // 16


def _digits(value: int) -> int:
    """30-bit digits of an int (CPython's unit of big-int work)."""
    return value.bit_length() // 30 + 1


def int_steps(a: Any, b: Any, quadratic: bool) -> int:
    """Steps of ``a op b``: linear in the digits (+, -, &, ...) or, for *, //, %,
    divmod and **, their product (schoolbook; CPython's Karatsuba is faster)."""
    da = _digits(a) if isinstance(a, int) else 1
    db = _digits(b) if isinstance(b, int) else 1
    if quadratic:
        return 1 + da * db // 16
    return 1 + (da + db) // 16


_SCALAR_SIZES: dict[type, tuple[int, int, int]] = {  # steps, characters, bytes
    float: (1, 24, 24),
    complex: (1, 52, 32),
    bool: (1, 5, 28),
    type(None): (1, 4, 16),
    type(...): (1, 8, 16),
}
_VIEWS: Any = (type({}.keys()), type({}.values()), type({}.items()))
_SIZED = (str, bytes, list, tuple, set, frozenset, dict, range, *_VIEWS)
_WALKED = (list, tuple, set, frozenset, dict, *_VIEWS)
_FLAT = 64  # a container this long is first tried as flat: numbers or strings only
_INTS = frozenset((int, bool))
_FIXED: dict[type, tuple[int, int, int]] = {
    **_SCALAR_SIZES,
    type: (1, 200, 64),
    type(len): (1, 200, 64),
    type(lambda: None): (1, 200, 64),
}
_STRS = frozenset((str,))
_TUPLES = frozenset((tuple,))
_FLAT_TYPES = frozenset((list, tuple, set, frozenset, *_VIEWS))
WALK_STEPS = 50
"""Steps per item a measurement walks in Python (a container of containers); a flat
container of numbers or strings is measured at C speed, one step per item."""
Sizes = tuple[int, int, int]  # steps to walk a value unfolded, characters it prints as, bytes


def _scalar(value: Any) -> Sizes | None:
    kind = type(value)
    if kind is int or kind is str or kind is bytes or isinstance(value, int | str | bytes):
        if isinstance(value, int):  # 1233 / 4096 > log10(2): decimal digits, and a sign
            b = value.bit_length()
            return int_walk(b), 2 + (b * 1233 >> 12), sys.getsizeof(value)
        n = len(value)
        wide = isinstance(value, str) and not value.isascii()  # repr: '\x01', '\U0010ffff'
        return 1 + n // CHARS_PER_STEP, 3 + n * (10 if wide else 4), sys.getsizeof(value)
    return _SCALAR_SIZES.get(kind)


def _flat(value: Any) -> Sizes | None:
    """Sizes of a container of plain numbers or strings, or of tuples of them (what
    ``zip`` and ``enumerate`` make), read at C speed; None when it holds anything else."""
    if type(value) not in _FLAT_TYPES:
        value = list(list.__iter__(value))  # a YAML list: its own iterator copies each item
    items = _flat_items(value, True)
    if items is None:
        return None
    return 1 + items[0], 12 + items[1], sys.getsizeof(value) + items[2]


def _flat_items(items: Any, nested: bool) -> Sizes | None:
    """Sizes of ``items`` themselves (a string held twice counts once in bytes, a
    number or tuple twice: finding them would cost more than it saves)."""
    kinds = set(map(type, items))
    n = len(items)
    if kinds <= _INTS:  # numbers held twice count twice: cheaper than finding them
        bits = sum(map(int.bit_length, items))
        steps = 2 * n + bits // 30
        if n and max(map(int.bit_length, items)) > 120:  # large ones: printing is quadratic
            steps = n + sum(int_walk(b) for b in map(int.bit_length, items))
        return steps, 7 * n + (bits * 1233 >> 12), 32 * n + bits // 30 * 4
    if kinds <= _FIXED.keys():  # None, floats, types, functions: each the same size
        sizes = [_FIXED[k] for k in kinds] or [(1, 4, 16)]
        most = [max(col) for col in zip(*sizes, strict=True)]
        return n * (1 + most[0]), n * (2 + most[1]), n * most[2]
    if kinds <= _STRS:
        total = sum(map(len, items))
        wide = 10 if not all(map(str.isascii, items)) else 4
        steps, chars = 3 * n + total // CHARS_PER_STEP, 5 * n + total * wide
    elif kinds == _TUPLES and nested and _small_and_distinct(items):
        inner = _flat_items(list(chain.from_iterable(items)), False)
        if inner is None:
            return None
        steps, chars = 2 * n + inner[0], 16 * n + inner[1]
        return steps, chars, sum(map(sys.getsizeof, items)) + inner[2]
    else:
        return None
    distinct = dict(zip(map(id, items), items, strict=True)).values()  # ['abc' * 1000] * 1000
    return steps, chars, sum(map(sys.getsizeof, distinct))


def _small_and_distinct(tuples: Any) -> bool:
    """Whether ``tuples`` are each held once and short (pairs from ``zip``): then
    reading all their items costs no more than a few times reading the tuples."""
    return len(set(map(id, tuples))) == len(tuples) and max(map(len, tuples), default=0) <= 8


class Budget:
    """Work and memory spent so far in one expansion, and the values measured."""

    def __init__(self, table_type: type | None = None):
        self.steps = 0
        self.bytes = 0
        self.table_type = table_type  # xacro's Table: measured, never memoized
        self._fresh = 0  # work of measurements not yet charged
        # id -> [value, steps, chars, counted in memory]; the value is kept so the id stays its
        self._memo: dict[int, list[Any]] = {}

    # -- spending ----------------------------------------------------------------------

    def work(self, steps: int) -> None:
        self.steps += steps
        if self.steps > MAX_WORK:
            raise Refused(
                f"work past the bound of {MAX_WORK:,} steps for one expansion "
                "(refused: the description computes more than it may)"
            )

    def hold(self, nbytes: int) -> None:
        self.bytes += nbytes
        if self.bytes > MAX_MEMORY:
            raise Refused(
                f"memory past the bound of {MAX_MEMORY:,} bytes for one expansion "
                "(refused: the description makes more than it may hold)"
            )

    def made(self, value: Any) -> Any:
        """``value``, just made: its bytes not counted before are held, writing its
        items is work, and it must be within the bounds on single values."""
        check_size(value)
        scalar = _scalar(value)
        if scalar is not None and scalar[2] < _MEMO_CHARS:
            self.hold(scalar[2])
            self.work(1)
            return value
        nbytes = self._sizes(value, {}, 0, True)[2]
        self.hold(nbytes)
        size = len(value) if isinstance(value, _WALKED) else 0
        self.work(1 + size + self._taken())
        return value

    def _taken(self) -> int:
        fresh, self._fresh = self._fresh, 0
        return fresh

    # -- measuring ---------------------------------------------------------------------

    def measure(self, value: Any) -> tuple[int, int]:
        """(steps to walk ``value`` unfolded, characters its repr may take at most);
        measuring costs the work of walking what was not measured before."""
        scalar = _scalar(value)
        if scalar is not None:
            return scalar[0], scalar[1]
        steps, chars, _ = self._sizes(value, {}, 0, False)
        if self._fresh:
            self.work(self._taken())
        return steps, chars

    def walk(self, value: Any) -> Any:
        """``value`` after charging the work of walking it (a comparison, a hash)."""
        self.work(self.measure(value)[0])
        return value

    def text_size(self, value: Any) -> int:
        """Most characters ``str(value)`` may make (a namespace prints its parents too);
        the work of printing it (walking it) is charged."""
        if isinstance(value, str):
            return len(value)
        steps, chars = self.measure(value)
        table = self.table_type
        while table is not None and isinstance(value, table):
            value = getattr(value, "parent", None)
            more_steps, more = self.measure(value)
            steps, chars = steps + more_steps, min(_CAP, chars + 11 + more)
        self.work(steps)
        return chars

    def repr_size(self, value: Any) -> int:
        """Most characters ``repr(value)`` may make; the work of printing it is charged."""
        steps, chars = self.measure(value)
        self.work(steps)
        return chars

    def _sizes(
        self, value: Any, seen: dict[int, tuple[int, int]], depth: int, count: bool
    ) -> Sizes:
        """Sizes of ``value`` unfolded; its bytes (with ``count``) are those not counted
        before, and are then counted: what is seen twice in one walk, or was counted in
        an earlier one, is not counted again."""
        scalar = _scalar(value)
        if scalar is not None:
            if not count or scalar[2] < _MEMO_CHARS:
                return scalar if count else (scalar[0], scalar[1], 0)
        key = id(value)
        if key in seen:
            steps, chars = seen[key]
            return steps, chars, 0
        hit = self._memo.get(key)
        if hit is not None and (hit[3] or not count):
            return hit[1], hit[2], 0
        if scalar is not None:  # a large string or integer, counted once
            self._memo[key] = [value, scalar[0], scalar[1], True]
            return scalar
        table = self.table_type is not None and isinstance(value, self.table_type)
        if isinstance(value, range):
            try:
                n = len(value)
            except OverflowError:
                n = _CAP
            ends = (value.start, value.stop, value.step)
            seen[key] = (1 + n, 20 + sum(2 + (e.bit_length() * 1233 >> 12) for e in ends))
            return *seen[key], 48
        if not isinstance(value, _WALKED):
            return 1, 200, 64 if count else 0  # a function, a type, a date: printed short
        if depth > _DEEPEST:
            raise Refused(f"a value nested more than {_DEEPEST} levels deep (refused)")
        seen[key] = (1, 5)  # a value inside itself prints as [...]
        n = len(value)
        sizes = _flat(value) if n >= _FLAT and not isinstance(value, dict) else None
        if sizes is None and n >= _FLAT and isinstance(value, dict) and not table:
            keys, values = _flat(value.keys()), _flat(value.values())
            if keys is not None and values is not None:
                sizes = (
                    keys[0] + values[0],
                    keys[1] + values[1],
                    sys.getsizeof(value) + keys[2] + values[2],
                )
        inner = count and not table  # a namespace's values were counted where made
        if sizes is not None:
            self._fresh += 1 + n  # a few passes over the items in C
            steps, chars, nbytes = sizes
        elif n < _FLAT:
            self._fresh += OPERATION + n * WALK_STEPS
            steps, chars, nbytes = 1, 12, sys.getsizeof(value)
            for item in _items(value):
                s, c, b = self._sizes(item, seen, depth + 1, inner)
                steps, chars, nbytes = steps + 1 + s, chars + 2 + c, nbytes + b
        else:
            items = _items(value)
            times = Counter(map(id, items))  # [x] * 1000: x is walked once, counted 1000 times
            distinct = dict(zip(map(id, items), items, strict=True))
            self._fresh += OPERATION + 4 * len(items) + len(distinct) * WALK_STEPS
            steps, chars, nbytes = 1, 12, sys.getsizeof(value)
            for ident, item in distinct.items():
                s, c, b = self._sizes(item, seen, depth + 1, inner)
                k = times[ident]
                steps += k * (1 + s)
                chars += k * (2 + c)  # ', ' or ': '
                nbytes += b
        steps, chars = min(_CAP, steps), min(_CAP, chars)
        seen[key] = (steps, chars)
        if table:
            return steps, chars, 64 if count else 0
        if hit is not None:
            hit[3] = True
        elif steps >= _MEMO_ITEMS or n >= _MEMO_ITEMS:
            self._memo[key] = [value, steps, chars, count]
        return steps, chars, nbytes if count else 0


def _items(value: Any) -> list[Any]:
    """What a container holds (a dict: its keys and values), without running any of
    xacro's code: a Table's lazy properties are not evaluated, a YAML list's items
    are not copied."""
    if isinstance(value, dict):
        return [*dict.keys(value), *dict.values(value)]
    if isinstance(value, list):
        return list(list.__iter__(value))
    if isinstance(value, _VIEWS[2]):
        return [x for pair in value for x in pair]
    return list(value)


def check_size(value: Any) -> None:
    """Refuse a value past the bounds on single values (cheap: a length or a bit count)."""
    if isinstance(value, str | bytes):
        if len(value) > MAX_TEXT:
            raise too_big(f"text of {len(value):,} characters", f"{MAX_TEXT:,} characters")
    elif isinstance(value, range):
        try:
            n = len(value)
        except OverflowError:
            n = MAX_ITEMS + 1
        if n > MAX_ITEMS:
            raise too_big("a range of more items", f"{MAX_ITEMS:,} items")
    elif isinstance(value, list | tuple | set | frozenset | dict):
        if len(value) > MAX_ITEMS:
            what = f"a {type(value).__name__} of {len(value):,} items"
            raise too_big(what, f"{MAX_ITEMS:,} items")
    elif isinstance(value, int) and value.bit_length() > MAX_INT_BITS:
        raise too_big(f"an integer of {value.bit_length():,} bits", f"{MAX_INT_BITS:,} bits")
