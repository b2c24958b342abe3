"""A served trajectory's velocities and accelerations (what the action's velocity and
acceleration tolerances are checked against) are the derivatives of its positions:
against central finite differences of ``Trajectory.sample``, for straight segments and
for cubic Hermite ones, and zero where it holds; and the tolerances read from a goal."""

from __future__ import annotations

import numpy as np
import pytest

from urdf2mjcf.ros2.controllers import Trajectory
from urdf2mjcf.ros2.trajectory_action import _beyond, _tolerances

TIMES = np.array([1.0, 1.5, 2.5, 3.0])
POSITIONS = np.array([[0.0, 1.0], [0.4, 0.7], [-0.2, 0.9], [0.1, 0.1]])
VELOCITIES = np.array([[0.0, 0.0], [0.5, -0.3], [0.2, 0.4], [0.0, 0.0]])


@pytest.mark.parametrize("velocities", [None, VELOCITIES], ids=["straight", "hermite"])
def test_rates_are_the_derivatives_of_the_positions(velocities):
    traj = Trajectory((0, 1), TIMES, POSITIONS, velocities)
    h = 1e-5
    for t in np.linspace(1.01, 2.99, 37):
        if np.any(np.abs(t - TIMES) < 3 * h):
            continue  # a knot: a straight segment's velocity jumps there
        v, a = traj.rates(t)
        fd_v = (traj.sample(t + h) - traj.sample(t - h)) / (2 * h)
        np.testing.assert_allclose(v, fd_v, atol=1e-6)
        if velocities is not None:
            fd_a = (traj.sample(t + h) - 2 * traj.sample(t) + traj.sample(t - h)) / h**2
            np.testing.assert_allclose(a, fd_a, atol=1e-3)
        else:
            assert not a.any()
    for t in (0.5, 1.0, 3.0, 4.0):  # held before the start and after the end
        v, a = traj.rates(t)
        assert not v.any() and not a.any()


def test_tolerances_per_component_with_none_unchecked():
    joints = ("a", "b")
    tol = _tolerances(
        [
            {"name": "a", "position": 0.1, "velocity": 0.5, "acceleration": -1.0},
            {"name": "b", "position": 0.0, "velocity": float("nan"), "acceleration": 2.0},
            {"name": "c", "position": 9.0},  # not a goal joint
        ],
        joints,
    )
    np.testing.assert_array_equal(tol, [[0.1, 0.5, 0.0], [0.0, 0.0, 2.0]])
    errors = np.array([[0.05, 0.6, 100.0], [5.0, 5.0, 1.0]])
    assert _beyond(tol, errors).tolist() == [0]  # a's velocity; b's position unchecked
    errors[1, 2] = -2.5
    assert _beyond(tol, errors).tolist() == [0, 1]
