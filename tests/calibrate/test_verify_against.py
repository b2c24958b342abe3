"""`urdf2mjcf verify --against LOG MODEL.xml`: the model replays the log's commands; a
model that is the logged robot passes, one whose damping and gains are off fails naming
the joint (exit 1), and the figures are in the JSON report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.calibrate import arm
from tests.security.attack import assert_one_error, run


@pytest.fixture(scope="module")
def case(tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("against")
    nominal = arm.convert(folder)
    real = arm.perturbed(
        nominal, folder / "real.xml", {"elbow": {"damping": 3.0}}, {"elbow": 300.0}
    )
    return nominal, real


def test_the_logged_robot_passes_and_another_fails_naming_the_joint(case, tmp_path):
    nominal, real = case
    log = arm.record(nominal, tmp_path / "log.csv", seconds=4.0, amplitude=0.5)
    ok = run("urdf2mjcf", "verify", "--against", str(log), str(nominal), cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "passed" in ok.stdout
    res = run(
        "urdf2mjcf", "verify", "--against", str(log), str(real), "--q-rms", "0.02", "--v-rms", "1",
        "--report", "r.json", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 1, res.stderr
    assert "failed: joint 'elbow': RMS position error" in res.stderr
    assert "joint 'shoulder'" not in res.stderr
    data = json.loads((tmp_path / "r.json").read_text())["against"]
    assert not data["passed"] and data["joints"]["elbow"]["q_rms"] > 0.02
    assert data["joints"]["shoulder"]["q_rms"] <= 0.02


def test_against_takes_the_model_alone(case, tmp_path):
    nominal, _ = case
    log = arm.record(nominal, tmp_path / "log.csv", seconds=1.0)
    res = run("urdf2mjcf", "verify", "--against", str(log), "a.urdf", str(nominal), cwd=tmp_path)
    assert_one_error(res, "--against", "model alone")
