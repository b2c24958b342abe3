"""The report's warnings say what the logs do not determine, in words a user acts on: a log
that barely moves the arm leaves its damping and armature named as not identified, a log
that moves it well names none; a value near zero that the log pins down is no warning,
while a small value with an interval wider than itself is one; a servo the log drives into
its force limit is named, with its share of the samples."""

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
    _forces(nominal, log)
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
    assert not [w for w in said if "force is at its limit" in w]


def test_a_log_that_moves_the_arm_well_names_nothing_as_not_identified(case, tmp_path):
    nominal, real = case
    assert [w for w in _warnings(nominal, real, tmp_path, 0.5) if "not identified" in w] == []


def _forces(nominal, log) -> None:
    """Keep, beside the log, each servo's share of the fitted samples (the first 80 %) at
    its force limit, computed from the log with numpy: kp (u - q) - kv v against the
    servo's force range, the gains and ranges read from the MJCF with lxml."""
    from lxml import etree

    header = log.read_text().split("\n", 1)[0].split(",")
    data = np.loadtxt(log, delimiter=",", skiprows=1)
    data = data[: len(data) - round(0.2 * len(data))]
    col = {h: data[:, i] for i, h in enumerate(header)}
    shares = {}
    for el in etree.parse(str(nominal)).iter("position"):
        name, j = el.get("name"), el.get("joint")
        kp, kv = float(el.get("kp")), float(el.get("kv"))
        limit = min(abs(float(x)) for x in el.get("forcerange").split())
        force = kp * (col[f"u.{name}"] - col[f"q.{j}"]) - kv * col[f"v.{j}"]
        shares[name] = float(np.mean(np.abs(force) >= limit))
    (log.parent / "shares.json").write_text(json.dumps(shares))


def test_a_log_that_drives_a_servo_into_its_force_limit_says_so(case, tmp_path):
    """The fit's local minima come from a servo at its force limit (docs/calibrate.md):
    the warning names each servo there and its share of the samples, as numpy computes
    that share from the log."""
    nominal, real = case
    said = _warnings(nominal, real, tmp_path, 0.5)
    shares = json.loads((tmp_path / "shares.json").read_text())
    assert shares["shoulder"] > 0.001
    for name, share in shares.items():
        named = [w for w in said if w.startswith(f"actuator '{name}': its force is at its limit")]
        if share <= 0.001:
            assert named == []
            continue
        [line] = named
        assert f"in {100 * share:.1f} % of the fitted samples" in line
        assert "record a log within the servos' force ranges" in line


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
