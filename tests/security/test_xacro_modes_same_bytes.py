"""Every real xacro we know expands (and converts) to the same bytes with the
expression checks as with stock xacro (``--trust-xacro``): the facility's
descriptions with each recipe's arguments, the example-robot-data xacros and
the wild corpus. Also: every ``${...}`` and ``$(eval ...)`` written in those
corpora passes the static check.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from urdf2mjcf import api, xml_repair
from urdf2mjcf.errors import ConversionError
from urdf2mjcf.facility.build import NAMED_PACKAGES, PACKAGE_DIRS, xacro_args
from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.facility.root import data_path
from urdf2mjcf.facility.scatter import rocks_arg, scatter
from urdf2mjcf.passes import xacro, xacro_guard

ROOT = Path(__file__).resolve().parents[2]


def _corpus_roots() -> list[tuple[Path, tuple[Path, ...]]]:
    """(folder, package paths) of every collection holding xacro."""
    from tests.corpus import example_robot_data_share, wild_collections

    erd = example_robot_data_share()
    out = [(ROOT / "facility", tuple(ROOT / d for d in PACKAGE_DIRS)), (erd, (erd,))]
    out += [(c.root, c.package_paths) for c in wild_collections()]
    return out


def _xacro_sources() -> list[tuple[Path, tuple[Path, ...]]]:
    """Every ``.xacro`` file and every ``.urdf`` that xacro expands, in all corpora."""
    found = []
    for root, paths in _corpus_roots():
        for path in sorted(root.rglob("*")):
            if "random_urdfs" in path.parts or not path.is_file():
                continue
            if path.suffix == ".xacro":
                found.append((path, paths))
            elif path.suffix == ".urdf":
                data, _ = xml_repair.repair(path.read_bytes())  # as xacro.run reads it
                if b"ros.org/wiki/xacro" in data and xacro._needs_xacro(path, data, {}):
                    found.append((path, paths))
    return found


def _recipe_tops() -> list[tuple[str, Path, dict[str, str]]]:
    """Each recipe's top-level xacro with the arguments make-facility passes."""
    out = []
    for path in sorted((ROOT / "recipes").glob("*.yaml")):
        recipe = load_recipe(path, root=ROOT)
        placements = {n: p for n, p in recipe.placements.items() if recipe.enabled(n)}
        args = xacro_args(recipe, placements)
        if recipe.rocks.get("count"):
            clear_of = [p.xyz[:2] for p in placements.values()]
            args["rocks"] = rocks_arg(scatter(recipe.rocks, recipe.rocks["seed"], clear_of, path))
        out.append((path.stem, data_path(ROOT, recipe.path, recipe.xacro), args))
    return out


def _expand(source: Path, paths: tuple[Path, ...], args: dict[str, str], trust: bool):
    cfg = xacro.XacroConfig(
        args=args,
        package_paths=paths,
        packages={n: ROOT / d for n, d in NAMED_PACKAGES.items()},
        use_environment=False,
        trust=trust,
    )
    try:
        doc = xacro.run(source, cfg)
    except ConversionError as exc:
        return ("error", str(exc))
    return doc.xml, doc.warnings


def test_every_expression_in_the_corpora_passes_the_check():
    seen: dict[str, Path] = {}
    for source, _ in _xacro_sources():
        text = source.read_text(errors="replace")
        for m in re.finditer(r"\$\{([^}]*)\}|\$\(eval ([^)]*)\)", text):
            expr = m.group(1) if m.group(1) is not None else m.group(2)
            # substitutions inside are done before the check; any value stands in
            expr = re.sub(r"\$\((?:arg|env|optenv|find)[^)]*\)", "1", expr)
            expr = re.sub(r"[\n\r\t]", " ", expr)  # XML attribute value normalization
            expr = expr.replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&")
            seen.setdefault(expr, source)
    assert len(seen) > 300  # the corpora are there
    refused = {}
    for expr, source in seen.items():
        try:
            xacro_guard.check(expr)
        except xacro_guard.Refused as exc:
            refused[expr] = (source, exc.reason)
    assert not refused


@pytest.mark.slow
def test_every_corpus_xacro_expands_to_the_same_bytes_in_both_modes():
    sources = _xacro_sources()
    assert len(sources) >= 25
    expanded = 0
    for source, paths in sources:
        checked = _expand(source, paths, {}, trust=False)
        stock = _expand(source, paths, {}, trust=True)
        assert checked == stock, source
        expanded += checked[0] != "error"
    assert expanded >= 20  # not a comparison of two identical errors


@pytest.mark.slow
@pytest.mark.parametrize("recipe", [r[0] for r in _recipe_tops()])
def test_facility_recipe_expands_to_the_same_bytes_in_both_modes(recipe):
    _, top, args = next(r for r in _recipe_tops() if r[0] == recipe)
    paths = tuple(ROOT / d for d in PACKAGE_DIRS)
    checked = _expand(top, paths, args, trust=False)
    assert checked[0] != "error", checked
    assert checked == _expand(top, paths, args, trust=True)


def _convert(source: Path, out: Path, trust: bool) -> bytes:
    api.convert(
        source,
        out / "robot.xml",
        package_paths=[ROOT / d for d in PACKAGE_DIRS],
        packages={n: ROOT / d for n, d in NAMED_PACKAGES.items()},
        use_environment=False,
        validate_model=False,
        scene=False,
        trust_xacro=trust,
    )
    return (out / "robot.xml").read_bytes()


@pytest.mark.parametrize(
    "relative",
    [
        "facility/mockups/ctb/urdf/ctb.urdf.xacro",
        "facility/mockups/stowage_unit/urdf/stowage_unit.urdf.xacro",
    ],
)
def test_full_conversion_same_bytes_in_both_modes(tmp_path, relative):
    source = ROOT / relative
    assert _convert(source, tmp_path / "checked", False) == _convert(
        source, tmp_path / "stock", True
    )
