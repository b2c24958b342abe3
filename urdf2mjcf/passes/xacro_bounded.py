"""The builtins, math functions and methods an xacro expression may call, each
charging the expansion's :class:`~urdf2mjcf.passes.xacro_budget.Budget` for the
work it does before doing it.

A builtin that loops in C (``sum``, ``sorted``, ``max``, ``set``, ``str.join``)
is charged for every element it will read, unfolded where it compares or
hashes them, and a function it calls back (``map(f, ...)``, ``key=f``) goes
through the expression's call guard, so it is charged and bounded too. Each
result is checked against the bounds on single values and held in memory.
Results that could be huge are refused before they are made (``'{:>9999999}'``
fields, ``str.center``, ``int.to_bytes``, ``math.prod``). The computation itself
is always Python's own, so allowed expressions give stock xacro's values.

Methods that change a value in place (``list.append``, ``dict.update``) are
refused: a description's expressions read values, and a value that cannot change
is measured once.
"""

from __future__ import annotations

import builtins
import math
import re
import string
from collections.abc import Callable, Iterable
from typing import Any

from .xacro_budget import (
    MAX_INT_BITS,
    MAX_ITEMS,
    MAX_TEXT,
    OPERATION,
    WALK_STEPS,
    Budget,
    Refused,
    int_steps,
    search_steps,
    text_steps,
    too_big,
)

HINT = "it could run code; --trust-xacro runs the file's code, as ROS's xacro does"


def not_allowed(what: str) -> Refused:
    from .. import untrusted

    return Refused(f"'{untrusted.excerpt(what, 60)}' is not allowed in a description ({HINT})")


def _changes(what: str) -> Refused:
    return Refused(
        f"'{what}' changes a value in place, which an expression may not do "
        "(--trust-xacro runs the file's code, as ROS's xacro does)"
    )


_NO = object()
_SIZED: Any = (str, bytes, list, tuple, set, frozenset, dict, range)
_SIZED += (type({}.keys()), type({}.values()), type({}.items()))
FIELD_SLACK = 330
"""Characters a format field may add to its value's text and its spec's numbers
(a float's 309 integer digits with 'f', a sign, grouping commas)."""
_NUMBERS = re.compile(r"\d+")
_PERCENT_SPEC = re.compile(r"[#0 +-]*(\*|\d+)?(?:\.(\*|\d+))?")
_PARENS = re.compile(r"[()]")


def _spec_width(spec: str) -> int:
    """Most characters the numbers in a format spec ask for (width plus precision)."""
    total = 0
    for n in _NUMBERS.findall(spec):
        if len(n) > 8 or int(n) > MAX_TEXT:
            raise too_big(f"a format field {untrusted_excerpt(n)} wide", f"{MAX_TEXT:,} characters")
        total += int(n)
    return total


def _percent_fields(text: str) -> Iterable[tuple[str | None, str | None]]:
    """(width, precision) of each conversion of a %-format, read as Python reads it
    (a mapping key may hold parentheses and % signs), in one pass."""
    pos = text.find("%")
    while pos >= 0:
        pos += 1
        if text.startswith("%", pos):
            pos = text.find("%", pos + 1)
            continue
        if text.startswith("(", pos):
            depth = 0
            for paren in _PARENS.finditer(text, pos):
                depth += 1 if paren.group() == "(" else -1
                if depth == 0:
                    pos = paren.end()
                    break
            else:
                return  # Python reports the incomplete key
        spec = _PERCENT_SPEC.match(text, pos)
        assert spec is not None  # every part of the pattern is optional
        yield spec.group(1), spec.group(2)
        pos = text.find("%", spec.end())


def untrusted_excerpt(text: str) -> str:
    from .. import untrusted

    return untrusted.excerpt(text, 20)


class Bounded:
    """Bounded versions of what expressions call, for one expansion.

    ``call(func, *args)`` is the expression's call guard (used for callbacks),
    ``binop(op, a, b)`` its operator guard (used by ``sum`` of sequences).
    """

    def __init__(
        self,
        budget: Budget,
        call: Callable[..., Any],
        binop: Callable[[str, Any, Any], Any],
        copying: tuple[type, ...] = (),
    ):
        self.budget = budget
        self.call = call
        self.binop = binop
        self.copying = copying  # xacro's YAML list: iterating it copies each item
        self.table: dict[int, tuple[Any, Callable[..., Any]]] = {}
        for name in _BUILTINS:
            self.register(getattr(builtins, name), getattr(self, f"b_{name}"))
        for name in dir(math):
            func = getattr(math, name)
            if callable(func) and not name.startswith("_"):
                self.register(func, getattr(self, f"m_{name}", self.plain(func)))

    # -- registry ----------------------------------------------------------------------

    def register(self, raw: Any, impl: Callable[..., Any]) -> None:
        self.table[id(raw)] = (raw, impl)

    def lookup(self, func: Any) -> Callable[..., Any] | None:
        entry = self.table.get(id(func))
        return entry[1] if entry is not None and entry[0] is func else None

    # -- charging helpers --------------------------------------------------------------

    def shallow(self, iterable: Any) -> tuple[Any, int]:
        """``iterable`` for a builtin that reads each item once without looking inside
        (``list``, ``zip``, ``any``), its items charged; iterators charge themselves."""
        if isinstance(iterable, self.copying):
            self.budget.walk(iterable)  # each item copied as it is read
            return iterable, len(iterable)  # type: ignore[arg-type]
        if isinstance(iterable, _SIZED):
            n = len(iterable)
            self.budget.work(1 + n)
            return iterable, n
        try:
            n = len(iterable)  # a namespace, a YAML dict
        except TypeError:
            return iterable, 0
        self.budget.work(1 + n)
        return iterable, n

    def deep(self, iterable: Any) -> Any:
        """``iterable`` for a builtin that compares or hashes its items (``sorted``,
        ``set``, ``max``): an iterator is read into a list first, then the items'
        unfolded walk is charged."""
        if not isinstance(iterable, _SIZED):
            iterable = list(iterable)  # raises Python's own TypeError for a non-iterable
            self.budget.made(iterable)
        return self.budget.walk(iterable)

    def callback(self, func: Any, factor: int = 0) -> Any:
        """``func`` called through the expression's call guard; with ``factor``, the
        walk of each result (a key that is compared) is charged ``factor`` times."""
        if func is None:
            return None
        call, budget = self.call, self.budget

        def guarded(*args: Any) -> Any:
            result = call(func, *args)
            if factor:
                budget.work(budget.measure(result)[0] * factor)
            return result

        return guarded

    def plain(self, func: Callable[..., Any]) -> Callable[..., Any]:
        """``func`` whose work is reading its arguments once (math, ``abs``, ``chr``)."""
        budget = self.budget

        def bounded(*args: Any, **kwargs: Any) -> Any:
            budget.walk(args)  # math.hypot(*coordinates): a container, read at C speed
            if kwargs:
                budget.walk(kwargs)
            return budget.made(func(*args, **kwargs))

        return bounded

    def constant(self, func: Callable[..., Any]) -> Callable[..., Any]:
        """``func`` that does not read its arguments' items (``len``, ``bool``)."""
        return func

    def text_of(self, values: Iterable[Any], *, quoted: bool = False) -> int:
        """Most characters ``str`` (``repr`` with ``quoted``) of each value may take;
        the work of printing them is charged."""
        total = 0
        for v in values:
            total += self.budget.repr_size(v) if quoted else self.budget.text_size(v)
        return total

    def _printing(self, size: int, what: str) -> None:
        if size > MAX_TEXT:
            raise too_big(f"{what} of up to {size:,} characters", f"{MAX_TEXT:,} characters")
        self.budget.work(text_steps(size))

    # -- builtins ----------------------------------------------------------------------

    def b_abs(self, x: Any) -> Any:
        return self.plain(builtins.abs)(x)

    def b_all(self, iterable: Any) -> bool:
        return builtins.all(self.shallow(iterable)[0])

    def b_any(self, iterable: Any) -> bool:
        return builtins.any(self.shallow(iterable)[0])

    def b_bool(self, *args: Any) -> bool:
        return builtins.bool(*args)

    def b_chr(self, i: Any) -> str:
        return builtins.chr(i)

    def b_complex(self, *args: Any, **kwargs: Any) -> complex:
        return self.plain(builtins.complex)(*args, **kwargs)

    def b_dict(self, *args: Any, **kwargs: Any) -> dict:
        if args:
            first = args[0]
            args = (first if hasattr(first, "keys") else self.deep(first), *args[1:])
            self.budget.walk(args[0])
        self.budget.walk(kwargs)
        return self.budget.made(builtins.dict(*args, **kwargs))

    def b_divmod(self, a: Any, b: Any) -> Any:
        self.budget.work(int_steps(a, b, True))
        return self.budget.made(builtins.divmod(a, b))

    def b_enumerate(self, iterable: Any, start: Any = 0) -> Any:
        it, n = self.shallow(iterable)
        if isinstance(start, int):
            self.budget.work(n * (int_steps(start, 0, False) - 1))
        return builtins.enumerate(it, start)

    def b_filter(self, function: Any, iterable: Any) -> Any:
        return builtins.filter(self.callback(function), self.shallow(iterable)[0])

    def b_float(self, *args: Any) -> float:
        return self.plain(builtins.float)(*args)

    def b_frozenset(self, *args: Any) -> frozenset:
        return self.budget.made(builtins.frozenset(*(self.deep(a) for a in args)))

    def b_hash(self, obj: Any) -> int:
        return builtins.hash(self.budget.walk(obj))

    def b_int(self, *args: Any, **kwargs: Any) -> int:
        if args and isinstance(args[0], str | bytes) and len(args[0]) > MAX_INT_BITS // 4:
            raise too_big(f"an integer of {len(args[0]):,} digits", f"{MAX_INT_BITS:,} bits")
        return self.plain(builtins.int)(*args, **kwargs)

    def b_isinstance(self, obj: Any, classinfo: Any) -> bool:
        return builtins.isinstance(obj, self.budget.walk(classinfo))

    def b_issubclass(self, cls: Any, classinfo: Any) -> bool:
        return builtins.issubclass(cls, self.budget.walk(classinfo))

    def b_len(self, obj: Any) -> int:
        return builtins.len(obj)

    def b_list(self, *args: Any) -> list:
        return self.budget.made(builtins.list(*(self.shallow(a)[0] for a in args)))

    def b_map(self, function: Any, *iterables: Any) -> Any:
        its = [self.shallow(i)[0] for i in iterables]
        return builtins.map(self.callback(function), *its)

    def _extreme(self, pick: Callable[..., Any], args: tuple, kwargs: dict) -> Any:
        items = (self.deep(args[0]),) if len(args) == 1 else self.budget.walk(args)
        if "key" in kwargs:
            kwargs = {**kwargs, "key": self.callback(kwargs["key"], factor=1)}
        return pick(*items, **kwargs)

    def b_max(self, *args: Any, **kwargs: Any) -> Any:
        return self._extreme(builtins.max, args, kwargs)

    def b_min(self, *args: Any, **kwargs: Any) -> Any:
        return self._extreme(builtins.min, args, kwargs)

    def b_ord(self, c: Any) -> int:
        return builtins.ord(c)

    def b_range(self, *args: Any) -> range:
        return self.plain(builtins.range)(*args)

    def b_repr(self, obj: Any) -> str:
        self._printing(self.text_of([obj], quoted=True), "repr")
        return self.budget.made(builtins.repr(obj))

    def b_reversed(self, seq: Any) -> Any:
        return builtins.reversed(self.shallow(seq)[0])

    def b_round(self, number: Any, *args: Any) -> Any:
        self.budget.work(int_steps(number, number, True))
        return self.budget.made(builtins.round(number, *args))

    def b_set(self, *args: Any) -> set:
        return self.budget.made(builtins.set(*(self.deep(a) for a in args)))

    def b_slice(self, *args: Any) -> slice:
        return builtins.slice(*args)

    def b_sorted(self, iterable: Any, /, **kwargs: Any) -> list:
        items = self.deep(iterable)
        rounds = builtins.len(items).bit_length()  # a sort compares each item about log2(n) times
        self.budget.work(self.budget.measure(items)[0] * rounds)
        if "key" in kwargs:
            kwargs = {**kwargs, "key": self.callback(kwargs["key"], factor=rounds + 1)}
        return self.budget.made(builtins.sorted(items, **kwargs))

    def b_str(self, *args: Any, **kwargs: Any) -> str:
        if len(args) + len(kwargs) <= 1:
            obj = args[0] if args else kwargs.get("object", "")
            self._printing(self.text_of([obj]), "text")
            return self.budget.made(builtins.str(*args, **kwargs))
        obj = args[0] if args else kwargs.get("object", b"")
        self._coding(obj, kwargs.get("errors", args[2] if len(args) > 2 else "strict"))
        return self.budget.made(builtins.str(*args, **kwargs))

    def _coding(self, text: Any, errors: Any) -> None:
        """Refuse, before it runs, an encode or decode whose error handler could write
        many characters for each one read (``namereplace``: up to 80)."""
        n = len(text) if isinstance(text, str | bytes) else 0
        self.budget.work(text_steps(n))
        if errors in ("strict", "ignore", "replace", "surrogateescape", "surrogatepass"):
            return
        bound = n * (100 if errors == "namereplace" else 10)
        if bound > MAX_TEXT:
            raise too_big(f"text of up to {bound:,} characters", f"{MAX_TEXT:,} characters")

    def b_sum(self, iterable: Any, /, start: Any = 0) -> Any:
        if isinstance(start, str | bytes) or not isinstance(start, int | float | complex):
            if isinstance(start, str | bytes):
                return builtins.sum(iterable, start)  # Python's own refusal
            total = start  # sequences: each + is bounded (summing lists is quadratic)
            for item in self.shallow(iterable)[0]:
                total = self.binop("+", total, item)
            return total
        return self.budget.made(builtins.sum(self.deep(iterable), start))

    def b_tuple(self, *args: Any) -> tuple:
        return self.budget.made(builtins.tuple(*(self.shallow(a)[0] for a in args)))

    def b_zip(self, *iterables: Any, **kwargs: Any) -> Any:
        return builtins.zip(*(self.shallow(i)[0] for i in iterables), **kwargs)  # noqa: B905

    # -- math --------------------------------------------------------------------------

    def _result_bits(self, bits: float, what: str) -> None:
        if not bits <= MAX_INT_BITS:  # also NaN
            raise too_big(f"{what}: a result of about {bits:,.0f} bits", f"{MAX_INT_BITS:,} bits")

    @staticmethod
    def _log2_factorial(n: Any) -> float:
        try:
            return math.lgamma(n + 1) / math.log(2) if isinstance(n, int) and n >= 0 else 0.0
        except OverflowError:
            return math.inf

    def m_factorial(self, n: Any) -> int:
        bits = self._log2_factorial(n)
        self._result_bits(bits, "math.factorial")
        digits = int(bits) // 30 + 1
        self.budget.work(digits * digits // 64 + 1)
        return self.budget.made(math.factorial(n))

    def m_comb(self, n: Any, k: Any) -> int:
        if isinstance(n, int) and isinstance(k, int) and 0 <= k <= n:
            f = self._log2_factorial
            self._result_bits(f(n) - f(k) - f(n - k), "math.comb")
            self.budget.work(int_steps(n, 0, False) * builtins.min(k, n - k))
        return self.budget.made(math.comb(n, k))

    def m_perm(self, n: Any, k: Any = None) -> int:
        if isinstance(n, int) and n >= 0 and (k is None or isinstance(k, int) and 0 <= k <= n):
            f = self._log2_factorial
            self._result_bits(f(n) - f(n - (n if k is None else k)), "math.perm")
            self.budget.work(int_steps(n, 0, False) * (n if k is None else k))
        return self.budget.made(math.perm(n, k))

    def _int_product(self, values: Iterable[Any], what: str) -> None:
        bits = sum(v.bit_length() for v in values if isinstance(v, int))
        self._result_bits(bits, what)
        self.budget.work((bits // 30) ** 2 // 16)

    def m_prod(self, iterable: Any, /, *, start: Any = 1) -> Any:
        items = self.deep(iterable)
        self._int_product([*items, start], "math.prod")
        return self.budget.made(math.prod(items, start=start))

    def m_lcm(self, *integers: Any) -> int:
        self.budget.walk(integers)
        self._int_product(integers, "math.lcm")
        return self.budget.made(math.lcm(*integers))

    def m_gcd(self, *integers: Any) -> int:
        self.budget.walk(integers)
        self._int_product(integers, "math.gcd")
        return math.gcd(*integers)

    def m_isqrt(self, n: Any) -> int:
        self.budget.work(int_steps(n, n, True))
        return math.isqrt(n)

    def m_fsum(self, iterable: Any) -> float:
        return math.fsum(self.deep(iterable))

    # -- methods -----------------------------------------------------------------------

    def method(self, obj: Any, base: type, name: str) -> Any:
        """``obj.name`` (a method of the plain type ``base``), bounded; a method that
        changes ``obj`` is refused."""
        if name in _CHANGING.get(base, ()):
            raise _changes(f"{base.__name__}.{name}")
        bound = getattr(obj, name)
        if not callable(bound):
            return bound  # int.real, range.start
        kind = _METHOD_KINDS.get(base, {}).get(name)
        if kind is None:
            raise not_allowed(f"{base.__name__}.{name}")
        return Method(self, obj, name, bound, kind)

    def run_method(self, m: Method, args: tuple, kwargs: dict) -> Any:
        budget, obj, kind = self.budget, m.obj, m.kind
        if kind == "read":  # scans obj and its arguments, returns a number or a flag
            self._reads(obj, args, kwargs)
            return m.bound(*args, **kwargs)
        if kind == "view":
            return m.bound(*args, **kwargs)
        if kind == "copy":  # makes a value from obj's items (or characters)
            self._reads(obj, args, kwargs)
            return budget.made(m.bound(*args, **kwargs))
        handler = getattr(self, f"k_{kind}")
        return handler(m, args, kwargs)

    def _reads(self, obj: Any, args: tuple, kwargs: dict) -> None:
        budget = self.budget
        if isinstance(obj, str | bytes):
            budget.work(search_steps(len(obj)))
        else:
            budget.walk(obj)
        for a in (*args, *kwargs.values()):
            budget.walk(a)  # an iterator is not read here (a value compared, not a source)

    def k_width(self, m: Method, args: tuple, kwargs: dict) -> Any:
        """center, ljust, rjust, zfill: the result is as wide as asked."""
        width = args[0] if args else kwargs.get("width", 0)
        if isinstance(width, int) and width > MAX_TEXT:
            raise too_big(f"text {width:,} characters wide", f"{MAX_TEXT:,} characters")
        return self.budget.made(m.bound(*args, **kwargs))

    def k_tabs(self, m: Method, args: tuple, kwargs: dict) -> Any:
        tab = args[0] if args else kwargs.get("tabsize", 8)
        text = m.obj
        tabs = text.count("\t" if isinstance(text, str) else b"\t")
        size = len(text) + tabs * builtins.max(0, tab if isinstance(tab, int) else 0)
        if size > MAX_TEXT:
            raise too_big(f"text of up to {size:,} characters", f"{MAX_TEXT:,} characters")
        return self.budget.made(m.bound(*args, **kwargs))

    def k_replace(self, m: Method, args: tuple, kwargs: dict) -> Any:
        text = m.obj
        self.budget.work(search_steps(len(text)))
        if len(args) >= 2 and type(args[0]) is type(args[1]) is type(text):
            old, new = args[0], args[1]
            count = text.count(old) if old else len(text) + 1
            if len(args) > 2 and isinstance(args[2], int) and args[2] >= 0:
                count = builtins.min(count, args[2])
            size = len(text) + count * builtins.max(0, len(new) - len(old))
            if size > MAX_TEXT:
                raise too_big(f"text of {size:,} characters", f"{MAX_TEXT:,} characters")
        return self.budget.made(m.bound(*args, **kwargs))

    def k_translate(self, m: Method, args: tuple, kwargs: dict) -> Any:
        text, table = m.obj, (args[0] if args else kwargs.get("table"))
        self.budget.work(text_steps(len(text)))
        widest = 1
        if isinstance(text, str):
            if type(table) in (dict, list, tuple):
                self.budget.walk(table)
                values: Any = table.values() if isinstance(table, dict) else table
                widest = builtins.max(
                    [len(v) if isinstance(v, str) else 1 for v in values], default=1
                )
            elif type(table) is not str:
                raise not_allowed(f"str.translate with a {type(table).__name__}")
        size = len(text) * widest
        if size > MAX_TEXT:
            raise too_big(f"text of up to {size:,} characters", f"{MAX_TEXT:,} characters")
        return self.budget.made(m.bound(*args, **kwargs))

    def k_join(self, m: Method, args: tuple, kwargs: dict) -> Any:
        sep = m.obj
        parts = args[0] if args else kwargs.get("iterable", ())
        if not isinstance(parts, list | tuple):
            parts = list(self.shallow(parts)[0])
        else:
            self.budget.work(1 + len(parts))
        try:
            size = builtins.max(0, len(parts) - 1) * len(sep) + sum(map(len, parts))
        except TypeError:
            return m.bound(parts)  # a part that is not text: join's own error
        if size > MAX_TEXT:
            raise too_big(f"text of {size:,} characters", f"{MAX_TEXT:,} characters")
        self.budget.work(text_steps(size))
        return self.budget.made(m.bound(parts))

    def k_coding(self, m: Method, args: tuple, kwargs: dict) -> Any:
        errors = kwargs.get("errors", args[1] if len(args) > 1 else "strict")
        self._coding(m.obj, errors)
        return self.budget.made(m.bound(*args, **kwargs))

    def k_format(self, m: Method, args: tuple, kwargs: dict) -> Any:
        self._printing(self.format_size(m.obj, args, kwargs), "'{...}'.format")
        return self.budget.made(m.bound(*args, **kwargs))

    def format_size(self, fmt: str, args: tuple, kwargs: dict) -> int:
        """Most characters ``fmt.format(*args, **kwargs)`` may make (a field's spec
        may not itself hold a field: ``'{:{}}'`` would take its width from a value)."""
        self.budget.work(text_steps(len(fmt)) + fmt.count("{") * WALK_STEPS)
        try:
            fields = list(string.Formatter().parse(fmt))
        except ValueError:
            return len(fmt)  # str.format reports the malformed format string
        size, auto = 0, 0
        for literal, field, spec, conversion in fields:
            size += len(literal)
            if field is None:
                continue
            if spec and "{" in spec:
                raise not_allowed("'{...}'.format with a field inside a format spec")
            if field == "":
                key: Any = auto
                auto += 1
            else:
                key = int(field) if field.isdigit() else field
            try:
                value = kwargs[key] if isinstance(key, str) else args[key]
            except (KeyError, IndexError):
                continue  # str.format reports it
            size += self.field_size(value, conversion, spec or "")
        return size

    def field_size(self, value: Any, conversion: Any, spec: str) -> int:
        """Most characters one formatted field (``{value!conversion:spec}``) may make."""
        quoted = conversion in ("r", "a", 114, 97)
        text = self.text_of([value], quoted=quoted)
        return _spec_width(spec) + FIELD_SLACK + text * 4 // 3  # grouping: 1,000,000

    def percent_size(self, fmt: Any, values: Any) -> int:
        """Most characters ``fmt % values`` may make; a ``*`` width is refused."""
        text = fmt if isinstance(fmt, str) else fmt.decode("latin-1")
        self.budget.work(text_steps(len(text)) + text.count("%") * (OPERATION // 10))
        if isinstance(values, tuple) and len(values) <= 64:
            widest = builtins.max([self.text_of([v], quoted=True) for v in values], default=0)
        else:  # a long tuple: any one value prints shorter than all of them
            widest = self.text_of([values], quoted=True)
        size = len(text)
        for width, precision in _percent_fields(text):
            if width == "*" or precision == "*":
                raise too_big("a %-format field with a computed width", f"{MAX_TEXT:,} characters")
            size += _spec_width(f"{width or 0}.{precision or 0}") + FIELD_SLACK + widest
        return size

    def k_to_bytes(self, m: Method, args: tuple, kwargs: dict) -> Any:
        length = args[0] if args else kwargs.get("length", 1)
        if isinstance(length, int) and length > MAX_TEXT:
            raise too_big(f"{length:,} bytes", f"{MAX_TEXT:,} characters")
        return self.budget.made(m.bound(*args, **kwargs))

    def k_from_bytes(self, m: Method, args: tuple, kwargs: dict) -> Any:
        data = args[0] if args else kwargs.get("bytes", b"")
        data = data if isinstance(data, _SIZED) else self.deep(data)
        self.budget.work(1 + len(data))
        if len(data) * 8 > MAX_INT_BITS:
            raise too_big(f"an integer of {len(data) * 8:,} bits", f"{MAX_INT_BITS:,} bits")
        return m.bound(data, *args[1:], **{k: v for k, v in kwargs.items() if k != "bytes"})

    def k_sets(self, m: Method, args: tuple, kwargs: dict) -> Any:
        """union, intersection, ...: each argument's items are hashed."""
        self.budget.walk(m.obj)
        others = [self.deep(a) for a in args]
        return self.budget.made(m.bound(*others))

    def k_fromkeys(self, m: Method, args: tuple, kwargs: dict) -> Any:
        keys = self.deep(args[0]) if args else ()
        return self.budget.made(m.bound(keys, *args[1:], **kwargs))


class Method:
    """A bound method of a plain value, charged when called (see :meth:`Bounded.method`)."""

    __slots__ = ("bounded", "obj", "name", "bound", "kind")

    def __init__(self, bounded: Bounded, obj: Any, name: str, bound: Any, kind: str):
        self.bounded, self.obj, self.name, self.bound, self.kind = bounded, obj, name, bound, kind

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.bounded.run_method(self, args, kwargs)

    def __repr__(self) -> str:
        return repr(self.bound)


_BUILTINS = (
    "abs all any bool chr complex dict divmod enumerate filter float frozenset hash int "
    "isinstance issubclass len list map max min ord range repr reversed round set slice "
    "sorted str sum tuple zip"
).split()

_TEXT_KINDS: dict[str, str] = {
    **dict.fromkeys(
        (
            "count endswith find index isalnum isalpha isascii isdecimal isdigit isidentifier "
            "islower isnumeric isprintable isspace istitle isupper rfind rindex startswith"
        ).split(),
        "read",
    ),
    **dict.fromkeys(
        (
            "capitalize casefold lower upper swapcase title strip lstrip rstrip removeprefix "
            "removesuffix split rsplit splitlines partition rpartition maketrans hex fromhex"
        ).split(),
        "copy",
    ),
    **dict.fromkeys("center ljust rjust zfill".split(), "width"),
    "expandtabs": "tabs",
    "replace": "replace",
    "translate": "translate",
    "join": "join",
    "encode": "coding",
    "decode": "coding",
    "format": "format",
}
_METHOD_KINDS: dict[type, dict[str, str]] = {
    str: _TEXT_KINDS,
    bytes: _TEXT_KINDS,
    list: {"count": "read", "index": "read", "copy": "copy"},
    tuple: {"count": "read", "index": "read"},
    dict: {
        "get": "read",
        "keys": "view",
        "values": "view",
        "items": "view",
        "copy": "copy",
        "fromkeys": "fromkeys",
    },
    frozenset: {
        "copy": "copy",
        **dict.fromkeys(
            (
                "isdisjoint issubset issuperset union intersection difference symmetric_difference"
            ).split(),
            "sets",
        ),
    },
    int: {
        **dict.fromkeys("as_integer_ratio bit_count bit_length conjugate".split(), "copy"),
        "to_bytes": "to_bytes",
        "from_bytes": "from_bytes",
    },
    float: dict.fromkeys("as_integer_ratio conjugate fromhex hex is_integer".split(), "copy"),
    complex: {"conjugate": "copy"},
    range: {"count": "read", "index": "read"},
}
_METHOD_KINDS[set] = _METHOD_KINDS[frozenset]
_CHANGING: dict[type, frozenset[str]] = {
    list: frozenset("append clear extend insert pop remove reverse sort".split()),
    dict: frozenset("clear pop popitem setdefault update".split()),
    set: frozenset(
        "add clear difference_update discard intersection_update pop remove "
        "symmetric_difference_update update".split()
    ),
}

__all__ = ["MAX_ITEMS", "Bounded", "Method", "not_allowed", "HINT"]
