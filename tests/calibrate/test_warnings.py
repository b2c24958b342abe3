"""The report's warnings say what the logs do not determine, in words a user acts on: a log
that barely moves the arm leaves its damping and armature named as not identified, a log
that moves it well names none; a value near zero that the log pins down is no warning,
while a small value with an interval wider than itself is one."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.calibrate import arm
from tests.security.attack import run
from urdf2mjcf.calibrate import report
from urdf2mjcf.calibrate.fit import FitResult
from urdf2mjcf.calibrate.params import Param

TRUTH = {"shoulder": {"damping": 1.5, "armature": 0.05}, "elbow": {"damping": 0.9, "armature": 0.02}}


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    folder = tmp_path_factory.mktemp("warn")
    nominal = arm.convert(folder)
    return nominal, arm.perturbed(nominal, folder / "real.xml", TRUTH, {})


def _warnings(nominal, real, tmp_path, amplitude: float, still=()) -> list[str]:
    log = arm.record(real, tmp_path / "log.csv", seconds=6.0, amplitude=amplitude, still=still)
    res = run(
        "urdf2mjcf", "calibrate", str(nominal), str(log), "-o", "cal", "--free",
        "damping,armature", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    return json.loads((tmp_path / "cal" / "report.json").read_text())["warnings"]


def test_a_log_that_barely_moves_the_arm_names_what_it_cannot_tell(case, tmp_path):
    nominal, real = case
    said = _warnings(nominal, real, tmp_path, 0.02, still=(1,))  # the shoulder about 1 degree
    for owner, what in (("elbow", "damping"), ("shoulder", "armature"), ("elbow", "armature")):
        [line] = [w for w in said if w.startswith(f"joint '{owner}': {what} is not identified")]
        assert "record a log that moves it more, or fix it (--params: false)" in line


def test_a_log_that_moves_the_arm_well_names_nothing_as_not_identified(case, tmp_path):
    nominal, real = case
    assert [w for w in _warnings(nominal, real, tmp_path, 0.5) if "not identified" in w] == []


def _fit(values: list[tuple[str, float, float, float]]) -> FitResult:
    params = [Param(field, "elbow", 0.0, 0.0, hi) for field, _, _, hi in values]
    return FitResult(
        params,
        np.array([x for _, x, _, _ in values]),
        np.array([half for _, _, half, _ in values]),
        np.eye(len(values)),
        [False] * len(values),
        0,
    )


def test_a_small_value_wider_than_itself_is_named_and_a_pinned_zero_is_not():
    said = report.warnings(
        _fit([("damping", 0.25, 0.29, 50.0), ("frictionloss", 0.001, 0.005, 20.0)])
    )
    assert said == [
        "joint 'elbow': damping is not identified from these logs (0.25 +- 0.29): record a "
        "log that moves it more, or fix it (--params: false)"
    ]
