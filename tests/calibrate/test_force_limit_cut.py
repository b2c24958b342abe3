"""The fit leaves out the steps where a servo nears its force limit (there a replay's
result jumps with the parameters, docs/calibrate.md): every step a fitted window keeps has
each servo's force, as MuJoCo computes it from the MJCF with the force ranges taken out,
outside the band around its limits, and nearly every step outside the band is kept; a log
within the servos' ranges is not cut; and the seeds whose fit stopped in a local minimum
before the cut recover every value within 10 %."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
from lxml import etree

from tests.calibrate import arm
from tests.calibrate.test_recovery import KP, TRUTH, _truth_of
from tests.security.attack import run
from urdf2mjcf.calibrate import fit, logs, params
from urdf2mjcf.mjcf_input import load_model


@pytest.fixture(scope="module")
def case(tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("arm")
    nominal = arm.convert(folder)
    return nominal, arm.perturbed(nominal, folder / "real.xml", TRUTH, KP)


def _replay(nominal: Path, log: Path) -> tuple[fit.Replay, object]:
    m = load_model(nominal)
    acts = params.actuator_names(m)
    found = logs.read(log, acts, params.position_servos(m), None)
    tr = logs.resample(found, params.joint_names(m), acts, float(m.opt.timestep), None)
    return fit.Replay(params.Applier(m, []), [tr], fit.FitConfig()), m


def _unclamped(nominal: Path) -> tuple[mujoco.MjModel, np.ndarray]:
    """The model compiled without its force ranges, and the ranges."""
    tree = etree.parse(str(nominal))
    ranges = []
    for el in tree.iter("position"):
        ranges.append([float(x) for x in el.get("forcerange").split()])
        del el.attrib["forcerange"]
    m = mujoco.MjModel.from_xml_string(etree.tostring(tree).decode())
    assert not m.actuator_forcelimited.any()
    return m, np.array(ranges)


def test_the_fitted_steps_are_those_away_from_a_force_limit(case, tmp_path):
    nominal, real = case
    log = arm.record(real, tmp_path / "log.csv", amplitude=0.5, seed=2)
    replay, m = _replay(nominal, log)
    cut = replay.cut(m)
    assert cut is not replay and cut.samples < replay.samples
    ref, ranges = _unclamped(nominal)
    band = fit.NEAR_LIMIT * (ranges[:, 1] - ranges[:, 0]) / 2
    d = mujoco.MjData(ref)

    def near(q: np.ndarray, v: np.ndarray, u: np.ndarray) -> bool:
        d.qpos[:], d.qvel[:], d.ctrl[:] = q, v, u
        mujoco.mj_forward(ref, d)
        f = d.actuator_force
        return bool((np.minimum(np.abs(f - ranges[:, 0]), np.abs(f - ranges[:, 1])) < band).any())

    w = cut.windows
    for i in range(len(w.start)):
        kept = int(w.keep[i].sum())
        assert kept >= fit.MIN_WINDOW and w.keep[i, :kept].all()
        q = np.vstack([w.start[i, 1 : 1 + m.nq], w.q[i, : kept - 1]])
        v = np.vstack([w.start[i, 1 + m.nq : 1 + m.nq + m.nv], w.v[i, : kept - 1]])
        assert not any(near(q[j], v[j], w.ctrl[i, j]) for j in range(kept)), i
    tr = replay.trajectories[0]
    away = sum(not near(tr.q[k], tr.v[k], tr.u[k]) for k in range(len(tr.q) - 1))
    assert 0.2 * replay.samples < away and 0.9 * away <= cut.samples <= away


def test_a_log_within_the_force_ranges_is_not_cut(case, tmp_path):
    nominal, real = case
    log = arm.record(real, tmp_path / "log.csv", amplitude=0.005)  # kp x 0.005: 16 of 40 N m
    replay, m = _replay(nominal, log)
    assert replay.cut(m) is replay


@pytest.mark.parametrize("seed", [2, 5])
def test_seeds_that_stopped_in_a_local_minimum_recover_every_value(case, tmp_path, seed):
    """Before the cut these two seeds' shoulder damping came back 21.6 and 35.8 % off."""
    nominal, real = case
    log = arm.record(real, tmp_path / "log.csv", amplitude=0.5, seed=seed)
    free = "damping,frictionloss,armature,gains"
    res = run("urdf2mjcf", "calibrate", str(nominal), str(log), "-o", "cal", "--free", free,
              cwd=tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    report = json.loads((tmp_path / "cal" / "report.json").read_text())
    for p in report["parameters"]:
        truth = _truth_of(p["name"], TRUTH, KP)
        assert abs(p["after"] - truth) <= 0.1 * truth, (p["name"], p["after"], truth)


def test_a_late_log_is_cut_where_the_servos_were_near_their_limits(case, tmp_path):
    """A log whose positions and velocities are 3 samples late is cut, read with that
    delay, at the steps where the on-time log is, 3 rows on (its row k + 3 holds the
    on-time row k, replayed under the command of row k), and not so read without it."""
    nominal, real = case
    log = arm.record(real, tmp_path / "log.csv", amplitude=0.5, seed=2)
    replay, m = _replay(nominal, log)
    tr = replay.trajectories[0]
    late = 3
    shifted = dataclasses.replace(
        tr,
        q=np.vstack([np.repeat(tr.q[:1], late, 0), tr.q[:-late]]),
        v=np.vstack([np.repeat(tr.v[:1], late, 0), tr.v[:-late]]),
    )
    steps = 1000
    on_time = fit._cut(m, [tr], steps)
    read_late = fit._cut(m, [shifted], steps, float(late), late)
    unread = fit._cut(m, [shifted], steps)
    assert on_time is not None and read_late is not None and unread is not None

    def rows(spans: list[tuple[int, int, int]], by: int = 0) -> set[int]:
        """The rows the windows fit (the first and last few aside)."""
        inside = range(4 * late, len(tr.q) - 4 * late)
        return {r + by for _, k, n in spans for r in range(k, k + n) if r + by in inside}

    assert rows(read_late) == rows(on_time, late)
    assert len(read_late) > 10 and len(rows(read_late)) < len(tr.q) - 8 * late - 10
    assert rows(unread) != rows(on_time, late)
