"""The expression checks, bounds and confinements installed into xacro for one
expansion (:func:`installed`).

xacro keeps its state in module globals and calls its own functions through
them, so wrapping those functions reaches every call: ``safe_eval`` (``${...}``)
and ``substitution_args._eval`` (``$(eval ...)``) evaluate through
:mod:`.xacro_guard`; ``eval_text``, ``eval_extension`` and ``eval_all`` charge
the expansion's :class:`~urdf2mjcf.passes.xacro_budget.Budget` for the text
attributes expand to and the elements the document gets (a macro body or a
block is copied at each use, an included file parsed); ``handle_macro_call``
and ``process_include`` are counted; ``parse`` reads included files as regular
files within the size limit; ``xacro.load_yaml`` reads only YAML files inside
the description's packages. xacro's own functions (``xacro.tokenize``,
``xacro.message``, the deprecated global ``sorted``) get bounded versions.
Everything is restored on exit; ``--trust-xacro`` installs nothing.
"""

from __future__ import annotations

import builtins
import inspect
import io
import logging
import os
import re
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from .. import schema, untrusted
from ..errors import ConversionError, XacroError
from .xacro_budget import (
    MAX_ITEMS,
    MAX_TEXT,
    NAME_STEPS,
    NODE_BYTES,
    NODE_STEPS,
    OPERATION,
    PARSE_BYTES,
    PARSE_STEPS,
    WALK_STEPS,
    Refused,
    search_steps,
    text_steps,
    too_big,
)
from .xacro_guard import (
    EVAL_BUILTINS,
    GUARD_NAMES,
    NAMESPACE_ALLOWED,
    Checked,
    Guards,
    check_shadowing,
    checked,
    refusal,
)

log = logging.getLogger(__name__)

MAX_MACRO_CALLS = 20_000
"""Macro calls one expansion may make (our facility, the largest description we
test, makes 365; a call costs up to a few milliseconds)."""
MAX_MACRO_DEPTH = 100
"""Macro calls one may nest inside another: a macro that calls itself once per item
of a list nests as deep as the list is long (our iMETRO robot 38), and xacro
recurses in Python, whose stack ends between 100 and 150 levels."""
MAX_INCLUDES = 10_000
"""Files one expansion may include."""
INCLUDE_BYTES = 20
"""Bytes of memory an included file's document takes per byte of XML (measured: 17)."""


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
        self.guards = Guards(
            self.namespaces,
            xacro.NameSpace,
            xacro.YamlDictWrapper,
            xacro.Table,
            xacro.YamlListWrapper,
        )
        self.budget = self.guards.budget
        self.bounded = self.guards.bounded
        self.expr_builtins = self.guards.guard_builtins()  # ${...}: none but the guards, as stock
        allowed = {k: getattr(builtins, k) for k in EVAL_BUILTINS}
        self.eval_builtins = self.guards.guard_builtins(allowed)
        self.codes: dict[str, Checked] = {}  # each text is parsed once per expansion
        self.texts: list[list[int]] = []  # characters each eval_text being run will join

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

    def refused(self, reason: str) -> XacroError:
        """A bound spent outside any expression (expanding elements or text)."""
        x = self.x
        macros = [m.body.getAttribute("name") for m in (x.macrostack or [])]
        element = f"xacro macro '{macros[-1]}'" if macros else "xacro"
        file = x.filestack[-1] if x.filestack and x.filestack[-1] else self.source
        return XacroError(reason, file=file, element=element)

    def compiled(self, expr: str) -> Checked:
        code = self.codes.get(expr)
        if code is None:
            self.budget.work(PARSE_STEPS * (len(expr) + 40))  # about 40 characters' worth fixed
            self.budget.hold(PARSE_BYTES * (len(expr) + 40))
            code = self.codes[expr] = checked(expr)
        return code

    def _evaluate(self, code: Checked, globs: Any, locs: Any, depth: int) -> Any:
        guards = self.guards
        self.budget.work(OPERATION + code.nodes + code.names * NAME_STEPS * (1 + depth))
        saved, guards.depth = guards.depth, depth
        try:
            return eval(code.code, globs, locs)
        finally:
            guards.depth = saved

    def _joined(self, value: Any) -> None:
        """``value`` is one part of the text being expanded (xacro joins the parts as
        strings): the whole may not be past :data:`MAX_TEXT` characters."""
        if self.texts:
            frame = self.texts[-1]
            frame[0] += self.budget.text_size(value)
            if frame[0] > MAX_TEXT:
                raise too_big(
                    f"text expanding to {frame[0]:,} characters or more", f"{MAX_TEXT:,} characters"
                )

    # ${...}
    def safe_eval(self, expr: str, globals: Any, locals: Any = None) -> Any:
        written = "${" + expr + "}"
        try:
            code = self.compiled(expr)
            # the check looks each guard's name up through every scope of the call
            depth = getattr(globals, "depth", 0)
            self.budget.work(len(GUARD_NAMES) * NAME_STEPS * (1 + depth))
            check_shadowing(globals)
            globals.update(__builtins__=self.expr_builtins)  # as stock, plus the guards
            result = self._evaluate(code, globals, locals, depth)
            self._joined(result)
            return result
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

        functions: dict[str, Any] = {"arg": arg, "dirname": dirname}
        functions.update(sa._eval_dict)
        if s.find("__") >= 0:  # stock xacro's own rule, kept so its errors stay the same
            raise sa.SubstitutionException(
                "$(eval ...) may not contain double underscore expressions"
            )
        written = f"$(eval {s})"
        own: list[Callable[..., Any]] = [
            v for k, v in functions.items() if k in ("arg", "dirname", "env", "optenv", "find")
        ]
        for func in own:
            self.bounded.register(func, self.bounded.plain(func))
        try:
            code = self.compiled(s)
            check_shadowing(context["arg"])
            globs = {"__builtins__": self.eval_builtins}
            value = self._evaluate(code, globs, sa._DictWrapper(context["arg"], functions), 0)
            size = self.budget.text_size(value)
            if size > MAX_TEXT:
                raise too_big(f"text of up to {size:,} characters", f"{MAX_TEXT:,} characters")
            return self.budget.made(str(value))
        except Refused as exc:
            raise self.error(written, exc.reason) from None
        finally:
            for func in own:
                self.bounded.table.pop(id(func), None)

    # what an attribute or a property expands to
    def eval_text(self, original: Callable[..., Any]) -> Callable[..., Any]:
        budget = self.budget

        def eval_text(text: Any, symbols: Any) -> Any:
            try:
                size = len(text) if isinstance(text, str) else 0
                # xacro's lexer copies the rest of the text at each token
                budget.work(text_steps(size) * (1 + (text.count("$") if size else 0)))
                self.texts.append([size])
                try:
                    result = original(text, symbols)
                finally:
                    self.texts.pop()
                if isinstance(result, str):
                    if len(result) > MAX_TEXT:
                        raise self.error(
                            str(text),
                            f"expands to {len(result):,} characters, over the bound of "
                            f"{MAX_TEXT:,} characters (refused)",
                        )
                    budget.made(result)
                return result
            except Refused as exc:
                raise self.refused(exc.reason) from None

        return eval_text

    # $(arg ...), $(find ...), $(eval ...) as xacro substitutes them in text
    def substitution(self, original: Callable[..., Any]) -> Callable[..., Any]:
        budget = self.budget

        def eval_extension(s: str) -> Any:
            try:
                budget.work(OPERATION + len(s))  # read character by character
                result = original(s)
                self._joined(result)
                return result
            except Refused as exc:
                raise self.refused(exc.reason) from None

        return eval_extension

    # each element, text and comment of the expanded document
    def eval_all(self, original: Callable[..., Any]) -> Callable[..., Any]:
        budget = self.budget

        def eval_all(node: Any, macros: Any, symbols: Any) -> Any:
            attributes = node.attributes
            n = 1 + len(node.childNodes) + (len(attributes) if attributes else 0)
            try:
                budget.work(n * NODE_STEPS)
                budget.hold(n * NODE_BYTES)
            except Refused as exc:
                raise self.refused(exc.reason) from None
            return original(node, macros, symbols)

        return eval_all

    # a macro's expansion, a block or an included file put in place of its element
    def replace_node(self, original: Callable[..., Any]) -> Callable[..., Any]:
        budget = self.budget

        def replace_node(node: Any, by: Any, content_only: bool = False) -> Any:
            # minidom finds the element among its parent's children (list.index) for
            # each node it inserts and once to remove it: a macro that calls itself
            # twice piles thousands of elements into one parent, quadratic work no
            # element count sees (14 levels of it took 13 s)
            parent = node.parentNode
            moved = 1
            if by is not None:
                for doc in by if isinstance(by, list) else [by]:
                    moved += len(doc.childNodes) if content_only else 1
            try:
                budget.work(moved * (1 + len(parent.childNodes) if parent else 1))
            except Refused as exc:
                raise self.refused(exc.reason) from None
            return original(node, by, content_only)

        return replace_node

    # a macro called inside this many others
    def nested(self, original: Callable[..., Any]) -> Callable[..., Any]:
        x = self.x

        def handle_macro_call(node: Any, macros: Any, symbols: Any) -> Any:
            # every other xacro: element is handled before xacro asks this
            if node.tagName.startswith("xacro:") and len(x.macrostack) >= MAX_MACRO_DEPTH:
                raise XacroError(
                    f"macro '{x.macrostack[-1].body.getAttribute('name')}' calls "
                    f"'{node.tagName[6:]}' nested more than {MAX_MACRO_DEPTH} deep "
                    "(refused: a description that calls itself without end)",
                    file=x.filestack[-1] if x.filestack else self.source,
                )
            return original(node, macros, symbols)

        return handle_macro_call

    # macro calls; includes
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
                    f"more than {limit:,} {what} in one expansion (refused: a description "
                    "that multiplies itself)",
                    file=self.x.filestack[-1] if self.x.filestack else self.source,
                )
            return result

        return counted

    # xacro's own functions, as expressions call them
    def register_functions(self) -> None:
        """Each function in xacro's name spaces with its bounded version; a name space
        member this does not know (a newer xacro's) cannot be called."""
        x, bounded, budget = self.x, self.bounded, self.budget
        printing = self._printing
        kinds: dict[str, Callable[[Any], Callable[..., Any]]] = {
            "abs_filename": bounded.plain,
            "arg": bounded.plain,
            "dotify": lambda f: lambda d: budget.made(f(budget.walk(d))),
            "message": printing,
            "warning": printing,
            "error": printing,
            "print_location": printing,
            "fatal": printing,
            "tokenize": self._tokenize,
        }
        own = x._global_symbols["xacro"]
        for name, make in kinds.items():
            func = dict.get(own, name)
            if func is not None and bounded.lookup(func) is None:
                bounded.register(func, make(func))
        glob = x._global_symbols
        for table in (glob, *(glob[n] for n in NAMESPACE_ALLOWED)):
            for value in dict.values(table):
                if callable(value) and bounded.lookup(value) is None:
                    self._register_deprecated(value)

    def _register_deprecated(self, wrapper: Any) -> None:
        """xacro's ``deprecate`` wrapper (``sorted`` for ``python.sorted``): the
        warning it prints, then the bounded function it wraps."""
        if not inspect.isfunction(wrapper) or wrapper.__closure__ is None:
            return
        cells = inspect.getclosurevars(wrapper).nonlocals
        impl = self.bounded.lookup(cells.get("f"))
        message = cells.get("msg")
        if impl is None or not isinstance(message, str):
            return
        x = self.x

        def deprecated(*args: Any, **kwargs: Any) -> Any:
            x.warning(message)
            return impl(*args, **kwargs)  # type: ignore[misc]

        self.bounded.register(wrapper, deprecated)

    def _printing(self, func: Callable[..., Any]) -> Callable[..., Any]:
        """xacro.message, warning, error, fatal: what they print (or raise) is the text
        of each argument."""
        budget = self.budget

        def printing(*args: Any, **kwargs: Any) -> Any:
            size = self.bounded.text_of([*args, *kwargs.values()]) + 16 * (len(args) + 2)
            if size > MAX_TEXT:
                raise too_big(f"a message of up to {size:,} characters", f"{MAX_TEXT:,} characters")
            budget.work(text_steps(size))
            budget.hold(size)
            return func(*args, **kwargs)

        return printing

    def _tokenize(self, func: Callable[..., Any]) -> Callable[..., Any]:
        """xacro.tokenize splits with the regex ``[sep]``: a ``]`` or ``\\`` in ``sep``
        would make it another regex, one that can backtrack without end."""
        budget = self.budget

        def tokenize(s: Any, sep: Any = ",; ", skip_empty: Any = True) -> Any:
            if not isinstance(sep, str) or "]" in sep[1:] or "\\" in sep:
                raise refusal("xacro.tokenize with ']' or '\\' in its separators")
            if isinstance(s, str):
                pieces = 1 + sum(map(s.count, set(sep)))
                if pieces > MAX_ITEMS:
                    raise too_big(f"xacro.tokenize into {pieces:,} items", f"{MAX_ITEMS:,} items")
                budget.work(search_steps(len(s)) + pieces * WALK_STEPS)
            return budget.made(func(s, sep, skip_empty))

        return tokenize

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
            # our reader, as for every YAML file: no key twice, no YAML 1.1 reading
            # (a calibration's 1:30 is not 90), no alias bomb
            value, _ = schema.parse(data, _unit_loader(x))
            return self.budget.made(x.YamlListWrapper.wrap(value))
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark
            where = f" line {mark.line + 1}" if mark else ""
            raise Refused(f"YAML file {path}{where}: {exc.problem}") from None
        except yaml.YAMLError as exc:
            raise Refused(f"YAML file {path}: {untrusted.excerpt(str(exc), 200)}") from None
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
                try:
                    self.budget.work(len(data))
                    self.budget.hold(INCLUDE_BYTES * len(data))
                except Refused as exc:
                    raise self.refused(exc.reason) from None
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
    """Our YAML loader with xacro's ``!degrees``-style unit tags, on a private subclass
    (stock xacro adds them to yaml.SafeLoader for the whole process)."""

    class UnitLoader(schema.Loader):
        pass

    for unit in x.ConstructUnits:
        UnitLoader.add_constructor(unit.value.tag, unit.constructor)
    return UnitLoader


@contextmanager
def installed(roots: Callable[[], Sequence[Path]], source: Path) -> Iterator[None]:
    """Checked expressions, bounded work and memory, confined ``load_yaml``, checked
    includes, for one expansion. ``roots()`` is the folders whose YAML files
    ``load_yaml`` may read. Call it under the lock that serializes xacro; everything is
    restored on exit."""
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
        xacro.eval_all,
        xacro.eval_extension,
        xacro.replace_node,
    )

    def deprecated_load_yaml(filename: Any) -> Any:
        xacro.warning("Using load_yaml() directly is deprecated. Use xacro.load_yaml() instead.")
        return inst.load_yaml(filename)

    xacro.safe_eval = inst.safe_eval
    xacro.parse = inst.parse(saved[1])
    sa._eval = inst.eval_extension
    xacro.eval_text = inst.eval_text(saved[3])
    xacro.handle_macro_call = inst.nested(
        inst.counted(saved[4], MAX_MACRO_CALLS, "macro calls", [0])
    )
    xacro.process_include = inst.counted(saved[5], MAX_INCLUDES, "includes", [0])
    xacro.eval_all = inst.eval_all(saved[9])
    xacro.eval_extension = inst.substitution(saved[10])
    xacro.replace_node = inst.replace_node(saved[11])
    load_yaml = inst.load_yaml  # one bound method: the one registered is the one called
    dict.__setitem__(xacro_ns, "load_yaml", load_yaml)
    glob["load_yaml"] = deprecated_load_yaml
    for own in (load_yaml, deprecated_load_yaml):
        inst.bounded.register(own, own)  # charges what it reads itself
    inst.register_functions()
    try:
        yield
    finally:
        log.debug(
            "xacro expansion of %s: %d steps of work, %d bytes",
            source,
            inst.budget.steps,
            inst.budget.bytes,
        )
        xacro.safe_eval, xacro.parse, sa._eval = saved[:3]
        xacro.eval_text, xacro.handle_macro_call, xacro.process_include = saved[3:6]
        xacro.eval_all, xacro.eval_extension, xacro.replace_node = saved[9:12]
        dict.__setitem__(xacro_ns, "load_yaml", saved[6])
        glob["load_yaml"] = saved[7]
        if saved[8] is _MISSING:
            glob.pop("__builtins__", None)
        else:
            glob["__builtins__"] = saved[8]


_MISSING = object()
