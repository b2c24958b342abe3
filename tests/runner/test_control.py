"""The Controller's servo targets, step by step, against the definitions they follow:
``play`` interpolates a timed trajectory at every physics step's time (numpy's
``interp`` sample by sample), ``follow`` walks a joint path's arc length with the
quintic time scaling. The targets of a whole move are computed at once (for speed):
each step must still command exactly what the per-step definition gives."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from urdf2mjcf.runner.control import Controller, quintic
from urdf2mjcf.runner.load import load

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def controller(imetro_bundle: Path) -> Controller:
    fac = load(imetro_bundle)
    return Controller(fac, np.full(len(fac.robot.joints), 1.0))


def _commanded(ctl: Controller) -> list[np.ndarray]:
    """Record the arm's actuator commands after every physics step."""
    seen: list[np.ndarray] = []
    ctl.on_step[:] = [lambda: seen.append(ctl.d.ctrl[ctl.r.actuators].copy())]
    return seen


def test_play_commands_the_trajectory_at_every_step_time(controller):
    ctl = controller
    start = ctl.target.copy()
    goal = np.clip(start + 0.1, ctl.r.lower, ctl.r.upper)
    times = np.array([0.0, 0.13, 0.4, 0.61])
    q = np.array([start, start + 0.3 * (goal - start), goal - 0.01, goal])
    seen = _commanded(ctl)
    t0 = ctl.d.time
    ctl.play(times, q)
    n = int(round(times[-1] / ctl.dt))
    assert len(seen) == n
    for k, cmd in enumerate(seen, start=1):
        t = min(k * ctl.dt, float(times[-1]))
        want = np.array([np.interp(t, times, q[:, j]) for j in range(q.shape[1])])
        np.testing.assert_array_equal(cmd, np.clip(want, ctl.r.lower, ctl.r.upper))
    assert ctl.d.time == pytest.approx(t0 + n * ctl.dt)


def test_follow_walks_the_path_with_the_quintic_scaling(controller):
    ctl = controller
    start = ctl.target.copy()
    mid = np.clip(start + 0.05, ctl.r.lower, ctl.r.upper)
    end = np.clip(mid - np.linspace(0.0, 0.08, len(start)), ctl.r.lower, ctl.r.upper)
    path = np.vstack([start, mid, end])
    seen = _commanded(ctl)
    T = ctl.follow(path, 0.3)
    n = int(round(T / ctl.dt))
    assert len(seen) == n
    seg = np.abs(np.diff(path, axis=0)) / ctl.vmax
    cum = np.concatenate([[0.0], np.cumsum(seg.max(axis=1))])
    for k, cmd in enumerate(seen, start=1):
        u = float(quintic(k / n)) * cum[-1]
        i = min(int(np.searchsorted(cum, u, side="right")) - 1, len(path) - 2)
        w = (u - cum[i]) / max(cum[i + 1] - cum[i], 1e-12)
        want = path[i] + w * (path[i + 1] - path[i])
        np.testing.assert_allclose(cmd, np.clip(want, ctl.r.lower, ctl.r.upper), atol=1e-15)
    np.testing.assert_allclose(seen[-1], end, atol=1e-12)
    np.testing.assert_allclose(ctl.target, end, atol=1e-12)
