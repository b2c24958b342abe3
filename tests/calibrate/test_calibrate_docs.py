"""docs/calibrate.md states what the code does: the kinds --free takes and its default, the
files written, and its YAML examples are files the code reads."""

from __future__ import annotations

import re
from pathlib import Path

import mujoco

from tests.calibrate import arm
from urdf2mjcf.calibrate import apply, params
from urdf2mjcf.calibrate.command import calibrate_command

DOC = Path(__file__).resolve().parents[2] / "docs" / "calibrate.md"


def test_the_kinds_and_the_default_are_the_code_s():
    text = DOC.read_text()
    (kinds, default) = re.findall(
        r"`--free` takes any of `([\w,]+)`.*?\(default: `([\w,]+)`\)", text, re.S
    )[0]
    assert kinds.split(",") == list(params.KINDS)
    assert default.split(",") == list(params.DEFAULT_FREE)
    assert [
        row for row in re.findall(r"^\| `(\w+)` \|", text, re.M) if row in params.KINDS
    ] == list(params.KINDS)
    free = next(p for p in calibrate_command.params if p.name == "free")
    assert free.default == ",".join(params.DEFAULT_FREE)


def test_the_files_listed_are_the_files_written():
    from urdf2mjcf.calibrate.run import OUTPUT_FILES

    listed = re.findall(r"^\s*\| `([\w.]+)` \| ", DOC.read_text(), re.M)
    assert sorted(f for f in listed if "." in f) == sorted(OUTPUT_FILES)


def test_the_params_example_is_read_by_the_code(tmp_path):
    blocks = re.findall(r"```yaml\n(.*?)```", DOC.read_text(), re.S)
    (example,) = [b for b in blocks if "payload" in b]
    path = tmp_path / "params.yaml"
    path.write_text(example)
    m = mujoco.MjModel.from_xml_path(str(arm.convert(tmp_path / "arm")))
    chosen = {
        (p.target, p.field): (p.lo, p.hi) for p in params.select(m, params.DEFAULT_FREE, path)
    }
    assert chosen[("elbow", "damping")] == (0.0, 5.0)
    assert ("elbow", "frictionloss") not in chosen
    assert chosen[("shoulder", "kp")] == (1000.0, 8000.0)
    assert ("fore", "mass") in chosen and chosen[("fore", "payload")] == (0.0, 3.0)
    assert chosen[("", "delay")] == (0.0, 0.02)


def test_the_calibration_file_s_schema_is_read_by_the_code(tmp_path):
    (example,) = re.findall(r"::\n\n((?:    .*\n)+)", Path(apply.__file__).read_text())
    path = tmp_path / "calibration.yaml"
    path.write_text("\n".join(line[4:] for line in example.splitlines()) + "\n")
    calib = apply.load(path)
    assert calib.joints["elbow"] == {"damping": 0.9, "frictionloss": 0.4, "armature": 0.02}
    assert calib.payload == ("fore", 1.5) and calib.delay == 0.005


def test_the_against_tolerances_stated_are_the_defaults():
    from urdf2mjcf.calibrate.against import AgainstTolerances

    text = " ".join((DOC.parent / "cli.md").read_text().split())
    assert f"`--q-rms` (default {AgainstTolerances.q_rms:g} rad or m)" in text
    assert f"`--v-rms` (default {AgainstTolerances.v_rms:g} rad/s or m/s)" in text


SERVO = """<mujoco><option integrator="{}"/><worldbody><body>
  <joint name="j" axis="0 1 0" damping="1"/>
  <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.02" mass="1"/></body></worldbody>
  <actuator><position joint="j" kp="1000" kv="60" forcerange="-40 40"/></actuator></mujoco>"""


def _one_step(integrator: str, kp: float) -> float:
    m = mujoco.MjModel.from_xml_string(SERVO.format(integrator))
    m.actuator_gainprm[0, 0], m.actuator_biasprm[0, 1] = kp, -kp
    d = mujoco.MjData(m)
    d.ctrl[0] = 0.04
    mujoco.mj_step(m, d)
    return float(d.qvel[0])


def test_the_servo_step_the_docs_give_is_mujoco_s():
    """The docs' reason for the fit's local minima: under implicitfast a servo's velocity
    gain damps a step only while its force is inside its range, so one step's velocity
    jumps where the force meets the limit (under Euler it does not)."""
    text = " ".join(DOC.read_text().split())
    assert "0.51 rad/s after one step at kp 975, 2.39 at kp 1000; with `Euler` 2.33 and 2.39" in text
    assert round(_one_step("implicitfast", 975.0), 2) == 0.51
    assert round(_one_step("implicitfast", 1000.0), 2) == 2.39
    assert round(_one_step("Euler", 975.0), 2) == 2.33
    assert round(_one_step("Euler", 1000.0), 2) == 2.39


def test_the_warning_thresholds_are_the_code_s():
    from urdf2mjcf.calibrate import report

    text = " ".join(DOC.read_text().split())
    assert report.WIDE == 0.25 and "an interval wider than a quarter of the value" in text
    assert f"and than {report.FLOOR * 100:g} % of its bounds' span" in text
    assert f"correlated beyond {report.CORRELATED:g}" in text
    from urdf2mjcf.calibrate import fit

    assert f"at its force range in more than {fit.LIMITED * 100:g} % of the fitted" in text


def test_the_cut_at_a_force_limit_the_docs_give_is_the_code_s():
    from urdf2mjcf.calibrate import fit

    text = " ".join(DOC.read_text().split())
    assert f"within {fit.NEAR_LIMIT * 100:g} % of its range's half-span of a limit" in text
    assert f"windows shorter than {fit.MIN_WINDOW} steps are left out" in text
    assert f"at most {'twice' if fit.PADDED == 2 else fit.PADDED} the steps fitted" in text
