"""Small URDFs written for the tests convert to MJCF that matches stored
golden files after canonical normalisation. Regenerate only with
``pytest tests/test_golden.py --update-golden`` and review the diff."""

from __future__ import annotations

from pathlib import Path

import pytest

import urdf2mjcf
from tests.golden import canonical

INPUTS = Path(__file__).parent / "data" / "golden"
GOLDEN = Path(__file__).parent / "golden"
CASES = sorted(p.stem for p in INPUTS.glob("*.urdf"))


@pytest.mark.parametrize("case", CASES)
def test_conversion_matches_golden_file(case, tmp_path, update_golden):
    out = tmp_path / f"{case}.xml"
    urdf2mjcf.convert(INPUTS / f"{case}.urdf", out, use_environment=False)
    got = canonical(out.read_bytes())
    golden = GOLDEN / f"{case}.xml"
    if update_golden:
        golden.write_text(got)
        pytest.skip(f"rewrote {golden.name}")
    assert golden.is_file(), f"no golden file {golden}; run pytest --update-golden and review it"
    assert got == golden.read_text(), f"{case}: output differs from {golden} (see diff above)"


def test_canonical_form_ignores_float_noise_but_not_changes():
    a = b'<mujoco><body pos="0.1 0.30000000000000004 0"/></mujoco>'
    b = b'<mujoco><body pos="0.1 0.3 0"/></mujoco>'
    c = b'<mujoco><body pos="0.1 0.31 0"/></mujoco>'
    assert canonical(a) == canonical(b) != canonical(c)
