"""docs/architecture.md's claims, checked against the code: which passes read the
user's files (watched through Python's audit hook during a real conversion), the mesh
formats the diagram names, and package docstrings that list their modules list them all.
"""

from __future__ import annotations

import ast
import functools
import re
import sys
from pathlib import Path

import pytest

from tests.corpus import example_robot_data_share
from urdf2mjcf import api
from urdf2mjcf.passes import (
    actuators,
    collision,
    contacts,
    emit,
    extension,
    inertia,
    meshes,
    parse,
    scene,
    sensors,
    validate,
    xacro,
)

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "architecture.md").read_text()
PASSES = (xacro, parse, meshes, collision, inertia, actuators, sensors, emit, extension)
PASSES += (contacts, scene, validate)

READERS = {"xacro", "parse", "meshes"}
"""The passes that open the user's files: the description and what it includes, the
package manifests that resolve ``package://``, each mesh file (once)."""

_watching: list[tuple[str, dict[str, set[str]], list[str]]] = []


def _hook(event: str, args: tuple) -> None:
    if event != "open" or not _watching or not args:
        return
    root, seen, current = _watching[-1]
    path = args[0]
    if isinstance(path, (str, Path)) and str(path).startswith(root):
        seen.setdefault(current[-1], set()).add(str(path))


sys.addaudithook(_hook)  # a hook cannot be removed: it does nothing unless a test watches


def test_only_the_documented_passes_read_the_users_files(tmp_path, monkeypatch):
    share = example_robot_data_share()
    source = share / "example-robot-data/robots/panda_description/urdf/panda.urdf"
    current = ["certificate"]  # outside every pass: the certificate's own reading
    for module in PASSES:
        name = module.__name__.rsplit(".", 1)[1]

        def run(*args, _f=module.run, _name=name, **kwargs):
            current.append(_name)
            try:
                return _f(*args, **kwargs)
            finally:
                current.pop()

        monkeypatch.setattr(module, "run", functools.wraps(module.run)(run))
    seen: dict[str, set[str]] = {}
    _watching.append((str(share), seen, current))
    try:
        api.convert(
            source,
            tmp_path / "out" / "robot.xml",
            package_paths=[share],
            use_environment=False,
            cache_dir=tmp_path / "cache",
        )
    finally:
        _watching.pop()
    assert set(seen) - {"certificate"} == READERS, {k: sorted(v)[:3] for k, v in seen.items()}
    assert str(source) in seen["xacro"]
    assert all(Path(p).suffix.lower() in meshes.FORMATS for p in seen["meshes"])
    # outside the passes only the certificate reads (the description and its meshes, as an
    # independent reference; figures the cache already holds are not read again)
    claim = re.search(r"Of the passes, only (.*?) read the\s+user's files", DOC, re.S)
    assert claim, "docs/architecture.md no longer says which passes read the user's files"
    assert set(re.findall(r"`(\w+)`", claim.group(1))) == READERS


def test_the_diagram_names_every_mesh_format():
    line = next(x for x in DOC.splitlines() if "passes/meshes/" in x and "MeshConfig" in x)
    named = re.search(r"load (\S+) once", line)
    assert named, line
    assert named.group(1).split("/") == [f.lstrip(".").upper() for f in meshes.FORMATS]


def _listed(doc: str) -> set[str]:
    """Modules a docstring names: ``:mod:`.name``` or a table row starting ````name````."""
    names = set(re.findall(r":mod:`\.(\w+)", doc))
    names |= set(re.findall(r"^``(\w+)``\s{2,}", doc, re.M))
    return names


PACKAGES = sorted(p.parent for p in (ROOT / "urdf2mjcf").rglob("__init__.py"))


@pytest.mark.parametrize("package", PACKAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_a_package_docstring_lists_all_its_modules_or_none(package: Path):
    doc = ast.get_docstring(ast.parse((package / "__init__.py").read_text())) or ""
    listed = _listed(doc)
    if not listed:
        return
    modules = {p.stem for p in package.glob("*.py") if p.stem not in ("__init__", "__main__")}
    modules |= {p.name for p in package.iterdir() if (p / "__init__.py").is_file()}
    assert sorted(listed - modules) == [], "the docstring names modules that do not exist"
    assert sorted(modules - listed) == [], "the docstring lists some modules, not all"
