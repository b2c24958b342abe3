"""Every URDF of example-robot-data (robots written by others) converts, and
kinematics and gravity torques agree with pinocchio.

MuJoCo's own URDF import loads 42 of these 69 files, and only after paths are
rewritten by hand; we need nothing but --package-path.
"""

from __future__ import annotations

import json

import pytest

import urdf2mjcf
from tests.corpus import (
    compare_with_pinocchio,
    example_robot_data_share,
    example_robot_data_urdfs,
    patched_urdf,
)

pytestmark = pytest.mark.slow

URDFS = example_robot_data_urdfs()


def test_corpus_has_all_69_urdfs():
    assert len(URDFS) == 69


@pytest.mark.parametrize("urdf", URDFS, ids=[p.stem for p in URDFS])
def test_robot_converts_and_matches_pinocchio(urdf, tmp_path):
    out = tmp_path / "robot.xml"
    report = urdf2mjcf.convert(
        urdf, out, package_paths=[example_robot_data_share()], use_environment=False
    )
    assert out.is_file() and (tmp_path / "scene.xml").is_file()
    model = report.model
    if not model.robot.links:
        pytest.skip("empty robot description (no links): converted to an empty model")
    mimics = {
        j.name: (j.mimic.joint, j.mimic.multiplier, j.mimic.offset)
        for j in model.robot.joints
        if j.mimic
    }
    reference = patched_urdf(urdf, model, tmp_path / "reference.urdf")
    cmp = compare_with_pinocchio(reference, out, mimics)
    changed = {n.element: n.message for n in report.notes if n.kind in ("repaired", "estimated")}
    print(
        json.dumps(
            {
                "robot": urdf.stem,
                "frames": cmp.frames,
                "dofs": cmp.dofs,
                "changed_inertials": changed,
            }
        )
    )
    assert cmp.max_frame_pos_err < 1e-9
    assert cmp.max_frame_rot_err < 1e-9
    assert cmp.max_gravity_rel_err < 1e-6
