"""Every URDF of example-robot-data (robots written by others) converts, and
kinematics and gravity torques agree with pinocchio, and each passes its own
certificate.

MuJoCo's own URDF import loads 42 of these 69 files, and only after paths are
rewritten by hand; we need nothing but --package-path. Link frames are
compared at random joint configurations (1e-9), gravity torques relative to
the largest (1e-6). Where we repaired or estimated an inertial, pinocchio
reads the URDF with our inertial in its place, so the dynamics of every robot
are checked; docs/corpus.md lists those changes (bench/corpus_report.py).
"""

from __future__ import annotations

import pytest

from tests.corpus import check_robot, example_robot_data_urdfs, urdfdom_error
from urdf2mjcf.errors import ConversionError

pytestmark = pytest.mark.slow

URDFS = example_robot_data_urdfs()


def test_corpus_has_all_69_urdfs():
    assert len(URDFS) == 69


@pytest.mark.parametrize("urdf", URDFS, ids=[p.stem for p in URDFS])
def test_robot_converts_and_matches_pinocchio(urdf, tmp_path):
    if urdfdom_error(urdf) is not None:  # ur3.urdf: no name, no link: not a robot
        with pytest.raises(ConversionError, match="has no <link>") as refused:
            check_robot(urdf, tmp_path)
        assert refused.value.file and not (tmp_path / "robot.xml").exists()
        return
    result = check_robot(urdf, tmp_path)
    assert (tmp_path / "robot.xml").is_file() and (tmp_path / "scene.xml").is_file()
    assert result["bodies"] == result["links"] - (
        1 if result["links"] and _has_world_root(urdf) else 0
    )
    assert result["pos_err"] < 1e-9
    assert result["rot_err"] < 1e-9
    assert result["gravity_rel_err"] < 1e-6
    cert = result["certificate"]  # docs/corpus.md's table: every one passes its own
    assert cert["computed"], cert["why"]
    assert cert["reference"].startswith("urdfdom "), cert  # urdfdom reads the file
    assert cert["passed"], cert["failures"]


def _has_world_root(urdf) -> bool:
    """A root link named 'world' is MuJoCo's own world body, not a new body."""
    from lxml import etree

    root = etree.parse(str(urdf)).getroot()
    children = {j.find("child").get("link") for j in root.findall("joint")}
    return any(
        link.get("name") == "world" and link.get("name") not in children
        for link in root.findall("link")
    )
