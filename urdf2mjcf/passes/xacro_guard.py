"""Checked evaluation of xacro expressions: a description cannot run code, nor make
the expansion work or hold memory without bound.

Stock xacro evaluates ``${...}`` with ``eval`` and no builtins, which is
escapable (``python.vars``, ``python.type``, generator frames, format-string
attribute walks), and ``$(eval ...)`` with every builtin (``exec``, ``open``).
Here every expression is parsed with :mod:`ast` and checked before it runs:

* statically: no lambda, walrus, yield/await, async comprehension, no
  assignment to anything but plain names (comprehension targets), no name
  starting with ``__``, no attribute starting with ``_``, no string subscript
  key starting with ``__``, not nested deeper than :data:`MAX_DEPTH`;
* at run time: every operation of the checked tree that can reach an object or
  do work is rewritten into a call of a guard: attribute loads and subscripts
  (only xacro's name spaces, the global ``python``, ``math`` and ``xacro`` only
  for :data:`NAMESPACE_ALLOWED`, YAML data, and the methods of strings, numbers,
  lists, tuples, dicts and sets that read values: ``str.format`` without ``.``
  or ``[`` in its fields, no ``format_map``, no ``list.append``), calls,
  operators, comparisons, displays, comprehensions, ``*`` unpacking and
  f-strings.

The guards charge the expansion's budget (:mod:`.xacro_budget`: a bound on work
in steps and on memory in bytes, for all expressions, expanded text and
elements together) and refuse a value past the bounds on single values before
making it. A call reaches a builtin only through its bounded version
(:mod:`.xacro_bounded`), which charges the loop the builtin runs in C, so
``sum(map(sum, ...))`` and ``1.5 in range(...)`` are refused before they run.

The guards reach the expression through the ``__builtins__`` dict xacro
already replaces per call, under names that are not identifiers (a
description cannot write them) and that no symbol table may hold (checked
before each evaluation). :mod:`.xacro_install` puts all of it into xacro for
one expansion.
"""

from __future__ import annotations

import ast
import builtins
import math
import operator
import os
import re
import string
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from types import CodeType
from typing import Any

from .. import untrusted
from ..errors import InputError
from .xacro_bounded import HINT, Bounded, Method, not_allowed
from .xacro_budget import (
    MAX_INT_BITS,
    MAX_ITEMS,
    MAX_MEMORY,
    MAX_TEXT,
    MAX_WORK,
    NAME_STEPS,
    OPERATION,
    WALK_STEPS,
    Budget,
    Refused,
    int_steps,
    search_steps,
    text_steps,
    too_big,
)

__all__ = [
    "HINT",
    "MAX_DEPTH",
    "MAX_INT_BITS",
    "MAX_ITEMS",
    "MAX_MEMORY",
    "MAX_TEXT",
    "MAX_WORK",
    "Guards",
    "Refused",
    "check",
    "checked",
    "trust_from_env",
]

TRUST_ENV = "URDF2MJCF_TRUST_XACRO"
"""``1``/``true``/``yes`` runs a description's code as ROS's xacro does (API, facility)."""

MAX_DEPTH = 100
"""How deeply an expression's syntax tree may nest (real ones stay below 30)."""

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

# Names no description can write or define (not identifiers); see check_shadowing.
G_ATTR = "xacro guard.attribute"
G_ITEM = "xacro guard.subscript"
G_SLICE = "xacro guard.slice"
G_CALL = "xacro guard.call"
G_BINOP = "xacro guard.binop"
G_UNARY = "xacro guard.unary"
G_CMP = "xacro guard.compare"
G_ITER = "xacro guard.iter"
G_MADE = "xacro guard.made"
G_STAR = "xacro guard.unpack"
G_FORMAT = "xacro guard.format"
G_FSTRING = "xacro guard.fstring"
GUARD_NAMES = (
    G_ATTR,
    G_ITEM,
    G_SLICE,
    G_CALL,
    G_BINOP,
    G_UNARY,
    G_CMP,
    G_ITER,
    G_MADE,
    G_STAR,
    G_FORMAT,
    G_FSTRING,
)

_FORBIDDEN_NODES: dict[type, str] = {
    ast.Lambda: "lambda",
    ast.NamedExpr: ":=",
    ast.Yield: "yield",
    ast.YieldFrom: "yield from",
    ast.Await: "await",
}


def refusal(what: str) -> Refused:
    return not_allowed(what)


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


def _spec_text(spec: ast.expr | None) -> str:
    if spec is None:
        return ""
    parts = spec.values if isinstance(spec, ast.JoinedStr) else [spec]
    return "".join(str(p.value) for p in parts if isinstance(p, ast.Constant))


def _check_node(node: ast.AST) -> None:
    if type(node) in _FORBIDDEN_NODES:
        raise refusal(_FORBIDDEN_NODES[type(node)])
    if isinstance(node, ast.Name) and node.id.startswith("__"):
        raise refusal(node.id)
    if isinstance(node, ast.Attribute):
        if node.attr.startswith("_"):
            raise refusal(f".{node.attr}")
        if not isinstance(node.ctx, ast.Load):
            raise refusal(f"assignment to .{node.attr}")
    if isinstance(node, ast.Subscript):
        key = node.slice
        if isinstance(key, ast.Constant) and isinstance(key.value, str | bytes):
            text = key.value if isinstance(key.value, str) else key.value.decode("latin-1")
            if text.startswith("__"):
                raise refusal(f"[{text!r}]")
        if not isinstance(node.ctx, ast.Load):
            raise refusal("assignment to a subscript")
    if isinstance(node, ast.Starred) and not isinstance(node.ctx, ast.Load):
        raise refusal("starred assignment")
    if isinstance(node, ast.comprehension) and node.is_async:
        raise refusal("async for")
    if isinstance(node, ast.FormattedValue) and node.format_spec is not None:
        spec = node.format_spec
        parts = spec.values if isinstance(spec, ast.JoinedStr) else [spec]
        if not all(isinstance(p, ast.Constant) and isinstance(p.value, str) for p in parts):
            raise refusal("an f-string format spec that is computed")
        text = _spec_text(spec)
        if _too_wide(text):
            raise Refused(
                f"format spec '{untrusted.excerpt(text, 20)}' is wider than the bound of "
                f"{MAX_TEXT:,} characters (refused)"
            )


_BINARY = {
    ast.Add: "+",
    ast.Sub: "-",
    ast.Mult: "*",
    ast.Div: "/",
    ast.FloorDiv: "//",
    ast.Mod: "%",
    ast.Pow: "**",
    ast.LShift: "<<",
    ast.RShift: ">>",
    ast.BitOr: "|",
    ast.BitXor: "^",
    ast.BitAnd: "&",
    ast.MatMult: "@",
}
_UNARY = {ast.USub: "-", ast.UAdd: "+", ast.Invert: "~"}


def _counts(node: ast.AST) -> tuple[int, int]:
    """(syntax nodes, name lookups) of ``node``: what one evaluation of it costs
    besides its guarded operations (a name is looked up through every scope)."""
    nodes = names = 0
    for sub in ast.walk(node):
        nodes += 1
        names += isinstance(sub, ast.Name)
    return nodes, names


class _Rewrite(ast.NodeTransformer):
    """Every operation that reaches an object or does work -> a call of its guard:
    ``a.b`` -> ``G_ATTR(a, 'b')``, ``a[k]`` -> ``G_ITEM(a, k)``, ``f(x)`` ->
    ``G_CALL(f, x)``, ``a + b`` -> ``G_BINOP('+', a, b)``, ``[x, y]`` ->
    ``G_MADE([x, y])``, ``for x in it`` -> ``for x in G_ITER(it, ...)`` and so on."""

    def __init__(self) -> None:
        self._per: list[tuple[int, int]] = []

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
        keywords = []
        for k in node.keywords:
            value = self.visit(k.value)
            if k.arg is None:  # **mapping
                value = self._call(G_STAR, [value], k.value)
            keywords.append(ast.copy_location(ast.keyword(arg=k.arg, value=value), k))
        call = ast.Call(
            func=ast.Name(id=G_CALL, ctx=ast.Load()),
            args=[self.visit(node.func), *(self.visit(a) for a in node.args)],
            keywords=keywords,
        )
        return ast.copy_location(call, node)

    def visit_BinOp(self, node: ast.BinOp) -> ast.expr:
        left, right = self.visit(node.left), self.visit(node.right)
        op = ast.Constant(_BINARY[type(node.op)])
        return self._call(G_BINOP, [op, left, right], node)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> ast.expr:
        if isinstance(node.op, ast.Not) or isinstance(node.operand, ast.Constant):
            return self.generic_visit(node)  # type: ignore[return-value]
        op = ast.Constant(_UNARY[type(node.op)])
        return self._call(G_UNARY, [op, self.visit(node.operand)], node)

    def visit_Compare(self, node: ast.Compare) -> ast.expr:
        if all(isinstance(op, ast.Is | ast.IsNot) for op in node.ops):
            return self.generic_visit(node)  # type: ignore[return-value]
        search = ast.Constant(any(isinstance(op, ast.In | ast.NotIn) for op in node.ops))
        left = self._call(G_CMP, [self.visit(node.left), search], node.left)
        rights: list[ast.expr] = [
            self._call(G_CMP, [self.visit(c), search], c) for c in node.comparators
        ]
        return ast.copy_location(ast.Compare(left=left, ops=node.ops, comparators=rights), node)

    def visit_Starred(self, node: ast.Starred) -> ast.expr:
        value = self._call(G_STAR, [self.visit(node.value)], node.value)
        return ast.copy_location(ast.Starred(value=value, ctx=node.ctx), node)

    def _made(self, node: ast.expr) -> ast.expr:
        return self._call(G_MADE, [self.generic_visit(node)], node)  # type: ignore[list-item]

    def visit_List(self, node: ast.List) -> ast.expr:
        return self._made(node) if isinstance(node.ctx, ast.Load) else node

    def visit_Set(self, node: ast.Set) -> ast.expr:
        return self._made(node)

    def visit_Tuple(self, node: ast.Tuple) -> ast.expr:
        if not isinstance(node.ctx, ast.Load) or all(
            isinstance(e, ast.Constant) for e in node.elts
        ):
            return self.generic_visit(node)  # type: ignore[return-value]
        return self._made(node)

    def visit_Dict(self, node: ast.Dict) -> ast.expr:
        values = [
            self._call(G_STAR, [self.visit(v)], v) if k is None else self.visit(v)
            for k, v in zip(node.keys, node.values, strict=True)
        ]
        keys = [self.visit(k) if k is not None else None for k in node.keys]
        made = ast.copy_location(ast.Dict(keys=keys, values=values), node)
        return self._call(G_MADE, [made], node)

    def _comprehension(self, node: ast.expr, made: bool) -> ast.expr:
        self._per.append(_counts(node))
        try:
            out = self.generic_visit(node)
        finally:
            self._per.pop()
        return self._call(G_MADE, [out], node) if made else out  # type: ignore[list-item,return-value]

    def visit_ListComp(self, node: ast.ListComp) -> ast.expr:
        return self._comprehension(node, True)

    def visit_SetComp(self, node: ast.SetComp) -> ast.expr:
        return self._comprehension(node, True)

    def visit_DictComp(self, node: ast.DictComp) -> ast.expr:
        return self._comprehension(node, True)

    def visit_GeneratorExp(self, node: ast.GeneratorExp) -> ast.expr:
        return self._comprehension(node, False)

    def visit_comprehension(self, node: ast.comprehension) -> ast.comprehension:
        nodes, names = self._per[-1]
        args = [self.visit(node.iter), ast.Constant(nodes), ast.Constant(names)]
        it = self._call(G_ITER, args, node.iter)
        return ast.comprehension(
            target=node.target,
            iter=it,
            ifs=[self.visit(i) for i in node.ifs],
            is_async=node.is_async,
        )

    def visit_JoinedStr(self, node: ast.JoinedStr) -> ast.expr:
        parts: list[ast.expr] = []
        for v in node.values:
            if isinstance(v, ast.FormattedValue):
                args = [
                    self.visit(v.value),
                    ast.Constant(v.conversion),
                    ast.Constant(_spec_text(v.format_spec)),
                ]
                parts.append(self._call(G_FORMAT, args, v))
            else:
                parts.append(v)
        return self._call(G_FSTRING, parts, node)


_OPERATORS: dict[str, Callable[[Any, Any], Any]] = {
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
    "/": operator.truediv,
    "//": operator.floordiv,
    "%": operator.mod,
    "**": operator.pow,
    "<<": operator.lshift,
    ">>": operator.rshift,
    "|": operator.or_,
    "^": operator.xor,
    "&": operator.and_,
    "@": operator.matmul,
}
_UNARIES: dict[str, Callable[[Any], Any]] = {
    "-": operator.neg,
    "+": operator.pos,
    "~": operator.invert,
}
_QUADRATIC = frozenset(("*", "/", "//", "%", "**"))
_WIDTH = re.compile(r"(\d+)")


def _too_wide(spec: str) -> bool:
    """Whether a format spec (``>20``, ``.3f``, ``0999999999d``) asks for a field wider
    or more precise than :data:`MAX_TEXT` characters could hold."""
    return any(len(n) > 8 or int(n) > MAX_TEXT for n in _WIDTH.findall(spec))


@dataclass(frozen=True)
class Checked:
    """An expression checked and compiled with its guards, and what one evaluation of
    it costs besides its guarded operations."""

    code: CodeType
    nodes: int
    names: int


def checked(expression: str) -> Checked:
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
    nodes, names = _counts(tree)
    tree = ast.fix_missing_locations(_Rewrite().visit(tree))
    try:
        return Checked(compile(tree, "<expression>", "eval"), nodes, names)
    except (SyntaxError, ValueError, RecursionError, MemoryError) as exc:
        raise Refused(f"invalid expression: {exc}") from None


def check(expression: str) -> CodeType:
    """:func:`checked`'s compiled code."""
    return checked(expression).code


# -- run-time guards --------------------------------------------------------------------

_PLAIN_TYPES: dict[type, frozenset[str]] = {}


def _public(cls: type, drop: Sequence[str] = ()) -> frozenset[str]:
    return frozenset(n for n in dir(cls) if not n.startswith("_") and n not in drop)


for _cls in (int, float, complex, bool, bytes, tuple, range, set, frozenset, list, dict):
    _PLAIN_TYPES[_cls] = _public(_cls)
_PLAIN_TYPES[str] = _public(str, drop=("format_map",))


def _format_fields_plain(fmt: str) -> bool:
    """Whether no replacement field of ``fmt`` walks attributes or items (``{0.x}``,
    ``{0[k]}``): that is how ``str.format`` reaches an object's internals."""
    try:
        for _, field, spec, _ in string.Formatter().parse(fmt):
            if field is not None and ("." in field or "[" in field):
                return False
            if spec and _too_wide(spec):
                return False
            if spec and "{" in spec and not _format_fields_plain(spec):
                return False
    except (ValueError, RecursionError):
        return True  # str.format itself will report the malformed format string
    return True


_SETS: Any = (set, frozenset, dict, type({}.keys()), type({}.items()))


class Guards:
    """The guards for one expansion: what every rewritten operation calls."""

    def __init__(
        self,
        namespaces: dict[int, str],
        namespace_type: Any,
        yaml_dict: type,
        table_type: Any,
        yaml_list: type = list,
    ):
        self.namespaces = namespaces  # id of xacro's global NameSpace -> its name
        self.namespace_type = namespace_type
        self.yaml_dict = yaml_dict
        self.yaml_list = yaml_list
        self.table_type = table_type
        self.budget = Budget(table_type)
        self.bounded = Bounded(self.budget, self.call, self.binop, copying=(yaml_list,))
        self.depth = 0  # scopes the expression being evaluated looks names up through

    def attr(self, obj: Any, name: str) -> Any:
        self.budget.work(OPERATION)
        if name.startswith("_"):
            raise refusal(f".{name}")
        if isinstance(obj, self.table_type):
            return self._namespace_attr(obj, name)
        kind = type(obj)
        if isinstance(obj, self.yaml_dict) and not hasattr(dict, name):
            return self._copied(getattr(obj, name))  # a YAML key, as xacro's dotted access
        for base in (kind, *kind.__mro__[1:]):
            allowed = _PLAIN_TYPES.get(base)
            if allowed is None:
                continue
            if name not in allowed:
                break
            if base is str and name == "format":
                self.budget.work(text_steps(len(obj)) + obj.count("{") * WALK_STEPS)
                if not _format_fields_plain(obj):
                    raise refusal("'{...}'.format with '.' or '[' in a field")
            return self.bounded.method(obj, base, name)
        raise refusal(f"{_describe(obj)}.{name}")

    def _copied(self, value: Any) -> Any:
        """A YAML value xacro's wrapper hands out (a list or dict it copies each time)."""
        if isinstance(value, list | dict):
            return self.budget.made(value)
        return value

    def _namespace_attr(self, obj: Any, name: str) -> Any:
        glob = self.namespaces.get(id(obj))
        if glob is not None and name not in NAMESPACE_ALLOWED[glob]:
            raise refusal(f"{glob}.{name}")
        if hasattr(type(obj), name) or name in vars(obj):  # a method or the table's parent
            raise refusal(f"{glob or 'namespace'}.{name}")
        return self.namespace_type.__getattr__(obj, name)  # xacro's own dotted lookup

    def item(self, obj: Any, key: Any) -> Any:
        self.budget.work(OPERATION)
        if isinstance(obj, self.table_type):
            glob = self.namespaces.get(id(obj))
            if isinstance(key, str) and key.startswith("_"):
                raise refusal(f"{glob or 'namespace'}[{key!r}]")
            if glob is not None and key not in NAMESPACE_ALLOWED[glob]:
                raise refusal(f"{glob}[{key!r}]")
            return obj[key]
        if isinstance(obj, str | bytes | list | tuple | dict | range):
            if isinstance(obj, dict):
                self.budget.walk(key)  # hashed and compared
            result = obj[key]
            if isinstance(key, slice):
                return self.budget.made(result)
            if isinstance(obj, self.yaml_dict | self.yaml_list):
                return self._copied(result)
            return result
        raise refusal(f"{_describe(obj)}[...]")

    def call(self, func: Any, /, *args: Any, **kwargs: Any) -> Any:
        self.budget.work(OPERATION + len(args) + len(kwargs))
        bounded = self.bounded.lookup(func)
        if bounded is not None:
            return bounded(*args, **kwargs)
        if type(func) is Method or not callable(func):
            return func(*args, **kwargs)  # a bounded method; or Python's own TypeError
        raise refusal(f"calling {_describe(func)}")

    def binop(self, op: str, a: Any, b: Any) -> Any:
        budget = self.budget
        budget.work(OPERATION)
        _check_operands(op, a, b)
        if op == "%" and isinstance(a, str | bytes):
            size = self.bounded.percent_size(a, b)
            if size > MAX_TEXT:
                raise too_big(
                    f"a %-format of up to {size:,} characters", f"{MAX_TEXT:,} characters"
                )
            budget.work(text_steps(size))
        elif isinstance(a, int) and isinstance(b, int):
            if op == "**" and b > 0:
                digits = abs(a).bit_length() * b // 30 + 1
                budget.work(digits * digits // 16)
            else:
                budget.work(int_steps(a, b, op in _QUADRATIC))
        elif isinstance(a, _SETS) or isinstance(b, _SETS):
            budget.walk(a)  # each item hashed
            budget.walk(b)
        return budget.made(_OPERATORS[op](a, b))

    def unary(self, op: str, x: Any) -> Any:
        self.budget.work(OPERATION + (int_steps(x, 0, False) if isinstance(x, int) else 0))
        return self.budget.made(_UNARIES[op](x))

    def compare(self, x: Any, search: bool) -> Any:
        """An operand of a comparison: comparing (``==``, ``<``, ``in``) walks it, and
        ``in`` searches a text for a substring."""
        if search and isinstance(x, str | bytes):
            self.budget.work(OPERATION // 2 + search_steps(len(x)))
            return x
        if search and isinstance(x, range):  # 2.5 in range(n) compares with every item
            self.budget.work(OPERATION // 2 + 3 * len(x))
            return x
        self.budget.work(OPERATION // 2)
        return self.budget.walk(x)

    def iterate(self, iterable: Any, nodes: int, names: int) -> Iterator[Any]:
        per = OPERATION + nodes + names * NAME_STEPS * (1 + self.depth)
        budget = self.budget
        copying = isinstance(iterable, self.yaml_list)
        for item in iterable:
            budget.work(per)
            if copying:
                budget.walk(item)
            yield item

    def made(self, value: Any) -> Any:
        return self.budget.made(value)

    def unpack(self, value: Any) -> Any:
        """``*value`` or ``**value``: its items are copied into a new call or display."""
        try:
            n = len(value)
        except TypeError:
            return value  # an iterator: each item it yields is charged as it is made
        self.budget.work(1 + n)
        self.budget.hold(8 * n)
        return value

    def format(self, value: Any, conversion: int, spec: str) -> str:
        """One field of an f-string, as Python formats it (``f'{x!r:>10}'``)."""
        size = self.bounded.field_size(value, conversion, spec)
        if size > MAX_TEXT:
            raise too_big(
                f"an f-string field of up to {size:,} characters", f"{MAX_TEXT:,} characters"
            )
        self.budget.work(OPERATION + text_steps(size))
        if conversion == ord("s"):
            value = str(value)
        elif conversion == ord("r"):
            value = repr(value)
        elif conversion == ord("a"):
            value = ascii(value)
        return self.budget.made(builtins.format(value, spec))

    def fstring(self, *parts: str) -> str:
        size = sum(len(p) for p in parts)
        if size > MAX_TEXT:
            raise too_big(f"an f-string of {size:,} characters", f"{MAX_TEXT:,} characters")
        self.budget.work(OPERATION + text_steps(size))
        return self.budget.made("".join(parts))

    def guard_builtins(self, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        out = _Builtins(extra or {})
        out.update(
            {
                G_ATTR: self.attr,
                G_ITEM: self.item,
                G_SLICE: slice,
                G_CALL: self.call,
                G_BINOP: self.binop,
                G_UNARY: self.unary,
                G_CMP: self.compare,
                G_ITER: self.iterate,
                G_MADE: self.made,
                G_STAR: self.unpack,
                G_FORMAT: self.format,
                G_FSTRING: self.fstring,
            }
        )
        return out


_SEQUENCES = (str, bytes, list, tuple)


def _limit(value: Any) -> tuple[int, str]:
    if isinstance(value, str | bytes):
        return MAX_TEXT, f"{MAX_TEXT:,} characters"
    return MAX_ITEMS, f"{MAX_ITEMS:,} items"


def _check_operands(op: str, a: Any, b: Any) -> None:
    """Refuse ``a op b`` whose result would be past the bounds, before computing it."""
    ints = isinstance(a, int) and isinstance(b, int)
    if op == "+" and isinstance(a, _SEQUENCES) and isinstance(b, _SEQUENCES):
        limit, bound = _limit(a)
        if len(a) + len(b) > limit:
            raise too_big(f"joining {len(a):,} and {len(b):,} items", bound)
    elif op == "*":
        seq, n = (a, b) if isinstance(a, _SEQUENCES) else (b, a)
        if isinstance(seq, _SEQUENCES) and isinstance(n, int):
            limit, bound = _limit(seq)
            if len(seq) * n > limit:
                unit = "characters" if isinstance(seq, (str, bytes)) else "items"
                unit = unit if len(seq) != 1 else unit[:-1]
                raise too_big(f"{len(seq):,} {unit} repeated {n:,} times", bound)
        if ints and a.bit_length() + b.bit_length() > MAX_INT_BITS:
            raise too_big("a product of this size", f"{MAX_INT_BITS:,} bits")
    elif op == "**" and ints and b > 0 and abs(a) > 1:
        if a.bit_length() * b > MAX_INT_BITS:
            raise too_big(f"a power of {b:,}", f"{MAX_INT_BITS:,} bits")
    elif op == "<<" and ints and b > MAX_INT_BITS:
        raise too_big(f"a shift by {b:,}", f"{MAX_INT_BITS:,} bits")


class _Builtins(dict):
    """An expression's builtins: a name no symbol defines and that is one of Python's
    other builtins (``exec``, ``open``, ``getattr``) is refused by name rather than
    reported as undefined (a dict subclass: Python then looks names up through it)."""

    def __missing__(self, key: str) -> Any:
        if hasattr(builtins, key) and key not in EVAL_BUILTINS:
            raise refusal(key)
        raise KeyError(key)  # Python reports it undefined, as stock xacro does


def _describe(obj: Any) -> str:
    if isinstance(obj, type):
        return obj.__name__
    name = getattr(obj, "__name__", None)
    if callable(obj) and isinstance(name, str):
        return name
    return f"a {type(obj).__name__}"


def check_shadowing(symbols: Any) -> None:
    """Refuse when a symbol table holds a guard's name (an include's ``ns`` or a
    macro parameter can name anything): the guard would not be the one called."""
    for name in GUARD_NAMES:
        if name in symbols:
            raise Refused(f"the name '{name}' is reserved")


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
