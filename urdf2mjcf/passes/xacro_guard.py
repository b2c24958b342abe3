"""Checked evaluation of xacro expressions: a description cannot run code.

Stock xacro evaluates ``${...}`` with ``eval`` and no builtins, which is
escapable (``python.vars``, ``python.type``, generator frames, format-string
attribute walks), and ``$(eval ...)`` with every builtin (``exec``, ``open``).
Here every expression is parsed with :mod:`ast` and checked before it runs:

* statically: no lambda, walrus, yield/await, async comprehension, no
  assignment to anything but plain names (comprehension targets), no name
  starting with ``__``, no attribute starting with ``_``, no string subscript
  key starting with ``__``, not nested deeper than :data:`MAX_DEPTH`;
* at run time: every attribute load and every subscript of the checked tree is
  rewritten into a call of a guard that lets through only what descriptions
  use: xacro's name spaces (the global ``python``, ``math`` and ``xacro`` only
  for :data:`NAMESPACE_ALLOWED`), YAML data, and the methods of strings,
  numbers, lists, tuples, dicts and sets (``str.format`` only without ``.``
  or ``[`` in its fields, no ``format_map``).

The guards reach the expression through the ``__builtins__`` dict xacro
already replaces per call, under names that are not identifiers (a
description cannot write them) and that no symbol table may hold (checked
before each evaluation). ``xacro.load_yaml`` reads only regular files inside
the description's own packages, within the ``yaml`` size limit and alias
bound; included files are regular files within the ``description`` limit.

Nothing an expression does may hang or exhaust memory: calls, ``+``, ``*``,
``**``, ``<<`` and ``%`` go through guards that refuse results past
:data:`MAX_ITEMS` items, :data:`MAX_TEXT` characters or :data:`MAX_INT_BITS`
bits before computing them (``'a' * 10**10``, ``9**9**9``, ``range(10**12)``),
comprehensions share one budget of :data:`MAX_ITERATIONS` iterations per
expansion, and the text a property or attribute expands to, the macro calls
and the includes of one expansion are bounded too (properties that double
each other, macros that call others twice: xacro's billion laughs).

Everything is installed by :func:`installed` (under the caller's lock: xacro
keeps global state) and restored after; ``--trust-xacro`` installs nothing.
"""

from __future__ import annotations

import ast
import builtins
import io
import math
import operator
import os
import re
import string
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import CodeType
from typing import Any

from .. import untrusted
from ..errors import ConversionError, InputError, XacroError

TRUST_ENV = "URDF2MJCF_TRUST_XACRO"
"""``1``/``true``/``yes`` runs a description's code as ROS's xacro does (API, facility)."""

MAX_DEPTH = 100
"""How deeply an expression's syntax tree may nest (real ones stay below 30)."""

HINT = "it could run code; --trust-xacro runs the file's code, as ROS's xacro does"

MAX_ITEMS = 1_000_000
"""Most items a range, list, tuple or set an expression makes may hold."""
MAX_TEXT = 10_000_000
"""Most characters a string an expression (or an expanded attribute) may hold."""
MAX_INT_BITS = 100_000
"""Largest integer an expression may compute (about 30,000 digits)."""
MAX_ITERATIONS = 10_000_000
"""Comprehension iterations one expansion may run, all expressions together."""
MAX_MACRO_CALLS = 20_000
"""Macro calls one expansion may make (our facility, the largest description we
test, makes 365; a call costs up to a few milliseconds)."""
MAX_INCLUDES = 10_000
"""Files one expansion may include."""
MAX_FACTORIAL = 10_000
"""Largest argument of math.factorial, comb and perm."""

# What $(eval ...) may call besides xacro's own functions (stock: every builtin).
EVAL_BUILTINS = (
    "abs all any bool chr complex dict divmod enumerate filter float frozenset hash int "
    "isinstance issubclass len list map max min ord range repr reversed round set slice "
    "sorted str sum tuple zip"
).split()

# Members of xacro's global name spaces an expression may use (python.type, python.vars
# are the way out of stock xacro's sandbox).
NAMESPACE_ALLOWED: dict[str, frozenset[str]] = {
    "python": frozenset(
        (
            "list dict map len str float int bool True False min max round abs all any "
            "complex divmod enumerate filter frozenset hash isinstance issubclass ord repr "
            "reversed slice set sum tuple zip sorted range"
        ).split()
    ),
    "math": frozenset(k for k in vars(math) if not k.startswith("_")),
    "xacro": frozenset(
        (
            "load_yaml abs_filename dotify arg message warning error print_location fatal tokenize"
        ).split()
    ),
}

# Names no description can write or define (not identifiers); see _check_shadowing.
G_ATTR = "xacro guard.attribute"
G_ITEM = "xacro guard.subscript"
G_SLICE = "xacro guard.slice"
G_CALL = "xacro guard.call"
G_BINOP = "xacro guard.binop"
G_ITER = "xacro guard.iter"
_GUARD_NAMES = (G_ATTR, G_ITEM, G_SLICE, G_CALL, G_BINOP, G_ITER)

_FORBIDDEN_NODES: dict[type, str] = {
    ast.Lambda: "lambda",
    ast.NamedExpr: ":=",
    ast.Yield: "yield",
    ast.YieldFrom: "yield from",
    ast.Await: "await",
}


class Refused(Exception):
    """An expression (or a file it reads) a description may not use; ``reason`` is
    the whole explanation, the caller adds file, line and expression."""

    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


def _not_allowed(what: str) -> Refused:
    return Refused(f"'{untrusted.excerpt(what, 60)}' is not allowed in a description ({HINT})")


# -- static check and rewrite -----------------------------------------------------------


def _depth(tree: ast.AST) -> int:
    deepest = 0
    stack = [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if deepest > MAX_DEPTH:
            break
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return deepest


def _check_node(node: ast.AST) -> None:
    if type(node) in _FORBIDDEN_NODES:
        raise _not_allowed(_FORBIDDEN_NODES[type(node)])
    if isinstance(node, ast.Name) and node.id.startswith("__"):
        raise _not_allowed(node.id)
    if isinstance(node, ast.Attribute):
        if node.attr.startswith("_"):
            raise _not_allowed(f".{node.attr}")
        if not isinstance(node.ctx, ast.Load):
            raise _not_allowed(f"assignment to .{node.attr}")
    if isinstance(node, ast.Subscript):
        key = node.slice
        if isinstance(key, ast.Constant) and isinstance(key.value, str | bytes):
            text = key.value if isinstance(key.value, str) else key.value.decode("latin-1")
            if text.startswith("__"):
                raise _not_allowed(f"[{text!r}]")
        if not isinstance(node.ctx, ast.Load):
            raise _not_allowed("assignment to a subscript")
    if isinstance(node, ast.Starred) and not isinstance(node.ctx, ast.Load):
        raise _not_allowed("starred assignment")
    if isinstance(node, ast.comprehension) and node.is_async:
        raise _not_allowed("async for")
    if isinstance(node, ast.FormattedValue) and node.format_spec is not None:
        spec = node.format_spec
        parts = spec.values if isinstance(spec, ast.JoinedStr) else [spec]
        if not all(isinstance(p, ast.Constant) and isinstance(p.value, str) for p in parts):
            raise _not_allowed("an f-string format spec that is computed")
        text = "".join(p.value for p in parts)  # type: ignore[attr-defined]
        if _too_wide(text):
            raise Refused(f"format spec '{untrusted.excerpt(text, 20)}' is too wide (refused)")


class _Rewrite(ast.NodeTransformer):
    """``a.b`` -> ``G_ATTR(a, 'b')``, ``a[k]`` -> ``G_ITEM(a, k)`` (slices as ``G_SLICE``)."""

    @staticmethod
    def _call(name: str, args: list[ast.expr], like: ast.AST) -> ast.Call:
        call = ast.Call(func=ast.Name(id=name, ctx=ast.Load()), args=args, keywords=[])
        return ast.copy_location(call, like)

    def _key(self, key: ast.expr) -> ast.expr:
        if isinstance(key, ast.Slice):
            parts = [
                self.visit(p) if p is not None else ast.Constant(None)
                for p in (key.lower, key.upper, key.step)
            ]
            return self._call(G_SLICE, parts, key)
        if isinstance(key, ast.Tuple):
            return ast.copy_location(
                ast.Tuple(elts=[self._key(e) for e in key.elts], ctx=ast.Load()), key
            )
        return self.visit(key)

    def visit_Attribute(self, node: ast.Attribute) -> ast.expr:
        return self._call(G_ATTR, [self.visit(node.value), ast.Constant(node.attr)], node)

    def visit_Subscript(self, node: ast.Subscript) -> ast.expr:
        return self._call(G_ITEM, [self.visit(node.value), self._key(node.slice)], node)

    def visit_Call(self, node: ast.Call) -> ast.expr:
        call = ast.Call(
            func=ast.Name(id=G_CALL, ctx=ast.Load()),
            args=[self.visit(node.func), *(self.visit(a) for a in node.args)],
            keywords=[self.visit(k) for k in node.keywords],
        )
        return ast.copy_location(call, node)

    def visit_BinOp(self, node: ast.BinOp) -> ast.expr:
        op = _GUARDED_OPS.get(type(node.op))
        left, right = self.visit(node.left), self.visit(node.right)
        if op is None:
            return ast.copy_location(ast.BinOp(left=left, op=node.op, right=right), node)
        return self._call(G_BINOP, [ast.Constant(op), left, right], node)

    def visit_comprehension(self, node: ast.comprehension) -> ast.comprehension:
        return ast.comprehension(
            target=self.visit(node.target),
            iter=self._call(G_ITER, [self.visit(node.iter)], node.iter),
            ifs=[self.visit(i) for i in node.ifs],
            is_async=node.is_async,
        )


_GUARDED_OPS = {ast.Add: "+", ast.Mult: "*", ast.Pow: "**", ast.LShift: "<<", ast.Mod: "%"}
_OPERATORS = {
    "+": operator.add,
    "*": operator.mul,
    "**": operator.pow,
    "<<": operator.lshift,
    "%": operator.mod,
}
_WIDTH = re.compile(r"(\d+)")
_PERCENT = re.compile(r"%(?:\([^)]*\))?[#0 +-]*(\*|\d+)?(?:\.(\*|\d+))?")


def _too_wide(spec: str) -> bool:
    """Whether a format spec (``>20``, ``.3f``, ``0999999999d``) asks for a field wider
    or more precise than :data:`MAX_TEXT` characters could hold."""
    return any(len(n) > 7 or int(n) > MAX_TEXT for n in _WIDTH.findall(spec))


def check(expression: str) -> CodeType:
    """``expression`` (the text inside ``${...}`` or ``$(eval ...)``) checked and
    compiled with its guards; :class:`Refused` when it is not allowed or not valid."""
    text = expression.strip()
    try:
        tree = ast.parse(text, "<expression>", "eval")
    except SyntaxError as exc:
        raise Refused(f"invalid expression: {exc.msg}") from None
    except (ValueError, MemoryError, RecursionError) as exc:  # null bytes, absurd nesting
        raise Refused(f"invalid expression: {exc}") from None
    if _depth(tree) > MAX_DEPTH:
        raise Refused(f"expression nested more than {MAX_DEPTH} levels deep (refused)")
    for node in ast.walk(tree):
        _check_node(node)
    tree = ast.fix_missing_locations(_Rewrite().visit(tree))
    try:
        return compile(tree, "<expression>", "eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError) as exc:
        raise Refused(f"invalid expression: {exc}") from None


# -- run-time guards --------------------------------------------------------------------

_PLAIN_TYPES: dict[type, frozenset[str]] = {}


def _public(cls: type, drop: Sequence[str] = ()) -> frozenset[str]:
    return frozenset(n for n in dir(cls) if not n.startswith("_") and n not in drop)


for _cls in (int, float, complex, bool, bytes, tuple, range, set, frozenset, list, dict):
    _PLAIN_TYPES[_cls] = _public(_cls)
_PLAIN_TYPES[str] = _public(str, drop=("format_map",))


def _format_fields_plain(fmt: str, depth: int = 0) -> bool:
    """Whether no replacement field of ``fmt`` walks attributes or items (``{0.x}``,
    ``{0[k]}``): that is how ``str.format`` reaches an object's internals."""
    if depth > 2:
        return False
    try:
        for _, field, spec, _ in string.Formatter().parse(fmt):
            if field is not None and ("." in field or "[" in field):
                return False
            if spec and _too_wide(spec):
                return False
            if spec and "{" in spec and not _format_fields_plain(spec, depth + 1):
                return False
    except ValueError:
        return True  # str.format itself will report the malformed format string
    return True


class Guards:
    """The attribute and subscript guards for one expansion."""

    def __init__(
        self, namespaces: dict[int, str], namespace_type: Any, yaml_dict: type, table_type: Any
    ):
        self.namespaces = namespaces  # id of xacro's global NameSpace -> its name
        self.namespace_type = namespace_type
        self.yaml_dict = yaml_dict
        self.table_type = table_type

    def attr(self, obj: Any, name: str) -> Any:
        if name.startswith("_"):
            raise _not_allowed(f".{name}")
        if isinstance(obj, self.table_type):
            return self._namespace_attr(obj, name)
        kind = type(obj)
        if isinstance(obj, self.yaml_dict) and not hasattr(dict, name):
            return getattr(obj, name)  # a YAML key, as xacro's dotted access
        for base in (kind, *kind.__mro__[1:]):
            allowed = _PLAIN_TYPES.get(base)
            if allowed is None:
                continue
            if name not in allowed:
                break
            if base is str and name == "format" and not _format_fields_plain(obj):
                raise _not_allowed("'{...}'.format with '.' or '[' in a field")
            if base is str and name in _GROWING:
                return _bounded_method(obj, name)
            return getattr(obj, name)
        raise _not_allowed(f"{_describe(obj)}.{name}")

    def _namespace_attr(self, obj: Any, name: str) -> Any:
        glob = self.namespaces.get(id(obj))
        if glob is not None and name not in NAMESPACE_ALLOWED[glob]:
            raise _not_allowed(f"{glob}.{name}")
        if hasattr(type(obj), name) or name in vars(obj):  # a method or the table's parent
            raise _not_allowed(f"{glob or 'namespace'}.{name}")
        return self.namespace_type.__getattr__(obj, name)  # xacro's own dotted lookup

    def item(self, obj: Any, key: Any) -> Any:
        if isinstance(obj, self.table_type):
            glob = self.namespaces.get(id(obj))
            if isinstance(key, str) and key.startswith("_"):
                raise _not_allowed(f"{glob or 'namespace'}[{key!r}]")
            if glob is not None and key not in NAMESPACE_ALLOWED[glob]:
                raise _not_allowed(f"{glob}[{key!r}]")
            return obj[key]
        if isinstance(obj, str | bytes | list | tuple | dict | range):
            return obj[key]
        raise _not_allowed(f"{_describe(obj)}[...]")

    iterations = 0
    """Comprehension iterations so far in this expansion."""

    def call(self, func: Any, /, *args: Any, **kwargs: Any) -> Any:
        if func in _BIG_NUMBER_FUNCTIONS and any(
            isinstance(a, int) and a > MAX_FACTORIAL for a in args
        ):
            raise Refused(f"{func.__name__} of more than {MAX_FACTORIAL} (refused: too costly)")
        result = func(*args, **kwargs)
        _check_size(result)
        return result

    def binop(self, op: str, a: Any, b: Any) -> Any:
        _check_operands(op, a, b)
        result = _OPERATORS[op](a, b)
        _check_size(result)
        return result

    def iterate(self, iterable: Any) -> Iterator[Any]:
        for item in iterable:
            self.iterations += 1
            if self.iterations > MAX_ITERATIONS:
                raise Refused(
                    f"comprehensions ran more than {MAX_ITERATIONS} iterations (refused)"
                )
            yield item

    def guard_builtins(self, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        out = _Builtins(extra or {})
        out.update(
            {
                G_ATTR: self.attr,
                G_ITEM: self.item,
                G_SLICE: slice,
                G_CALL: self.call,
                G_BINOP: self.binop,
                G_ITER: self.iterate,
            }
        )
        return out


_BIG_NUMBER_FUNCTIONS = (math.factorial, math.comb, math.perm)
_SEQUENCES = (str, bytes, list, tuple)


def _too_big(what: str) -> Refused:
    return Refused(f"{what} (refused: an expression may not make something this large)")


def _check_size(value: Any) -> None:
    """Refuse a result past the bounds (cheap: a length or a bit count)."""
    if isinstance(value, str | bytes):
        if len(value) > MAX_TEXT:
            raise _too_big(f"text of {len(value)} characters")
    elif isinstance(value, range | list | tuple | set | frozenset | dict):
        if len(value) > MAX_ITEMS:
            raise _too_big(f"a {type(value).__name__} of {len(value)} items")
    elif isinstance(value, int) and value.bit_length() > MAX_INT_BITS:
        raise _too_big(f"an integer of {value.bit_length()} bits")


def _limit(value: Any) -> int:
    return MAX_TEXT if isinstance(value, str | bytes) else MAX_ITEMS


def _check_operands(op: str, a: Any, b: Any) -> None:
    """Refuse ``a op b`` whose result would be past the bounds, before computing it."""
    ints = isinstance(a, int) and isinstance(b, int)
    if op == "+" and isinstance(a, _SEQUENCES) and isinstance(b, _SEQUENCES):
        if len(a) + len(b) > _limit(a):
            raise _too_big(f"joining {len(a)} and {len(b)} items")
    elif op == "*":
        seq, n = (a, b) if isinstance(a, _SEQUENCES) else (b, a)
        if isinstance(seq, _SEQUENCES) and isinstance(n, int) and len(seq) * n > _limit(seq):
            raise _too_big(f"{len(seq)} items repeated {n} times")
        if ints and a.bit_length() + b.bit_length() > MAX_INT_BITS:
            raise _too_big("a product of this size")
    elif op == "**" and ints and b > 0 and abs(a) > 1:
        if a.bit_length() * b > MAX_INT_BITS:
            raise _too_big(f"a power of {b}")
    elif op == "<<" and ints and b > MAX_INT_BITS:
        raise _too_big(f"a shift by {b}")
    elif op == "%" and isinstance(a, str | bytes):
        fmt = a if isinstance(a, str) else a.decode("latin-1")
        for m in _PERCENT.finditer(fmt):
            for n in m.groups():
                if n == "*" or (n is not None and (len(n) > 7 or int(n) > MAX_TEXT)):
                    raise _too_big("a %-format field this wide")


_GROWING = ("ljust", "rjust", "center", "zfill", "expandtabs", "replace")


def _bounded_method(text: str, name: str) -> Callable[..., Any]:
    """``text.name`` that refuses, before running, a result past :data:`MAX_TEXT`."""
    method = getattr(text, name)

    def bounded(*args: Any, **kwargs: Any) -> Any:
        size = len(text)
        if name in ("ljust", "rjust", "center", "zfill") and args and isinstance(args[0], int):
            size = max(size, args[0])
        elif name == "expandtabs":
            tab = args[0] if args else kwargs.get("tabsize", 8)
            size = len(text) * max(1, tab if isinstance(tab, int) else 1)
        elif name == "replace" and len(args) >= 2:
            old, new = args[0], args[1]
            if isinstance(old, str) and isinstance(new, str):
                count = text.count(old) if old else len(text) + 1
                size = len(text) + count * max(0, len(new) - len(old))
        if size > MAX_TEXT:
            raise _too_big(f"text of {size} characters")
        return method(*args, **kwargs)

    return bounded


class _Builtins(dict):
    """An expression's builtins: a name no symbol defines and that is one of Python's
    other builtins (``exec``, ``open``, ``getattr``) is refused by name rather than
    reported as undefined (a dict subclass: Python then looks names up through it)."""

    def __missing__(self, key: str) -> Any:
        if hasattr(builtins, key) and key not in EVAL_BUILTINS:
            raise _not_allowed(key)
        raise KeyError(key)  # Python reports it undefined, as stock xacro does


def _describe(obj: Any) -> str:
    if isinstance(obj, type):
        return obj.__name__
    name = getattr(obj, "__name__", None)
    if callable(obj) and isinstance(name, str):
        return name
    return f"a {type(obj).__name__}"


def _check_shadowing(symbols: Any) -> None:
    """Refuse when a symbol table holds a guard's name (an include's ``ns`` or a
    macro parameter can name anything): the guard would not be the one called."""
    for name in _GUARD_NAMES:
        if name in symbols:
            raise Refused(f"the name '{name}' is reserved")


# -- where an expression is written -----------------------------------------------------

_ENTITIES = {
    "<": "(?:<|&lt;)",
    ">": "(?:>|&gt;)",
    "&": "(?:&|&amp;)",
    '"': '(?:"|&quot;)',
    "'": "(?:'|&apos;)",
}


def _pattern(written: str) -> re.Pattern[str] | None:
    """A regex finding ``written`` in XML source: whitespace may be any whitespace
    (attribute values are normalized), ``<`` may be ``&lt;`` and so on."""
    tokens = written.split()[:12]
    if not tokens:
        return None
    parts = ["".join(_ENTITIES.get(c, re.escape(c)) for c in tok) for tok in tokens]
    return re.compile(r"\s+".join(parts))


def locate(written: str, files: Sequence[str | None]) -> tuple[str | None, int | None]:
    """The first of ``files`` holding ``written``, and the line where it starts. What
    was evaluated may differ from what was written (``$(arg)`` and ``${}`` inside it
    are substituted first): then the longest prefix of it that is found."""
    texts = []
    for f in dict.fromkeys(f for f in files if f):
        try:
            texts.append((f, untrusted.read_file(f, "description").decode("utf-8", "replace")))
        except (ConversionError, OSError):
            continue
    for size in (len(written), 40, 20, 11):
        pattern = _pattern(written[:size])
        for f, text in texts:
            match = pattern.search(text) if pattern else None
            if match:
                return f, text.count("\n", 0, match.start()) + 1
    return next((f for f in files if f), None), None


# -- installing the guards into xacro ---------------------------------------------------


class _Installer:
    def __init__(self, xacro: Any, roots: Callable[[], Sequence[Path]], source: Path):
        self.x = xacro
        self.roots = roots
        self.source = source
        glob = xacro._global_symbols
        self.namespaces = {id(glob[n]): n for n in NAMESPACE_ALLOWED}
        self.guards = Guards(self.namespaces, xacro.NameSpace, xacro.YamlDictWrapper, xacro.Table)
        self.expr_builtins = self.guards.guard_builtins()  # ${...}: none but the guards, as stock
        allowed = {k: getattr(builtins, k) for k in EVAL_BUILTINS}
        self.eval_builtins = self.guards.guard_builtins(allowed)

    # where errors point
    def _files(self) -> list[str | None]:
        x = self.x
        stack = list(x.filestack or [])
        files: list[str | None] = stack[-1:]
        for macro in reversed(x.macrostack or []):
            if macro.history and macro.history[-1]:
                files.append(macro.history[-1][-1])
        files += list(reversed(stack)) + list(x.all_includes) + [str(self.source)]
        return files

    def error(self, written: str, reason: str) -> XacroError:
        file, line = locate(written, self._files())
        return XacroError(
            f"{untrusted.excerpt(written)}: {reason}",
            file=file or self.source,
            element=f"line {line}" if line else None,
        )

    # ${...}
    def safe_eval(self, expr: str, globals: Any, locals: Any = None) -> Any:
        written = "${" + expr + "}"
        try:
            code = check(expr)
            _check_shadowing(globals)
            globals.update(__builtins__=self.expr_builtins)  # as stock, plus the guards
            return eval(code, globals, locals)
        except Refused as exc:
            raise self.error(written, exc.reason) from None

    # $(eval ...)
    def eval_extension(self, s: str, context: dict) -> str:
        from xacro import substitution_args as sa

        if "arg" not in context:
            context["arg"] = {}

        def arg(name: str) -> Any:
            return sa.convert_value(sa._eval_arg(name, args=context["arg"]), "auto")

        def dirname() -> str:
            return sa._eval_dirname(context["filename"])

        functions = {"arg": arg, "dirname": dirname}
        functions.update(sa._eval_dict)
        if s.find("__") >= 0:  # stock xacro's own rule, kept so its errors stay the same
            raise sa.SubstitutionException(
                "$(eval ...) may not contain double underscore expressions"
            )
        written = f"$(eval {s})"
        try:
            code = check(s)
            _check_shadowing(context["arg"])
            globs = {"__builtins__": self.eval_builtins}
            return str(eval(code, globs, sa._DictWrapper(context["arg"], functions)))
        except Refused as exc:
            raise self.error(written, exc.reason) from None

    # what an attribute or a property expands to; macro calls; includes
    def eval_text(self, original: Callable[..., Any]) -> Callable[..., Any]:
        def eval_text(text: Any, symbols: Any) -> Any:
            result = original(text, symbols)
            if isinstance(result, str) and len(result) > MAX_TEXT:
                raise self.error(
                    str(text), f"expands to {len(result)} characters, over {MAX_TEXT} (refused)"
                )
            return result

        return eval_text

    def counted(
        self, original: Callable[..., Any], limit: int, what: str, count: list[int]
    ) -> Callable[..., Any]:
        # Counted as each returns true: xacro asks handle_macro_call of every element
        # whether it is a macro call (false for plain ones, which do not count)
        def counted(*args: Any, **kwargs: Any) -> Any:
            result = original(*args, **kwargs)
            if result is False:
                return result
            count[0] += 1
            if count[0] > limit:
                raise XacroError(
                    f"more than {limit} {what} in one expansion (refused: a description "
                    "that multiplies itself)",
                    file=self.x.filestack[-1] if self.x.filestack else self.source,
                )
            return result

        return counted

    # xacro.load_yaml
    def load_yaml(self, filename: Any) -> Any:
        x = self.x
        path = x.abs_filename_spec(str(filename))
        self._inside_packages(path)
        try:
            data = untrusted.read_file(path, "yaml", error=XacroError, what="YAML file")
        except XacroError as exc:
            raise Refused(exc.detail) from None
        x.filestack.append(path)
        try:
            loader = _unit_loader(x)(data)
            try:
                node = loader.get_single_node()
                if node is not None:
                    untrusted.check_yaml_size(node)
                value = loader.construct_document(node) if node is not None else None
            finally:
                loader.dispose()
            return x.YamlListWrapper.wrap(value)
        except untrusted.YamlBombError as exc:
            raise Refused(f"YAML file {path} {exc}") from None
        finally:
            x.filestack.pop()
            x.all_includes.append(path)

    def _inside_packages(self, path: str) -> None:
        real = os.path.realpath(path)
        roots = _allowed_roots(self.roots())
        if not any(real == r or real.startswith(r.rstrip(os.sep) + os.sep) for r in roots):
            shown = ", ".join(sorted(set(roots))[:4]) or "none"
            raise Refused(
                f"load_yaml of {path}: outside the description's packages ({shown}); "
                "only YAML files inside them are read"
            )

    # xacro:include (and the source file)
    def parse(self, original: Callable[..., Any]) -> Callable[..., Any]:
        x = self.x

        def parse(inp: Any, filename: str | None = None) -> Any:
            if inp is None and filename is not None:
                path = os.path.join(x.root_dir, filename)
                try:
                    os.stat(path)
                except (OSError, ValueError):
                    return original(inp, filename)  # missing: xacro's own error (optional=)
                data = self._read_include(path, filename)
                inp = io.TextIOWrapper(io.BytesIO(data))  # as open() would decode it
            return original(inp, filename)

        return parse


    def _read_include(self, path: str, filename: str) -> bytes:
        """An included file's bytes; a FIFO, device or oversized file is an error naming
        the including file and the line of the include."""
        try:
            return untrusted.read_file(path, "description", error=XacroError, what="file")
        except XacroError as exc:
            stack = list(self.x.filestack or [])
            parents = stack[:-1] if stack and stack[-1] == filename else stack
            if not parents or parents == [None]:
                raise  # the source file itself
            file, line = locate(os.path.basename(filename), parents[-1:])
            where = f"line {line}: xacro:include" if line else "xacro:include"
            raise XacroError(exc.detail, file=file, element=where) from None


def _allowed_roots(folders: Sequence[Path]) -> list[str]:
    """Each folder (real path) and, where its package.xml is a symlink to another
    package.xml (colcon --symlink-install), that file's folder."""
    out = []
    for folder in folders:
        out.append(os.path.realpath(folder))
        manifest = Path(folder) / "package.xml"
        if manifest.is_symlink():
            target = os.path.realpath(manifest)
            if os.path.basename(target) == "package.xml":
                out.append(os.path.dirname(target))
    return out


def _unit_loader(x: Any) -> type:
    """A SafeLoader with xacro's ``!degrees``-style unit tags, on a private subclass
    (stock xacro adds them to yaml.SafeLoader for the whole process)."""
    import yaml

    class UnitLoader(yaml.SafeLoader):
        pass

    for unit in x.ConstructUnits:
        UnitLoader.add_constructor(unit.value.tag, unit.constructor)
    return UnitLoader


@contextmanager
def installed(roots: Callable[[], Sequence[Path]], source: Path) -> Iterator[None]:
    """Checked expressions, confined ``load_yaml``, checked includes, for one expansion.
    ``roots()`` is the folders whose YAML files ``load_yaml`` may read. Call it under
    the lock that serializes xacro; everything is restored on exit."""
    import xacro
    from xacro import substitution_args as sa

    inst = _Installer(xacro, roots, source)
    glob = xacro._global_symbols
    xacro_ns = glob["xacro"]
    saved = (
        xacro.safe_eval,
        xacro.parse,
        sa._eval,
        xacro.eval_text,
        xacro.handle_macro_call,
        xacro.process_include,
        dict.get(xacro_ns, "load_yaml"),
        glob.get("load_yaml"),
        glob.get("__builtins__", _MISSING),
    )

    def deprecated_load_yaml(filename: Any) -> Any:
        xacro.warning("Using load_yaml() directly is deprecated. Use xacro.load_yaml() instead.")
        return inst.load_yaml(filename)

    xacro.safe_eval = inst.safe_eval
    xacro.parse = inst.parse(saved[1])
    sa._eval = inst.eval_extension
    xacro.eval_text = inst.eval_text(saved[3])
    xacro.handle_macro_call = inst.counted(saved[4], MAX_MACRO_CALLS, "macro calls", [0])
    xacro.process_include = inst.counted(saved[5], MAX_INCLUDES, "includes", [0])
    dict.__setitem__(xacro_ns, "load_yaml", inst.load_yaml)
    glob["load_yaml"] = deprecated_load_yaml
    try:
        yield
    finally:
        xacro.safe_eval, xacro.parse, sa._eval = saved[:3]
        xacro.eval_text, xacro.handle_macro_call, xacro.process_include = saved[3:6]
        dict.__setitem__(xacro_ns, "load_yaml", saved[6])
        glob["load_yaml"] = saved[7]
        if saved[8] is _MISSING:
            glob.pop("__builtins__", None)
        else:
            glob["__builtins__"] = saved[8]


_MISSING = object()


def trust_from_env(environ: Any = None) -> bool:
    """``$URDF2MJCF_TRUST_XACRO`` as a flag: 1/true/yes, 0/false/no or empty; anything
    else is an InputError naming the variable."""
    raw = (os.environ if environ is None else environ).get(TRUST_ENV, "")
    value = raw.strip().lower()
    if value in ("1", "true", "yes"):
        return True
    if value in ("", "0", "false", "no"):
        return False
    raise InputError(
        f"'{untrusted.excerpt(raw)}' is not a flag (use 1, true, yes, 0, false, no or "
        "leave it empty)",
        file=f"${TRUST_ENV}",
    )
