"""What a conversion writes is what it validated: the files on disk, compiled again
by MuJoCo from their paths, give the model validation stepped, bit for bit.

Validation compiles the staged files from memory (the same bytes) before they are
moved into place; a pass that rewrote a file after validation, or a difference
between compiling from memory and from disk, shows here. The facility's scenes are
checked the same way in tests/facility (test_facility.py, test_mira3d.py)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

import urdf2mjcf
from tests.corpus import example_robot_data_share, example_robot_data_urdfs
from tests.same_model import differences

DATA = Path(__file__).parent / "data"
# Robots of several kinds: a floating humanoid with meshes, an arm with a gripper,
# a quadruped, and our own servo-driven arm with sensors and a <mujoco> extension.
ROBOTS = ("talos_full_v2", "panda", "solo12")


def _cases() -> list[Path]:
    urdfs = {u.stem: u for u in example_robot_data_urdfs()}
    return [urdfs[name] for name in ROBOTS] + [DATA / "sim_robot" / "urdf" / "sim_arm.urdf.xacro"]


@pytest.mark.parametrize("source", _cases(), ids=lambda p: p.name)
@pytest.mark.parametrize("scene", [True, False], ids=["scene", "robot-only"])
def test_the_written_files_are_the_validated_model(tmp_path, source, scene):
    report = urdf2mjcf.convert(
        source,
        tmp_path / "robot.xml",
        package_paths=[example_robot_data_share()],
        use_environment=False,
        gravcomp=True,
        scene=scene,
        certify=False,
    )
    assert report.compiled is not None
    written = mujoco.MjModel.from_xml_path(str(tmp_path / ("scene.xml" if scene else "robot.xml")))
    assert differences(written, report.compiled) == []
    # the comparison sees a change of one number
    written.body_mass[-1] += 1e-12
    assert differences(written, report.compiled) == ["body_mass"]
