"""A payload at the tool and a sensor delay are recovered: the arm's forearm carries 1.5 kg
more at its origin (a body added to the MJCF by hand), and its log's positions and
velocities arrive 10 ms late (the log's rows shifted)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from lxml import etree

from tests.calibrate import arm
from tests.security.attack import run


@pytest.fixture(scope="module")
def nominal(tmp_path_factory) -> Path:
    return arm.convert(tmp_path_factory.mktemp("arm"))


def _found(folder: Path) -> dict[str, float]:
    report = json.loads((folder / "report.json").read_text())
    return {p["name"]: p["after"] for p in report["parameters"]}


def test_a_payload_at_the_tool_is_recovered(nominal, tmp_path):
    tree = etree.parse(str(nominal))
    (fore,) = tree.xpath("//body[@name='fore']")
    extra = etree.SubElement(fore, "body", name="load")
    etree.SubElement(extra, "inertial", pos="0 0 0", mass="1.5", diaginertia="1e-9 1e-9 1e-9")
    real = tmp_path / "real.xml"
    tree.write(str(real))
    log = arm.record(real, tmp_path / "log.csv", seconds=6.0, amplitude=0.5)
    res = run(
        "urdf2mjcf",
        "calibrate",
        str(nominal),
        str(log),
        "-o",
        "cal",
        "--free",
        "payload",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    assert _found(tmp_path / "cal")["fore.payload"] == pytest.approx(1.5, rel=0.1)


def test_a_sensor_delay_is_recovered(nominal, tmp_path):
    log = arm.record(nominal, tmp_path / "log.csv", seconds=6.0, amplitude=0.5)
    header, *rows = log.read_text().splitlines()
    cells = [r.split(",") for r in rows]
    n = len(arm.JOINTS)
    late = 5  # rows of 2 ms: the measurement at t is what was true at t - 10 ms
    shifted = [
        [c[0], *cells[max(i - late, 0)][1 : 1 + 2 * n], *c[1 + 2 * n :]]
        for i, c in enumerate(cells)
    ]
    log.write_text("\n".join([header, *(",".join(c) for c in shifted)]) + "\n")
    res = run(
        "urdf2mjcf",
        "calibrate",
        str(nominal),
        str(log),
        "-o",
        "cal",
        "--free",
        "delay",
        cwd=tmp_path,
    )
    assert res.returncode == 0, res.stderr
    assert _found(tmp_path / "cal")["delay"] == pytest.approx(0.010, rel=0.1)


def test_the_same_log_gives_the_same_files(nominal, tmp_path):
    log = arm.record(nominal, tmp_path / "log.csv", seconds=3.0, amplitude=0.5)
    for out in ("a", "b"):
        res = run("urdf2mjcf", "calibrate", str(nominal), str(log), "-o", out, cwd=tmp_path)
        assert res.returncode == 0, res.stderr
    for name in ("robot.xml", "calibration.yaml", "report.json", "report.html"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name


def test_a_whole_log_can_be_held_out(nominal, tmp_path):
    truth = {"shoulder": {"damping": 1.5}, "elbow": {"damping": 0.9}}
    real = arm.perturbed(nominal, tmp_path / "real.xml", truth, {})
    fitted = arm.record(real, tmp_path / "a.csv", seconds=4.0, amplitude=0.5, seed=1)
    held = arm.record(real, tmp_path / "b.csv", seconds=2.0, amplitude=0.5, seed=2)
    res = run(
        "urdf2mjcf", "calibrate", str(nominal), str(fitted), "-o", "cal", "--free", "damping",
        "--holdout", str(held), cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    assert report["held_out"] == str(held)
    # the whole of a.csv is fitted: 4 s at 500 Hz, less one sample per window
    assert report["cost"]["steps_fitted"] >= 1990
    assert _found(tmp_path / "cal")["elbow.damping"] == pytest.approx(0.9, rel=0.1)
