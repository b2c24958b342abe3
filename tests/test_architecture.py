"""The layout the architecture doc promises is the layout of the package.

Three checks, all read from the source tree itself: every module of
``urdf2mjcf/`` is listed in docs/architecture.md's module table (and every
listed module exists); imports point one way between layers:
support modules -> passes -> api (and the certificate) -> facility -> runner -> envs -> cli;
and no module imports, directly or through others, one that imports it back (no
circle, in a layer either). Every import counts: at module level, inside a function,
under ``if TYPE_CHECKING:``.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "urdf2mjcf"
DOC = ROOT / "docs" / "architecture.md"

# Layers, lowest first; a module may import its own layer and the ones below.
LAYERS = ("support", "passes", "api", "facility", "runner", "envs", "cli")


def _modules(package: Path = PACKAGE) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    out = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) == 1:
        return "support"  # the package's own __init__: lazy re-exports only
    head = parts[1]
    if head in ("passes", "facility", "runner", "envs"):  # envs: Gymnasium over facility, runner
        return head
    if head == "ros2":  # the ROS 2 server: runs what runner/ loads; serve is a command
        return "cli" if parts[-1] == "command" else "runner"
    if head in ("api", "report", "options"):  # options: the converter's, made into configs
        return "api"
    if head == "certify":  # the certificate runs after the passes, beside api; verify is a command
        return "cli" if parts[-1] == "command" else "api"
    if head == "calibrate":  # a library beside api (the converter applies its file); a command
        return "cli" if parts[-1] == "command" else "api"
    if head in ("cli", "cli_common", "__main__", "batch"):  # batch: a command over api, executors
        return "cli"
    return "support"


def _from_target(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The module ``from X import ...`` in ``module`` (file ``path``) names, relative
    imports resolved."""
    if not node.level:
        return node.module or ""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _plant(package: Path, files: dict[str, str]) -> dict[str, Path]:
    """A fake package of ``files`` (path -> text) under ``package``; its modules."""
    for name, text in files.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text)
    return _modules(package)


def _imports(module: str, path: Path, modules: Iterable[str] = ()) -> set[str]:
    """Modules of the package that ``module`` imports (relative imports resolved), anywhere
    in its file. With ``modules`` (every module of the package), ``from p import name``
    is module ``p.name`` when there is one, else ``p``, whose ``__init__`` defines name."""
    known = set(modules)
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            target = _from_target(module, path, node)
            if target.split(".")[0] != "urdf2mjcf":
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                if known:
                    found.add(sub if sub in known else target)
                else:  # `from . import x` imports module x; `from .m import name`, module m
                    found.add(target if node.module else sub)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split(".")[0] == "urdf2mjcf")
    return found


def _graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the modules of the package it imports."""
    return {m: _imports(m, path, modules) & (set(modules) - {m}) for m, path in modules.items()}


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One import circle ``[a, b, ..., a]`` (each imports the next) for every group of
    modules that import each other (a strongly connected component, Tarjan's algorithm),
    the shortest through the group's first module by name."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[set[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = set()
            while True:
                w = stack.pop()
                group.add(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(group)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    circles = []
    for group in groups:
        start = min(group)
        came_from: dict[str, str] = {}
        queue = [start]
        while queue and start not in came_from:
            v = queue.pop(0)
            for w in sorted(graph[v] & group):
                if w not in came_from:
                    came_from[w] = v
                    queue.append(w)
        path = [start]
        while path[-1] != start or len(path) == 1:
            path.append(came_from[path[-1]])
        circles.append(path[::-1])
    return sorted(circles)


def test_every_module_is_in_the_architecture_doc_and_every_listed_one_exists():
    listed = set(re.findall(r"^\| `(urdf2mjcf/[\w/]+\.py)` \|", DOC.read_text(), re.M))
    actual = {str(p.relative_to(ROOT)) for p in _modules().values()}
    assert listed, "docs/architecture.md has no module table"
    assert sorted(actual - listed) == [], "modules missing from docs/architecture.md"
    assert sorted(listed - actual) == [], "docs/architecture.md lists modules that do not exist"


@pytest.mark.parametrize("module", sorted(_modules()))
def test_imports_point_one_way(module):
    modules = _modules()
    mine = LAYERS.index(_layer(module))
    found = _imports(module, modules[module], modules)
    upward = sorted(t for t in found if LAYERS.index(_layer(t)) > mine)
    assert upward == [], f"{module} ({LAYERS[mine]}) imports from a higher layer: {upward}"


def test_the_layering_check_catches_an_upward_import(tmp_path):
    # The check itself must be able to fail: a pass importing the api is upward.
    fake = tmp_path / "urdf2mjcf" / "passes" / "bad.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("from ..api import convert\n")
    targets = _imports("urdf2mjcf.passes.bad", fake)
    assert targets == {"urdf2mjcf.api"}
    assert LAYERS.index(_layer("urdf2mjcf.api")) > LAYERS.index(_layer("urdf2mjcf.passes.bad"))


def test_no_module_imports_one_that_imports_it_back():
    circles = _circles(_graph(_modules()))
    assert circles == [], "import circles (each module imports the next):\n" + "\n".join(
        " -> ".join(c) for c in circles
    )


def test_the_circle_check_catches_a_planted_circle(tmp_path):
    # Two circles the check must find: one through an import inside a function, one in
    # a layer through `from . import name` and a TYPE_CHECKING import. A module that
    # only imports a circle's module is in none.
    package = tmp_path / "urdf2mjcf"
    files = {
        "__init__.py": "",
        "errors.py": "class ConversionError(Exception):\n    pass\n",
        "ir.py": "from .errors import ConversionError\nfrom .fmt import f\n",
        "fmt.py": "def f():\n    from .ir import Model\n",
        "api.py": "from .ir import Model\n",
        "runner/__init__.py": "",
        "runner/a.py": "from . import b\n",
        "runner/b.py": (
            "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from .c import Thing\n"
        ),
        "runner/c.py": "from ..runner import a\n\nThing = int\n",
        "runner/d.py": "from .a import x\n",
    }
    modules = _plant(package, files)
    in_layer = ["urdf2mjcf.runner.a", "urdf2mjcf.runner.b", "urdf2mjcf.runner.c"]
    assert _circles(_graph(modules)) == [
        ["urdf2mjcf.fmt", "urdf2mjcf.ir", "urdf2mjcf.fmt"],
        [*in_layer, "urdf2mjcf.runner.a"],
    ]
    (package / "fmt.py").write_text("def f():\n    pass\n")  # the fix: that circle is gone
    assert _circles(_graph(_modules(package))) == [[*in_layer, "urdf2mjcf.runner.a"]]


def test_the_generic_facility_builder_names_none_of_our_components():
    """The builder knows components only from the recipe's component table: a user's own
    facility needs no change to urdf2mjcf/facility/ (issue 10's check, as a test)."""
    ours = re.compile(r"ctb|trainer|imetro|hatch", re.IGNORECASE)
    hits = [
        f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
        for path in sorted((ROOT / "urdf2mjcf" / "facility").glob("*.py"))
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if ours.search(line)
    ]
    assert hits == []


def _pass_order() -> list[str]:
    """The passes in the order ``api.build`` runs them (its ``<pass>.run(...)`` calls)."""
    tree = ast.parse((PACKAGE / "api.py").read_text())
    (build,) = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "_build"]
    order = []
    for node in ast.walk(build):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "run"
            and isinstance(node.func.value, ast.Name)
        ):
            order.append((node.lineno, node.func.value.id))
    return [name for _, name in sorted(order)]


def test_the_docs_number_the_passes_in_the_order_they_run():
    order = _pass_order()
    assert order[:2] == ["xacro", "parse"] and order[-2:] == ["extension", "contacts"]
    text = DOC.read_text()
    numbered = re.findall(
        r"^\| `urdf2mjcf/passes/(\w+)(?:/__init__)?\.py` \| pass (\d+):", text, re.M
    )
    assert [name for name, _ in sorted(numbered, key=lambda x: int(x[1]))] == order
    assert sorted(int(n) for _, n in numbered) == list(range(1, len(order) + 1))
    drawn = re.findall(r"│  passes/(\w+)(?:/|\.py)", text)  # the diagram, top to bottom
    assert drawn[: len(order)] == order
    # nowhere else a number: the module docstrings name their pass
    for path in (PACKAGE / "passes").rglob("*.py"):
        assert not re.match(r'"""Pass \d', path.read_text()), path


# Trials rebuild jittered facilities: they sit above the builder and the runtime both.
ABOVE_BOTH = {"urdf2mjcf.runner.trials"}


@pytest.mark.parametrize(
    "module",
    sorted(m for m in _modules() if m.startswith("urdf2mjcf.runner") and m not in ABOVE_BOTH),
)
def test_the_runtime_reads_bundles_not_the_builder(module):
    """The runtime replays a bundle: it imports neither the facility builder nor the
    compiler's passes (their shared limits live in urdf2mjcf.limits)."""
    modules = _modules()
    found = _imports(module, modules[module], modules)
    builder = sorted(t for t in found if t.startswith(("urdf2mjcf.facility", "urdf2mjcf.passes")))
    assert builder == [], f"{module} imports the builder: {builder}"


def _pass_of(module: str) -> str | None:
    """The pass a module belongs to (``urdf2mjcf.passes.<name>``), None outside passes/."""
    parts = module.split(".")
    return ".".join(parts[:3]) if len(parts) >= 3 and parts[1] == "passes" else None


def _runs(module: str, path: Path, modules: dict[str, Path]) -> list[str]:
    """Other passes whose ``run`` ``module`` calls: ``from <pass> import run``, or
    ``<alias>.run`` where ``alias`` is a module of another pass."""
    mine = _pass_of(module)
    aliases: dict[str, str] = {}
    found = []
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        target = _from_target(module, path, node)
        for a in node.names:
            sub = f"{target}.{a.name}"
            other = _pass_of(sub if sub in modules else target)
            if other is None or other == mine:
                continue
            if sub in modules:
                aliases[a.asname or a.name] = sub
            elif a.name == "run":
                found.append(target)
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and node.attr == "run"
            and isinstance(node.value, ast.Name)
            and node.value.id in aliases
        ):
            found.append(aliases[node.value.id])
    return sorted(set(found))


@pytest.mark.parametrize("module", sorted(m for m in _modules() if _pass_of(m)))
def test_no_pass_runs_another(module):
    """A pass may read another pass's declarations (the actuator file's reader, a
    constant) but runs none: the pipeline (``api._build``) runs the passes in order and
    hands a pass what it needs of another (the actuators pass gets emit's document as a
    function)."""
    modules = _modules()
    assert _runs(module, modules[module], modules) == []


def test_the_no_pass_runs_another_check_catches_one(tmp_path):
    package = tmp_path / "urdf2mjcf"
    files = {
        "__init__.py": "",
        "passes/__init__.py": "",
        "passes/emit.py": "def run(m):\n    return m\n",
        "passes/a/__init__.py": "from .. import emit\n\n\ndef run(m):\n    return emit.run(m)\n",
        "passes/b.py": "from .emit import run as emit_run\n",
        "passes/c.py": "from . import emit\n\nX = emit.WORLD\n",
    }
    modules = _plant(package, files)
    assert _runs("urdf2mjcf.passes.a", modules["urdf2mjcf.passes.a"], modules) == [
        "urdf2mjcf.passes.emit"
    ]
    assert _runs("urdf2mjcf.passes.b", modules["urdf2mjcf.passes.b"], modules) == [
        "urdf2mjcf.passes.emit"
    ]
    assert _runs("urdf2mjcf.passes.c", modules["urdf2mjcf.passes.c"], modules) == []


def test_no_module_imports_a_private_name_of_another():
    """What a module shares it names without ``_``: a private name imported across
    modules (a lock, a helper) is a contract nobody declared."""
    found = []
    for module, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (
                node.level or "urdf2mjcf" in (node.module or "")
            ):
                found += [
                    f"{module}: {node.module or '.'}.{a.name}"
                    for a in node.names
                    if a.name.startswith("_") and not a.name.startswith("__")
                ]
    assert found == [], "\n".join(found)


def test_the_five_common_changes_name_files_that_hold_what_they_say():
    """docs/architecture.md's table of the changes made most: each file exists and holds
    each registry or function the row names (in backquotes)."""
    text = DOC.read_text()
    block = text[text.index("<!-- newcomer:begin -->") : text.index("<!-- newcomer:end -->")]
    rows = [r for r in block.splitlines() if r.startswith("| a ")]
    assert len(rows) == 6
    for row in rows:
        _, change, files, what, _ = row.split("|")
        paths = [ROOT / f for f in re.findall(r"`([\w/]+\.py)`", files)]
        assert paths, change
        sources = "\n".join(path.read_text() for path in paths)
        for name in re.findall(r"`([A-Za-z_][\w]*)\*?`", what):
            if name in ("check_",):
                continue
            assert re.search(rf"\b{re.escape(name)}\b", sources), f"{change}: {name}"
