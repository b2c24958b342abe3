"""Sim against real: a model's tracking of logged runs (``urdf2mjcf verify --against``).

The logged commands are replayed in the model in windows from the measured states, as the
calibration's fit replays them (:class:`~urdf2mjcf.calibrate.fit.Replay`), and each joint's
error against the log is judged on tolerances of RMS position and velocity error."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import fit, logs, params


@dataclass(frozen=True)
class AgainstTolerances:
    q_rms: float = 0.01
    """Largest RMS position error of a joint, rad or m."""
    v_rms: float = 0.1
    """Largest RMS velocity error of a joint, rad/s or m/s."""


@dataclass(frozen=True)
class Against:
    joints: list[str]
    tracking: fit.Tracking
    tolerances: AgainstTolerances

    def failures(self) -> list[str]:
        """One sentence per figure out of tolerance."""
        out = []
        t, tol = self.tracking, self.tolerances
        for k, j in enumerate(self.joints):
            if t.q_rms[k] > tol.q_rms:
                out.append(f"joint '{j}': RMS position error {t.q_rms[k]:.3g} > {tol.q_rms:g}")
            if t.v_rms[k] > tol.v_rms:
                out.append(f"joint '{j}': RMS velocity error {t.v_rms[k]:.3g} > {tol.v_rms:g}")
        return out

    def to_dict(self) -> dict[str, Any]:
        t = self.tracking
        return {
            "tolerances": {"q_rms": self.tolerances.q_rms, "v_rms": self.tolerances.v_rms},
            "joints": {
                j: {
                    "q_rms": float(t.q_rms[k]),
                    "q_max": float(t.q_max[k]),
                    "v_rms": float(t.v_rms[k]),
                    "v_max": float(t.v_max[k]),
                }
                for k, j in enumerate(self.joints)
            },
            "failures": self.failures(),
            "passed": not self.failures(),
        }

    def table(self) -> str:
        t = self.tracking
        lines = ["joint  q_rms  q_max  v_rms  v_max"]
        for k, j in enumerate(self.joints):
            lines.append(
                f"{j}  {t.q_rms[k]:.3g}  {t.q_max[k]:.3g}  {t.v_rms[k]:.3g}  {t.v_max[k]:.3g}"
            )
        return "\n".join(lines)


def against(
    model_path: Path, log_paths: Sequence[Path], tolerances: AgainstTolerances, window: float
) -> Against:
    """The tracking of the logs at ``log_paths`` by the model at ``model_path``."""
    from ..mjcf_input import load_model

    m = load_model(model_path)
    joints, actuators = params.joint_names(m), params.actuator_names(m)
    servos = params.position_servos(m)
    dt = float(m.opt.timestep)
    floating = params.floating_base(m)
    trajectories = [
        logs.resample(logs.read(p, actuators, servos, floating), joints, actuators, dt, floating)
        for p in log_paths
    ]
    replay = fit.Replay(params.Applier(m, []), trajectories, fit.FitConfig(window=window))
    return Against(joints, replay.tracking(np.zeros(0)), tolerances)
