"""Seeded builds that reuse the attached components an earlier build made
(``build.Parts``, as trials do) write the same bundle as fresh builds."""

from __future__ import annotations

import hashlib
from pathlib import Path

from urdf2mjcf.facility.build import Parts, build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[2]


def _digests(folder: Path) -> dict[str, str]:
    return {
        str(f.relative_to(folder)): hashlib.sha256(f.read_bytes()).hexdigest()
        for f in sorted(folder.rglob("*"))
        if f.is_file()
    }


def test_reused_parts_give_the_bytes_of_a_fresh_build(tmp_path):
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml", root=ROOT)
    parts = Parts()
    attached = None
    for seed in (3, 4):
        kept = build_facility(
            recipe, tmp_path / f"kept-{seed}", root=ROOT, seed=seed, components=False,
            workers=1, parts=parts,
        )  # fmt: skip
        fresh = build_facility(
            recipe, tmp_path / f"fresh-{seed}", root=ROOT, seed=seed, components=False,
            workers=1,
        )  # fmt: skip
        attached = attached or len(parts)
        assert attached > 0 and len(parts) == attached  # each built by the first build only
        assert _digests(kept.output) == _digests(fresh.output)
    assert _digests(tmp_path / "kept-3") != _digests(tmp_path / "kept-4")  # the seed moved things
