"""An excitation for calibration (``urdf2mjcf excite``): position setpoints that a user runs
on the robot to record a log good for :mod:`urdf2mjcf.calibrate`.

Each joint follows a sum of sines (frequencies ``k / duration`` Hz up to ``max_hz``,
Schroeder phases for a low peak, a different set of frequencies per joint so that their
effects can be told apart) around the middle of its range. The amplitude is cut until the
setpoints stay within 80 % of the range, under ``max_velocity``, and the model, replaying
them, asks each servo for at most 90 % of its force range."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from ..errors import InputError
from . import params


@dataclass(frozen=True)
class ExciteConfig:
    duration: float = 30.0
    """Seconds."""
    amplitude: float = 0.5
    """Largest amplitude of a joint's setpoint about its centre, rad or m."""
    max_velocity: float = 1.0
    """Largest setpoint speed, rad/s or m/s."""
    max_hz: float = 2.0
    """Highest frequency, Hz."""
    rate: float = 100.0
    """Rows per second of the CSV."""


@dataclass(frozen=True)
class Excitation:
    joints: list[str]
    actuators: list[str]
    t: np.ndarray
    """(n,) s."""
    setpoints: np.ndarray
    """(n, nu) position setpoints."""
    amplitude: float
    """The amplitude used, after the limits cut it."""
    peak_force: np.ndarray
    """(nu,) largest |force| / force range of each servo in the model's replay."""


def excite(m: Any, cfg: ExciteConfig) -> Excitation:
    """The excitation of the compiled model ``m`` (position servos on every joint)."""
    joints, actuators = params.joint_names(m), params.actuator_names(m)
    if not m.nu or any(params.gain_field(m, a) != "kp" for a in range(m.nu)):
        raise InputError(
            "excite writes position setpoints: every actuator must be a position servo"
        )
    joint_of = [int(m.actuator_trnid[a, 0]) for a in range(m.nu)]
    lo = np.array([m.jnt_range[j, 0] if m.jnt_limited[j] else -math.pi for j in joint_of])
    hi = np.array([m.jnt_range[j, 1] if m.jnt_limited[j] else math.pi for j in joint_of])
    centre, half = (lo + hi) / 2, 0.8 * (hi - lo) / 2
    dt = float(m.opt.timestep)
    t = np.arange(int(round(cfg.duration / dt))) * dt
    base = 1.0 / cfg.duration
    top = max(1, int(cfg.max_hz / base))
    shape = np.zeros((len(t), m.nu))
    for a in range(m.nu):
        # every nu-th harmonic, offset by the actuator's index: no two joints share one
        ks = np.arange(1 + a, top + 1, m.nu) if top >= m.nu else np.array([1 + a])
        phases = -np.pi * np.arange(len(ks)) * (np.arange(len(ks)) + 1) / len(ks)
        s = np.sin(2 * np.pi * base * ks[None, :] * t[:, None] + phases).sum(axis=1)
        shape[:, a] = s / np.abs(s).max()
    speed = np.abs(np.gradient(shape, dt, axis=0)).max(axis=0)
    amplitude = min(cfg.amplitude, float(np.min(cfg.max_velocity / np.maximum(speed, 1e-12))))
    for _ in range(8):
        setpoints = centre + np.minimum(amplitude, half) * shape
        forces = _forces(m, [int(m.jnt_qposadr[j]) for j in joint_of], setpoints)
        limit = np.where(m.actuator_forcelimited, np.abs(m.actuator_forcerange).max(axis=1), np.inf)
        peak = forces / limit
        if peak.max() <= 0.9:
            break
        amplitude *= 0.7
    else:
        raise InputError("no excitation keeps every servo under 90 % of its force range")
    every = max(1, int(round(1.0 / (cfg.rate * dt))))
    return Excitation(joints, actuators, t[::every], setpoints[::every], float(amplitude), peak)


def _forces(m: Any, qadr: list[int], setpoints: np.ndarray) -> np.ndarray:
    """Largest |actuator force| of each servo while the model follows ``setpoints`` from
    their first row."""
    d = mujoco.MjData(m)
    d.qpos[qadr] = setpoints[0]
    peak = np.zeros(m.nu)
    for row in setpoints:
        d.ctrl[:] = row
        mujoco.mj_step(m, d)
        peak = np.maximum(peak, np.abs(d.actuator_force))
    return peak


def csv_text(e: Excitation) -> str:
    """``t,u.<actuator>...``: the setpoints, one row per sample."""
    lines = [",".join(["t", *(f"u.{a}" for a in e.actuators)])]
    for t, row in zip(e.t, e.setpoints, strict=True):
        lines.append(",".join([repr(round(float(t), 9)), *(repr(float(x)) for x in row)]))
    return "\n".join(lines) + "\n"
