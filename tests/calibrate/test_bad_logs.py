"""Logs as real robots write them: NaNs, dropped samples, another rate, unsorted rows are
warnings and the calibration still works; a joint missing, a log of another robot, a
header or number that is not one are one `error:` line (exit 2), with nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.calibrate import arm
from tests.security.attack import assert_one_error, run
from urdf2mjcf.calibrate import fit, logs, params
from urdf2mjcf.mjcf_input import load_model


@pytest.fixture(scope="module")
def case(tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("bad_logs")
    nominal = arm.convert(folder)
    truth = {"shoulder": {"damping": 1.5}, "elbow": {"damping": 0.9}}
    real = arm.perturbed(nominal, folder / "real.xml", truth, {})
    return nominal, arm.record(real, folder / "log.csv", seconds=6.0, rate=250.0, amplitude=0.5)


def _rows(log: Path) -> tuple[str, list[str]]:
    header, *rows = log.read_text().splitlines()
    return header, rows


def _calibrate(tmp_path: Path, nominal: Path, log: Path, *extra: str):
    return run(
        "urdf2mjcf", "calibrate", str(nominal), str(log), "-o", "cal",
        "--free", "damping", *extra, cwd=tmp_path,
    )  # fmt: skip


def test_nans_gaps_unsorted_rows_and_another_rate_are_warnings(case, tmp_path):
    nominal, log = case
    header, rows = _rows(log)
    rng = np.random.default_rng(3)
    cells = [r.split(",") for r in rows]
    for i in rng.choice(len(cells), 30, replace=False):
        cells[i][1 + int(rng.integers(4))] = "nan"  # a sensor's sample lost
    del cells[300:320]  # 80 ms of nothing
    cells[10], cells[11] = cells[11], cells[10]  # two rows out of order
    (tmp_path / "messy.csv").write_text("\n".join([header, *(",".join(c) for c in cells)]) + "\n")
    res = _calibrate(tmp_path, nominal, tmp_path / "messy.csv")
    assert res.returncode == 0, res.stderr
    for said in ("NaN samples dropped", "not in time order", "bridged by interpolation"):
        assert said in res.stderr, said
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    truth = {"shoulder.damping": 1.5, "elbow.damping": 0.9}
    for p in report["parameters"]:
        value = truth[p["name"]]
        # each value within 10 %, or within the interval the report gives it
        assert abs(p["after"] - value) <= max(0.1 * value, p["interval95"]), p
    assert report["held_out_improvement"] > 2.0


@pytest.mark.parametrize(
    ("edit", "needles"),
    [
        (lambda h, r: (h.replace("q.elbow", "q.wrist"), r), ["log lacks q.elbow"]),
        (
            lambda h, r: (
                ",".join(["t"] + [f"{c[0]}.other{i}" for i, c in enumerate(h.split(",")[1:])]),
                r,
            ),
            ["names none of the model's joints", "another robot"],
        ),
        (lambda h, r: (h.replace("t,", "time,", 1), r), ["line 1", "'t'"]),
        (lambda h, r: (h, [r[0], r[1].replace(",", ",x", 1), *r[2:]]), ["line 3", "not a number"]),
        (lambda h, r: (h, [r[0], r[1] + ",1"]), ["line 3", "values where the header has"]),
        (lambda h, r: (h, r[:1]), ["fewer than two samples"]),
    ],
    ids=[
        "joint missing",
        "another robot",
        "no time column",
        "not a number",
        "ragged row",
        "one row",
    ],
)
def test_a_log_that_cannot_be_replayed_is_one_error(case, tmp_path, edit, needles):
    nominal, log = case
    header, rows = edit(*_rows(log))
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([header, *rows]) + "\n")
    assert_one_error(_calibrate(tmp_path, nominal, bad), "bad.csv", *needles)
    assert not (tmp_path / "cal").exists()


def test_an_unknown_kind_and_a_model_without_actuators_are_one_error(case, tmp_path):
    nominal, log = case
    res = run(
        "urdf2mjcf",
        "calibrate",
        str(nominal),
        str(log),
        "-o",
        "cal",
        "--free",
        "springs",
        cwd=tmp_path,
    )
    assert_one_error(res, "--free", "'springs'", "damping")
    passive = tmp_path / "passive.xml"
    text = nominal.read_text()
    text = text[: text.index("<actuator>")] + text[text.index("</actuator>") + 11 :]
    passive.write_text(text.replace(' ctrl="0 0"', ""))
    (tmp_path / "assets").mkdir()
    res = run("urdf2mjcf", "calibrate", str(passive), str(log), "-o", "cal", cwd=tmp_path)
    assert_one_error(res, "no actuators")
    assert not (tmp_path / "cal").exists()


def test_a_ball_joint_or_two_free_bodies_are_refused_in_words():
    import mujoco

    from urdf2mjcf.calibrate import params
    from urdf2mjcf.errors import InputError

    body = '<body><joint type="{}"/><geom size="0.1" mass="1"/></body>'
    ball = mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{body.format('ball')}</worldbody></mujoco>")
    with pytest.raises(InputError, match="is a ball joint"):
        params.joint_names(ball)
    two = mujoco.MjModel.from_xml_string(
        f"<mujoco><worldbody>{body.format('free') * 2}</worldbody></mujoco>"
    )
    with pytest.raises(InputError, match="2 free joints; calibrate fits one robot"):
        params.joint_names(two)
    one = mujoco.MjModel.from_xml_string(
        f"<mujoco><worldbody>{body.format('free')}</worldbody></mujoco>"
    )
    assert params.joint_names(one) == [] and params.floating_base(one).joint == "joint 0"


def test_an_unnamed_floating_base_starts_each_window_from_its_logged_state():
    """The base is found by id, not by the name the log's columns use for it ("joint 0"
    when it has none): its logged pose is the replay's start."""
    import mujoco
    import numpy as np

    from urdf2mjcf.calibrate import fit, logs, params

    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><freejoint/><geom size="0.1" mass="1"/>'
        '<body><joint name="h"/><geom size="0.05" mass="0.5" pos="0 0 0.2"/></body>'
        '</body></worldbody><actuator><motor joint="h"/></actuator></mujoco>'
    )
    n = 10
    pose = np.tile([1.0, 2.0, 3.0, 1.0, 0.0, 0.0, 0.0], (n, 1))
    tr = logs.Trajectory(
        "log", m.opt.timestep, np.zeros((n, 1)), np.zeros((n, 1)), np.zeros((n, 1)),
        pose, np.zeros((n, 6)),
    )  # fmt: skip
    replay = fit.Replay(params.Applier(m, []), [tr], fit.FitConfig())
    assert replay.windows.start[0, 1:4].tolist() == [1.0, 2.0, 3.0]  # after the time


def test_a_log_slower_than_the_model_is_fitted_at_its_samples(case, tmp_path):
    """A 250 Hz log on the model's 2 ms grid: every other row is interpolated between two
    samples, a state on no trajectory. Each window starts from a sampled row and only the
    sampled rows are fitted; the dampings come back within 3 % (before: the elbow's 7 %
    off, from windows started between samples)."""
    nominal, log = case
    m = load_model(nominal)
    acts = params.actuator_names(m)
    found = logs.read(log, acts, params.position_servos(m), None)
    tr = logs.resample(found, params.joint_names(m), acts, float(m.opt.timestep), None)
    assert tr.sampled is not None
    assert tr.sampled[::2].all() and not tr.sampled[1::2].any()
    applier = params.Applier(m, params.select(m, ["damping"]))
    replay = fit.Replay(applier, [tr], fit.FitConfig())
    cut = replay.cut(m)
    for r in (replay, cut):
        assert all(tr.sampled[k] for _, k, _ in r.spans)
        for (_, k, n), keep in zip(r.spans, r.windows.keep, strict=True):
            # step i of a window ends on row k + i + 1
            assert (keep[:n] == tr.sampled[k + 1 : k + n + 1]).all()
    res = _calibrate(tmp_path, nominal, log)
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    truth = {"shoulder.damping": 1.5, "elbow.damping": 0.9}
    for p in report["parameters"]:
        assert p["after"] == pytest.approx(truth[p["name"]], rel=0.03), p
