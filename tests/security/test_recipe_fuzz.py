"""Property-based fuzzing of the recipe and waypoints readers (issue 19): our real
recipes (``recipes/*.yaml``, their component table inlined) and demo files
(``recipes/demo/*.yaml``) with random values put at random keys (NaN, inf, huge
and negative numbers, text, lists, nulls, mappings, deep nesting), read from a
file as a user's would be, give a result or a ``ForgeError``, never another
exception; a ``--set`` of any text at any key likewise. A result that is accepted
holds only finite numbers. The example counts are bounded for CI."""

from __future__ import annotations

import math
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from urdf2mjcf.errors import ForgeError
from urdf2mjcf.facility.recipe import Recipe, load_recipe
from urdf2mjcf.runner.waypoints import read_waypoints

from .attack import ROOT

SETTINGS = settings(
    max_examples=120,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def _recipe_documents() -> list[dict]:
    docs = []
    for path in sorted((ROOT / "recipes").glob("*.yaml")):
        data = yaml.safe_load(path.read_text())
        if isinstance(data.get("components"), str):  # inline the table: fuzz it too
            table = ROOT / "recipes" / data["components"]
            data["components"] = yaml.safe_load(table.read_text())
        docs.append(data)
    return docs


RECIPES = _recipe_documents()
DEMOS = [yaml.safe_load(p.read_text()) for p in sorted((ROOT / "recipes" / "demo").glob("*.yaml"))]


def _paths(node: Any, prefix: tuple = ()) -> Iterator[tuple]:
    """Every key path into ``node`` (mapping keys and list indices), the root included."""
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


def _nested(depth: int) -> Any:
    value: Any = 1.0
    for _ in range(depth):
        value = [value]
    return value


SCALARS = st.one_of(
    st.sampled_from(
        [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e-300, 0, -1, -5, 10**30, -(10**30)]
    ),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**40), max_value=10**40),
    st.text(max_size=40),
    st.booleans(),
    st.none(),
)
VALUES = st.one_of(
    SCALARS,
    st.lists(SCALARS, max_size=6),
    st.dictionaries(st.text(max_size=10), SCALARS, max_size=4),
    st.integers(min_value=1, max_value=200).map(_nested),
)


@st.composite
def mutated(draw: st.DrawFn, documents: list[dict]) -> Any:
    """One of ``documents`` with 1-3 random values put at random keys (or a key added)."""
    import copy

    doc = copy.deepcopy(draw(st.sampled_from(documents)))
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(doc))
        path = draw(st.sampled_from(paths))
        value = draw(VALUES)
        if not path:
            if draw(st.booleans()):
                return value  # the whole document replaced
            continue
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        if isinstance(parent, dict) and draw(st.booleans()):
            parent[draw(st.text(min_size=1, max_size=12))] = value  # a key added
        else:
            parent[path[-1]] = value
    return doc


def _write(folder: Path, data: Any) -> Path:
    path = folder / "fuzz.yaml"
    path.write_text(yaml.safe_dump(data, allow_unicode=True, sort_keys=False))
    return path


def _numbers_finite(node: Any) -> bool:
    if isinstance(node, float):
        return math.isfinite(node)
    if isinstance(node, dict):
        return all(_numbers_finite(v) for v in node.values())
    if isinstance(node, (list, tuple)):
        return all(_numbers_finite(v) for v in node)
    return True


def _check_recipe(recipe: Recipe) -> None:
    for pose in recipe.placements.values():
        assert all(math.isfinite(v) and abs(v) <= 1e4 for v in (*pose.xyz, pose.yaw))
    assert _numbers_finite(dict(recipe.jitter)) and _numbers_finite(dict(recipe.rocks))
    assert _numbers_finite(dict(recipe.noise)) and _numbers_finite(dict(recipe.flags))
    assert recipe.rocks.get("count", 0) <= 10_000
    timestep = recipe.simulation.get("timestep")
    assert timestep is None or 1e-5 <= float(timestep) <= 0.1


@pytest.fixture(scope="module")
def folder() -> Iterator[Path]:
    with tempfile.TemporaryDirectory() as name:
        yield Path(name)


@SETTINGS
@given(data=mutated(RECIPES))
def test_a_mutated_recipe_is_a_recipe_or_one_conversion_error(folder, data):
    path = _write(folder, data)
    try:
        recipe = load_recipe(path, root=ROOT)
    except ForgeError as exc:
        assert str(exc).strip()
        return
    _check_recipe(recipe)


KEYS = sorted(
    {
        ".".join(str(k) for k in p)
        for doc in RECIPES
        for p in _paths(doc)
        if p and all(isinstance(k, str) for k in p) and p[0] != "components"
    }
)


@SETTINGS
@given(
    doc=st.sampled_from(RECIPES),
    key=st.one_of(st.sampled_from(KEYS), st.text(max_size=30)),
    text=st.one_of(
        st.sampled_from(["nan", "inf", "-inf", "1e300", "1.0e+300", "-1", "1e-300", "[1, 2]", "~"]),
        st.text(max_size=40),
    ),
)
def test_any_set_of_any_text_is_a_recipe_or_one_conversion_error(folder, doc, key, text):
    path = _write(folder, doc)
    try:
        recipe = load_recipe(path, {key: text}, root=ROOT)
    except ForgeError:
        return
    _check_recipe(recipe)


@SETTINGS
@given(data=mutated(DEMOS))
def test_a_mutated_waypoints_file_is_checked_or_one_conversion_error(folder, data):
    path = _write(folder, data)
    try:
        spec = read_waypoints(path)
    except ForgeError:
        return
    assert _numbers_finite(spec)
