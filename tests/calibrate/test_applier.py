"""Values written into the compiled model (the fit's fast path, no recompile) give the
model MuJoCo compiles from the MJCF with those values, derived constants included
(``dof_invweight0`` sets how soft friction and limits are), and a noise-free log of that
robot replays exactly at its true values."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from tests.calibrate import arm
from urdf2mjcf.calibrate import fit, logs, params
from urdf2mjcf.mjcf_input import load_model

TRUTH = {
    "shoulder": {"damping": 1.4, "frictionloss": 0.6, "armature": 0.05},
    "elbow": {"damping": 0.8, "frictionloss": 0.3, "armature": 0.02},
}
KP = {"shoulder": 2500.0, "elbow": 700.0}


@pytest.fixture(scope="module")
def models(tmp_path_factory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("arm")
    nominal = arm.convert(folder)
    return nominal, arm.perturbed(nominal, folder / "real.xml", TRUTH, KP)


def _truth(free: list[params.Param]) -> np.ndarray:
    return np.array([KP[p.target] if p.field == "kp" else TRUTH[p.target][p.field] for p in free])


def _floats(m) -> dict[str, np.ndarray]:
    out = {}
    for name in dir(m):
        value = getattr(m, name, None) if not name.startswith("_") else None
        if isinstance(value, np.ndarray) and value.dtype.kind == "f":
            out[name] = value
    return out


@pytest.mark.parametrize("kinds", [("damping",), ("frictionloss",), ("armature",), ("gains",),
                                   ("damping", "frictionloss", "armature", "gains")])  # fmt: skip
def test_written_values_are_the_compiled_models(models, kinds):
    nominal, real = models
    m = load_model(nominal)
    free = params.select(m, kinds, None)
    assert free, kinds
    written = params.Applier(m, free).model(_truth(free))
    compiled = mujoco.MjModel.from_xml_path(str(real))
    want = _floats(compiled)
    if "gains" not in kinds:  # only what is free is written; the rest stays nominal
        nominal_kp = mujoco.MjModel.from_xml_path(str(nominal))
        want["actuator_gainprm"] = nominal_kp.actuator_gainprm
        want["actuator_biasprm"] = nominal_kp.actuator_biasprm
    for kind in {"damping", "frictionloss", "armature"} - set(kinds):
        want[f"dof_{kind}"] = load_model(nominal).__getattribute__(f"dof_{kind}")
    if {"damping", "frictionloss", "armature", "gains"} <= set(kinds):
        for name, value in want.items():
            assert np.allclose(getattr(written, name), value, rtol=1e-9, atol=1e-12), name
    else:
        for name in ("dof_invweight0", "body_invweight0", "dof_M0"):
            if "armature" in kinds:
                assert np.allclose(getattr(written, name), want[name], rtol=1e-9), name
        for kind in kinds:
            field = {"gains": "actuator_gainprm"}.get(kind, f"dof_{kind}")
            assert np.allclose(getattr(written, field), want[field], rtol=1e-9), field


def test_a_noise_free_log_replays_exactly_at_the_true_values(models, tmp_path):
    nominal, real = models
    log = arm.record(real, tmp_path / "log.csv", seconds=4.0, amplitude=0.5, q_noise=0.0,
                     v_noise=0.0)  # fmt: skip
    m = load_model(nominal)
    free = params.select(m, ("damping", "frictionloss", "armature", "gains"), None)
    acts = params.actuator_names(m)
    found = logs.read(log, acts, params.position_servos(m), None)
    tr = logs.resample(found, params.joint_names(m), acts, float(m.opt.timestep), None)
    replay = fit.Replay(params.Applier(m, free), [tr], fit.FitConfig())
    at_truth = replay.tracking(_truth(free))
    at_nominal = replay.tracking(np.array([p.nominal for p in free]))
    assert at_truth.q_max.max() < 1e-6 and at_truth.v_max.max() < 1e-5
    assert at_nominal.q_max.max() > 1e-3  # the values matter
