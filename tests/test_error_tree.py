"""One error tree (issue 31 item 7): every error class the package raises is defined in
``urdf2mjcf/errors.py``, under one base per product (compiler, bundle, runtime), all
``ForgeError``; commands turn any of them into one ``error:`` line and exit 2.

``python tests/test_error_tree.py`` prints the tree as docs/architecture.md shows it
(between its ``error-tree`` markers)."""

from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

import click
import pytest

from urdf2mjcf import errors
from urdf2mjcf.command_runner import run_command

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "urdf2mjcf"
PRODUCTS = {
    errors.ConversionError: "the compiler",
    errors.FacilityError: "the bundle",
    errors.RunError: "the runtime",
}
SIGNALS = {errors.BadNumber, errors.YamlBombError, errors.BadCommand, errors.BadManifest}
"""Raised while a value is read and caught by its reader, which names the file."""
CONTROL_FLOW = {
    ("command_runner.py", "Terminated"),  # SIGTERM unwinding (a BaseException, as KeyboardInterrupt)
    ("isolated.py", "ChildFailed"),  # a forked child's outcome, re-raised as the caller's error
    ("isolated.py", "ChildLost"),
    ("schema.py", "Refused"),  # a YAML construct refused inside PyYAML's loader
    ("passes/xacro_budget.py", "Refused"),  # a xacro budget spent, inside xacro's evaluator
    ("passes/meshes/__init__.py", "_Unusable"),
}
"""Exceptions that never leave the module that raises them."""


def _exception_classes() -> set[tuple[str, str]]:
    """(module file, class name) of every class defined outside errors.py whose bases name
    an exception (``...Error``, ``Exception``, built-in errors)."""
    found = set()
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = str(path.relative_to(PACKAGE))
        if rel == "errors.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ClassDef):
                continue
            bases = [ast.unparse(b) for b in node.bases]
            if any(re.search(r"(Error|Exception|Exit|MarkedYAMLError)$", b) for b in bases):
                found.add((rel, node.name))
    return found


def test_every_error_class_is_defined_in_errors_py() -> None:
    assert _exception_classes() == CONTROL_FLOW


def _public_errors() -> list[type[BaseException]]:
    return [
        c
        for _, c in inspect.getmembers(errors, inspect.isclass)
        if issubclass(c, BaseException) and c.__module__ == errors.__name__
    ]


def test_every_error_is_a_forge_error_under_one_product() -> None:
    for cls in _public_errors():
        if cls in SIGNALS:
            assert issubclass(cls, ValueError) and not issubclass(cls, errors.ForgeError)
            continue
        assert issubclass(cls, errors.ForgeError), cls
        if cls is errors.ForgeError:
            continue
        products = [p for p in PRODUCTS if issubclass(cls, p)]
        assert len(products) == 1, (cls, products)
    for product in PRODUCTS:
        assert product.__bases__ == (errors.ForgeError,)


def test_the_modules_that_raised_them_still_export_them() -> None:
    """Callers that imported an error from its old module get the same class."""
    from urdf2mjcf import bundle, extras
    from urdf2mjcf.certify import CertificateFailed
    from urdf2mjcf.runner import load, steps
    from urdf2mjcf.runner.rover import console_sim, roles

    assert bundle.BundleError is errors.BundleError
    assert extras.MissingExtraError is errors.MissingExtraError
    assert CertificateFailed is errors.CertificateFailed
    assert load.LoadError is errors.LoadError and steps.StepError is errors.StepError
    assert roles.RoverError is errors.RoverError
    assert console_sim.CommandError is errors.CommandError


@pytest.mark.parametrize(
    "exc",
    [
        errors.URDFError("two roots", file="r.urdf", element="link 'a'"),
        errors.BundleError("no scene.xml", file="facility.json"),
        errors.PlanningError("start in collision", file="demo.yaml", element="steps[2]"),
        errors.StepError("nothing seen"),
        errors.PortError(98, "Address already in use"),
    ],
    ids=lambda e: type(e).__name__,
)
def test_a_command_turns_any_product_error_into_one_line_and_exit_2(
    exc: errors.ForgeError, capsys: pytest.CaptureFixture[str]
) -> None:
    @click.command("probe")
    def probe() -> None:
        raise exc

    with pytest.raises(SystemExit) as stopped:
        run_command(probe, [], prog_name="probe")
    assert stopped.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: {exc}"], err


def tree_markdown() -> str:
    """The tree as docs/architecture.md lists it."""
    lines = []

    def walk(cls: type, depth: int) -> None:
        doc = (cls.__doc__ or "").strip().split("\n\n")[0]
        first = " ".join(doc.split())
        extra = [b.__name__ for b in cls.__bases__ if b.__module__ == "builtins"]
        also = f" (also `{'`, `'.join(extra)}`)" if extra and cls is not errors.ForgeError else ""
        lines.append(f"{'  ' * depth}- `{cls.__name__}`{also}: {first}")
        for sub in sorted(cls.__subclasses__(), key=lambda c: c.__name__):
            if sub.__module__ == errors.__name__:
                walk(sub, depth + 1)

    walk(errors.ForgeError, 0)
    for cls in sorted(SIGNALS, key=lambda c: c.__name__):
        lines.append(f"- `{cls.__name__}` (a `ValueError`, internal): {cls.__doc__.strip()}")
    return "\n".join(lines)


def test_architecture_md_shows_the_tree() -> None:
    text = (ROOT / "docs" / "architecture.md").read_text()
    block = re.search(r"<!-- error-tree:begin -->\n(.*?)\n<!-- error-tree:end -->", text, re.S)
    assert block, "docs/architecture.md lacks the error-tree block"
    assert block.group(1).strip() == tree_markdown(), "run: python tests/test_error_tree.py"


if __name__ == "__main__":
    print(tree_markdown())
