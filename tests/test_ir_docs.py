"""Every field of the typed IR documents what it is, its shape and unit.

The convention (docs/architecture.md): each annotated field of a ``@dataclass``
in ``urdf2mjcf/ir.py`` is immediately followed by a string-literal docstring.
Read from the source with :mod:`ast`; ``ClassVar`` annotations are not fields.
"""

from __future__ import annotations

import ast
from pathlib import Path

IR = Path(__file__).resolve().parents[1] / "urdf2mjcf" / "ir.py"


def _is_dataclass(node: ast.ClassDef) -> bool:
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        if isinstance(target, ast.Name) and target.id == "dataclass":
            return True
        if isinstance(target, ast.Attribute) and target.attr == "dataclass":
            return True
    return False


def _is_classvar(annotation: ast.expr) -> bool:
    if isinstance(annotation, ast.Constant) and isinstance(annotation.value, str):
        return "ClassVar" in annotation.value
    if isinstance(annotation, ast.Subscript):
        annotation = annotation.value
    if isinstance(annotation, ast.Name):
        return annotation.id == "ClassVar"
    if isinstance(annotation, ast.Attribute):
        return annotation.attr == "ClassVar"
    return False


def _is_docstring(node: ast.stmt) -> bool:
    return (
        isinstance(node, ast.Expr)
        and isinstance(node.value, ast.Constant)
        and isinstance(node.value.value, str)
    )


def undocumented_fields(source: str) -> list[str]:
    """``Class.field`` for every dataclass field not followed by a docstring."""
    missing = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.ClassDef) or not _is_dataclass(node):
            continue
        body = node.body
        for i, stmt in enumerate(body):
            if not isinstance(stmt, ast.AnnAssign) or not isinstance(stmt.target, ast.Name):
                continue
            if _is_classvar(stmt.annotation):
                continue
            if i + 1 >= len(body) or not _is_docstring(body[i + 1]):
                missing.append(f"{node.name}.{stmt.target.id} (line {stmt.lineno})")
    return missing


def test_every_ir_field_has_a_docstring() -> None:
    missing = undocumented_fields(IR.read_text(encoding="utf-8"))
    assert not missing, f"{len(missing)} IR field(s) lack a docstring: " + ", ".join(missing)


def test_the_check_reports_an_undocumented_field() -> None:
    source = '''
from dataclasses import dataclass
from typing import ClassVar

@dataclass(frozen=True)
class Example:
    """A class docstring is not a field docstring."""

    documented: float
    """Metres."""
    bare: float
    also_bare: int = 0
    counter: ClassVar[int] = 0

class NotADataclass:
    ignored: float
'''
    assert undocumented_fields(source) == [
        "Example.bare (line 11)",
        "Example.also_bare (line 12)",
    ]
