"""`urdf2mjcf SOURCE --calibration calib.yaml` writes identified values into every later
conversion: the compiled model holds them, and a joint the file names but the robot no
longer has is a warning, not a failure."""

from __future__ import annotations

import mujoco
import pytest

from tests.calibrate import arm
from tests.security.attack import assert_one_error, run

CALIB = """joints:
  shoulder: {damping: 1.25, frictionloss: 0.5, armature: 0.04}
  elbow: {damping: 0.75}
  wrist: {damping: 3}
actuators:
  elbow: {kp: 400}
bodies:
  fore: {mass: 1.2}
payload: {body: fore, mass: 1.5}
"""


def test_a_reconversion_carries_the_calibrated_values(tmp_path):
    nominal = arm.convert(tmp_path / "first")
    src = nominal.parent.parent / "arm.urdf"
    (tmp_path / "calib.yaml").write_text(CALIB)
    res = run(
        "urdf2mjcf", str(src), "-o", "again/arm.xml", "--actuator-config",
        str(nominal.parent.parent / "act.yaml"), "--calibration", "calib.yaml", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "no joint 'wrist'" in res.stderr
    before = mujoco.MjModel.from_xml_path(str(nominal))
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "again" / "arm.xml"))
    shoulder, elbow = (m.joint(n).dofadr[0] for n in ("shoulder", "elbow"))
    assert (m.dof_damping[shoulder], m.dof_frictionloss[shoulder]) == (1.25, 0.5)
    assert (m.dof_armature[shoulder], m.dof_damping[elbow]) == (0.04, 0.75)
    assert m.actuator("elbow").gainprm[0] == 400 and m.actuator("elbow").biasprm[1] == -400
    assert m.actuator("shoulder").gainprm[0] == before.actuator("shoulder").gainprm[0]
    # the forearm's own mass set, and 1.5 kg more carried at its origin
    fore = m.body("fore").id
    assert m.body_subtreemass[fore] == pytest.approx(1.2 + 1.5)
    assert m.body("fore").mass[0] == pytest.approx(1.2)
    assert m.body("fore").inertia == pytest.approx(before.body("fore").inertia * 1.2)


def test_a_bad_calibration_file_is_one_error_and_writes_nothing(tmp_path):
    nominal = arm.convert(tmp_path / "first")
    (tmp_path / "calib.yaml").write_text("joints:\n  shoulder: {damping: -1}\n")
    res = run(
        "urdf2mjcf", str(nominal.parent.parent / "arm.urdf"), "-o", "again/arm.xml",
        "--calibration", "calib.yaml", cwd=tmp_path,
    )  # fmt: skip
    assert_one_error(res, "calib.yaml", "joints.shoulder.damping", ">= 0")
    assert not (tmp_path / "again").exists()
