"""`urdf2mjcf excite MODEL.xml -o traj.csv`: setpoints within 80 % of each joint's range and
under the speed asked for, that the model follows with every servo under 90 % of its force
range (checked here by stepping it), and that an existing file is not replaced unasked."""

from __future__ import annotations

import mujoco
import numpy as np

from tests.calibrate import arm
from tests.security.attack import assert_one_error, run


def test_the_excitation_is_within_the_limits(tmp_path):
    model = arm.convert(tmp_path / "arm")
    res = run(
        "urdf2mjcf", "excite", str(model), "-o", "traj.csv", "--duration", "8",
        "--amplitude", "1.5", "--max-velocity", "2", cwd=tmp_path,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    header, *rows = (tmp_path / "traj.csv").read_text().splitlines()
    assert header == "t,u.shoulder,u.elbow"
    data = np.array([[float(x) for x in r.split(",")] for r in rows])
    t, u = data[:, 0], data[:, 1:]
    assert t[-1] > 7.9 and np.all(np.diff(t) > 0)
    m = mujoco.MjModel.from_xml_path(str(model))
    assert np.all(np.abs(u) <= 0.8 * 2.0 + 1e-9)  # both joints: range [-2, 2]
    assert np.abs(np.diff(u, axis=0) / np.diff(t)[:, None]).max() <= 2.0 * 1.01
    assert np.ptp(u, axis=0).min() > 0.3  # it moves every joint
    assert abs(np.corrcoef(u.T)[0, 1]) < 0.5  # and each its own way
    d = mujoco.MjData(m)
    peak = np.zeros(m.nu)
    for k in range(int(t[-1] / m.opt.timestep)):
        d.ctrl[:] = [np.interp(k * m.opt.timestep, t, u[:, a]) for a in range(m.nu)]
        mujoco.mj_step(m, d)
        peak = np.maximum(peak, np.abs(d.actuator_force))
    assert np.all(peak <= 0.9 * np.abs(m.actuator_forcerange).max(axis=1) * 1.05)
    again = run("urdf2mjcf", "excite", str(model), "-o", "traj.csv", cwd=tmp_path)
    assert_one_error(again, "traj.csv", "--overwrite")
