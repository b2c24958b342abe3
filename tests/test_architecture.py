"""The layout the architecture doc promises is the layout of the package.

Two checks, both read from the source tree itself: every module of
``urdf2mjcf/`` is listed in docs/architecture.md's module table (and every
listed module exists), and imports point one way:
support modules -> passes -> api (and the certificate) -> facility -> runner -> envs -> cli.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "urdf2mjcf"
DOC = ROOT / "docs" / "architecture.md"

# Layers, lowest first; a module may import its own layer and the ones below.
LAYERS = ("support", "passes", "api", "facility", "runner", "envs", "cli")


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
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
    if head in ("api", "report"):
        return "api"
    if head == "certify":  # the certificate runs after the passes, beside api; verify is a command
        return "cli" if parts[-1] == "command" else "api"
    if head in ("cli", "__main__", "batch"):  # batch: a command over api and executors
        return "cli"
    return "support"


def _imports(module: str, path: Path) -> set[str]:
    """Modules of the package that ``module`` imports (relative imports resolved)."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "urdf2mjcf":
                continue
            # `from . import x` imports module x; `from .m import name` imports module m
            found.update(f"{target}.{a.name}" if not node.module else target for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split(".")[0] == "urdf2mjcf")
    return found


def test_every_module_is_in_the_architecture_doc_and_every_listed_one_exists():
    listed = set(re.findall(r"^\| `(urdf2mjcf/[\w/]+\.py)` \|", DOC.read_text(), re.M))
    actual = {str(p.relative_to(ROOT)) for p in _modules().values()}
    assert listed, "docs/architecture.md has no module table"
    assert sorted(actual - listed) == [], "modules missing from docs/architecture.md"
    assert sorted(listed - actual) == [], "docs/architecture.md lists modules that do not exist"


@pytest.mark.parametrize("module", sorted(_modules()))
def test_imports_point_one_way(module):
    path = _modules()[module]
    mine = LAYERS.index(_layer(module))
    upward = sorted(t for t in _imports(module, path) if LAYERS.index(_layer(t)) > mine)
    assert upward == [], f"{module} ({LAYERS[mine]}) imports from a higher layer: {upward}"


def test_the_layering_check_catches_an_upward_import(tmp_path):
    # The check itself must be able to fail: a pass importing the api is upward.
    fake = tmp_path / "urdf2mjcf" / "passes" / "bad.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("from ..api import convert\n")
    targets = _imports("urdf2mjcf.passes.bad", fake)
    assert targets == {"urdf2mjcf.api"}
    assert LAYERS.index(_layer("urdf2mjcf.api")) > LAYERS.index(_layer("urdf2mjcf.passes.bad"))


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
