"""`urdf2mjcf calibrate` recovers known parameters: a converted arm whose copy has its
damping tripled, friction and armature added and its servo gains 30 % off is simulated with
sensor noise; calibrating the nominal model from that log finds each value within 10 %,
and the held-out tracking error falls at least five times."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from lxml import etree

from tests.calibrate import arm
from tests.security.attack import run
from urdf2mjcf.calibrate.run import OUTPUT_FILES

TRUTH = {
    "shoulder": {"damping": 1.5, "frictionloss": 0.8, "armature": 0.05},
    "elbow": {"damping": 0.9, "frictionloss": 0.4, "armature": 0.02},
}
KP = {"shoulder": arm.NOMINAL_KP["shoulder"] * 1.3, "elbow": arm.NOMINAL_KP["elbow"] * 0.7}


@pytest.fixture(scope="module")
def nominal(tmp_path_factory) -> Path:
    return arm.convert(tmp_path_factory.mktemp("arm"))


def _params(report: dict) -> dict[str, dict]:
    return {p["name"]: p for p in report["parameters"]}


def _truth_of(name: str, truth: dict, kp: dict) -> float:
    target, field = name.split(".")
    return kp[target] if field == "kp" else truth[target][field]


def test_damping_friction_armature_and_gains_are_recovered(nominal, tmp_path):
    real = arm.perturbed(nominal, tmp_path / "real.xml", TRUTH, KP)
    log = arm.record(real, tmp_path / "log.csv", amplitude=0.5)
    free = "damping,frictionloss,armature,gains"
    res = run(
        "urdf2mjcf", "calibrate", str(nominal), str(log), "-o", "cal", "--free", free, cwd=tmp_path
    )
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in (tmp_path / "cal").iterdir()) == sorted(OUTPUT_FILES)
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    assert sorted(report["files"]) == sorted(OUTPUT_FILES)
    found = _params(report)
    assert len(found) == 8
    for name, p in found.items():
        truth = _truth_of(name, TRUTH, KP)
        assert abs(p["after"] - truth) <= 0.1 * truth, (name, p, truth)
    assert report["held_out_improvement"] >= 5.0
    for joint in arm.JOINTS:
        held = report["tracking"]["held_out"]
        assert held["after"][joint]["q_rms"] * 5 <= held["before"][joint]["q_rms"], joint
    # the calibrated model holds the same values, compiled by MuJoCo from OUT/robot.xml
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "cal" / "robot.xml"))
    calib = yaml.safe_load((tmp_path / "cal" / "calibration.yaml").read_text())
    for j, name in enumerate(arm.JOINTS):
        assert m.dof_damping[j] == pytest.approx(calib["joints"][name]["damping"])
        assert m.dof_frictionloss[j] == pytest.approx(calib["joints"][name]["frictionloss"])
        assert m.dof_armature[j] == pytest.approx(calib["joints"][name]["armature"])
        assert m.actuator_gainprm[j, 0] == pytest.approx(calib["actuators"][name]["kp"])
        assert m.actuator_biasprm[j, 1] == pytest.approx(-calib["actuators"][name]["kp"])
    assert "report" in (tmp_path / "cal" / "report.html").read_text()


def _late(log: Path, seconds: float, joints: int) -> None:
    """Rewrite ``log`` as a sensor ``seconds`` late would have measured it: each row's
    positions and velocities are those of ``seconds`` earlier (linearly interpolated between
    rows); the commands keep their times."""
    header, *rows = log.read_text().splitlines()
    table = np.array([[float(x) for x in r.split(",")] for r in rows])
    t, measured = table[:, 0], table[:, 1 : 1 + 2 * joints]
    earlier = np.column_stack(
        [np.interp(t - seconds, t, measured[:, c]) for c in range(2 * joints)]
    )
    table[:, 1 : 1 + 2 * joints] = earlier
    text = [header] + [",".join(f"{x:.9g}" for x in row) for row in table]
    log.write_text("\n".join(text) + "\n")


DELAY = 0.006
"""s: three of the log's 2 ms samples (a delay between two samples is read by linear
interpolation, which this log's own making would then add to: docs/calibrate.md)."""


def test_every_kind_at_once_is_recovered(nominal, tmp_path):
    """The issue's whole list in one robot: damping x3, friction and armature added, gains
    30 % off, 1.5 kg at the tool and a 6 ms sensor delay, everything freed at once."""
    real = arm.perturbed(nominal, tmp_path / "real.xml", TRUTH, KP)
    tree = etree.parse(str(real))
    (fore,) = tree.xpath("//body[@name='fore']")
    load = etree.SubElement(fore, "body", name="load")
    etree.SubElement(load, "inertial", pos="0 0 0", mass="1.5", diaginertia="1e-9 1e-9 1e-9")
    tree.write(str(real))
    log = arm.record(real, tmp_path / "log.csv", amplitude=0.5)
    _late(log, DELAY, len(arm.JOINTS))
    free = "damping,frictionloss,armature,gains,payload,delay"
    res = run(
        "urdf2mjcf", "calibrate", str(nominal), str(log), "-o", "cal", "--free", free, cwd=tmp_path
    )
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    found = _params(report)
    assert len(found) == 10
    for name, p in found.items():
        truth = {"fore.payload": 1.5, "delay": DELAY}.get(name) or _truth_of(name, TRUTH, KP)
        assert abs(p["after"] - truth) <= 0.1 * truth, (name, p["after"], truth)
    assert report["held_out_improvement"] >= 5.0
