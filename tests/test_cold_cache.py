"""The one corpus robot converted from an empty decomposition cache.

Every other test runs on the pre-warmed cache (tests/warm_cache.py), so this is where
CoACD runs on a robot written by others: ABB's IRB 140 from rtb-data (three concave
links). Its conversion from an empty cache, again from the cache that filled, and
from the suite's pre-warmed cache must write the same bytes, and the cold one must
match pinocchio and pass its certificate as the corpus test asks.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests import warm_cache
from tests.corpus import check_wild, wild_collections

ROBOT = ("rtb-data", "xacro/abb_irb140_description/urdf/irb140.urdf")


def _written(out: Path) -> dict[str, bytes]:
    files = [out / "robot.xml", out / "scene.xml", *sorted((out / "assets").iterdir())]
    return {str(p.relative_to(out)): p.read_bytes() for p in files}


def test_a_robot_decomposed_from_an_empty_cache_is_written_as_from_a_warm_one(
    tmp_path, monkeypatch, _session_cache
):
    (collection,) = [c for c in wild_collections() if c.dist == ROBOT[0]]
    (urdf,) = [u for u in collection.urdfs if collection.name(u) == ROBOT[1]]

    monkeypatch.setenv("URDF2MJCF_CACHE", str(tmp_path / "empty"))
    cold = check_wild(collection, urdf, tmp_path / "cold")
    assert cold["decomposed_now"] == 3, cold
    assert cold["pos_err"] < 1e-9 and cold["gravity_rel_err"] < 1e-6
    assert cold["certificate"]["passed"], cold["certificate"]["failures"]
    again = check_wild(collection, urdf, tmp_path / "again")
    assert again["decomposed_now"] == 0, "the second conversion reads what the first stored"

    monkeypatch.setenv("URDF2MJCF_CACHE", str(_session_cache))
    warm = check_wild(collection, urdf, tmp_path / "warm")
    assert len(os.listdir(tmp_path / "cold" / "assets")) > 3
    assert _written(tmp_path / "again") == _written(tmp_path / "cold")
    assert _written(tmp_path / "warm") == _written(tmp_path / "cold")
    if not warm_cache.hits():
        pytest.skip(warm_cache.header())
    assert warm["decomposed_now"] == 0, "the pre-warmed cache holds this robot's decompositions"


def test_every_entry_of_the_archive_is_one_the_cache_reads(tmp_path):
    """The archive unpacks into entries the collision pass's cache takes (a damaged one
    would only be a miss: the suite silently slow)."""
    from urdf2mjcf.passes.collision.decompositions import DecompositionCache

    n = warm_cache.unpack(tmp_path)
    coacd = sorted((tmp_path / "coacd").glob("*.npz"))
    assert n > len(coacd) >= 100
    cache = DecompositionCache(tmp_path)
    assert all(cache.load(p.stem) for p in coacd), "an entry the cache cannot read"
    assert all(cache.load_gap(p.stem) is not None for p in (tmp_path / "hull_gap").glob("*"))
