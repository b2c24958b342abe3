"""Default servo gains from a robot's linearised dynamics (pure numerics, no I/O).

The robot at its home pose, in independent joint coordinates (mimic
followers folded into their leaders), is ``M q'' + (B + Kv) q' + Kp q = tau``
with M the joint-space inertia, B the joints' own damping and Kp, Kv the
diagonal servo gains. :func:`design` chooses the gains that were not given;
``passes/actuators.py`` documents the rules.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ...ir import Note


@dataclass(frozen=True, eq=False)
class ServoSystem:
    """The robot linearised at its home pose, in independent joint coordinates."""

    inertia: np.ndarray
    """(n, n) M = C^T M_q C, kg m^2 / kg; C maps independent velocities to all dofs."""
    damping: np.ndarray
    """(n, n) B = C^T diag(dof damping) C."""
    index: Mapping[str, int]
    """Actuated joint name -> its coordinate."""
    load: Mapping[str, float]
    """Joint -> worst gravity load over its own motion (followers' included), N m or N."""
    linear: Mapping[str, bool]
    """Joint -> True for slides."""
    timestep: float
    """s."""


@dataclass(frozen=True)
class ServoRequest:
    """One actuator to size: what was given (None = to be chosen)."""

    kind: str
    """``position`` or ``velocity``."""
    kp: float | None
    kv: float | None
    effort: float | None
    """Force limit, N m or N (None: unlimited)."""
    bandwidth_hz: float
    damping_ratio: float


@dataclass(frozen=True)
class DesignParams:
    sag_tolerance: float
    sag_tolerance_linear: float
    drift_tolerance: float
    max_omega_dt: float


_MODE_SLACK = 0.05
"""Coupled modes must be damped at least zeta - 0.05 (overshoot < 0.01 % at zeta = 1)."""
_MAX_KV_SCALE = 10.0
_GIVEN_OMEGA_DT = 2.0
"""Semi-implicit Euler's stability limit for an undamped spring: warn above it."""


def design(
    system: ServoSystem, requests: Mapping[str, ServoRequest], params: DesignParams
) -> tuple[dict[str, tuple[float | None, float | None]], list[Note]]:
    """Joint -> (kp, kv) for every request, given values kept; notes on what was chosen."""
    notes: list[Note] = []
    inertia = {name: float(system.inertia[i, i]) for name, i in system.index.items()}
    passive = {name: float(system.damping[i, i]) for name, i in system.index.items()}
    units = {name: _units(system.linear[name]) for name in requests}
    held = {
        name: min(system.load[name], r.effort) if r.effort is not None else system.load[name]
        for name, r in requests.items()
    }
    for name, r in requests.items():
        if r.effort is not None and system.load[name] > r.effort * (1 + 1e-9):
            u = units[name]
            notes.append(
                Note(
                    "warning",
                    f"joint '{name}'",
                    f"gravity load up to {_sig(system.load[name])} {u.force} exceeds the force "
                    f"limit {_sig(r.effort)} {u.force}: some poses cannot be held "
                    "(try --gravcomp)",
                )
            )

    position = [n for n, r in requests.items() if r.kind == "position"]
    velocity = [n for n, r in requests.items() if r.kind == "velocity"]
    why: dict[str, str] = {}

    # Stiffness: bandwidth and sag, then the coupled stability limit.
    kp: dict[str, float] = {}
    for name in position:
        r = requests[name]
        if r.kp is not None:
            kp[name] = r.kp
            continue
        tol = _tolerance(params, system.linear[name])
        omega = 2 * math.pi * r.bandwidth_hz
        kp_bw, kp_sag = inertia[name] * omega**2, held[name] / tol
        kp[name] = max(kp_bw, kp_sag)
        why[name] = (
            f"bandwidth {r.bandwidth_hz} Hz"
            if kp_bw >= kp_sag
            else f"sag <= {tol} {units[name].position}"
        )
    chosen = [n for n in position if requests[n].kp is None]
    limit = (params.max_omega_dt / system.timestep) ** 2
    capped = _stabilise(system, kp, chosen, limit)
    for name in chosen:
        kp[name] = _sig(kp[name], up=name not in capped)
        if name in capped:
            why[name] = f"stability: omega*dt <= {params.max_omega_dt}"
            tol = _tolerance(params, system.linear[name])
            sag = held[name] / kp[name]
            if sag > tol:
                u = units[name]
                notes.append(
                    Note(
                        "warning",
                        f"joint '{name}'",
                        f"default kp limited to {kp[name]} {u.stiffness} for stability at "
                        f"timestep {system.timestep} s; expected sag {_sig(sag)} {u.position} "
                        f"> {tol}: add armature or use --gravcomp",
                    )
                )
    omega_dt = math.sqrt(max(_top_mode(system, kp)[0], 0.0)) * system.timestep
    if omega_dt > _GIVEN_OMEGA_DT:
        given = ", ".join(n for n in position if requests[n].kp is not None)
        notes.append(
            Note(
                "warning",
                "actuators",
                f"given kp ({given}) make the fastest servo mode omega*dt = {omega_dt:.2f} > 2 "
                f"at timestep {system.timestep} s: may be unstable; add armature or lower kp",
            )
        )

    # Velocity actuators: bandwidth and drift.
    kv: dict[str, float] = {}
    for name in velocity:
        r = requests[name]
        if r.kv is not None:
            kv[name] = r.kv
            continue
        omega = 2 * math.pi * r.bandwidth_hz
        kv[name] = _sig(max(inertia[name] * omega, held[name] / params.drift_tolerance), up=True)
        notes.append(
            Note(
                "info", f"joint '{name}'", f"velocity actuator kv {kv[name]} {units[name].damping}"
            )
        )

    # Damping: critical per joint, then scaled until every coupled mode is damped.
    total = {
        n: 2 * requests[n].damping_ratio * math.sqrt(kp[n] * inertia[n])
        for n in position
        if requests[n].kv is None
    }
    for name in position:
        if requests[name].kv is not None:
            kv[name] = requests[name].kv  # type: ignore[assignment]
    if total:
        zeta = min(1.0, *(requests[n].damping_ratio for n in total)) - _MODE_SLACK

        def damped(scale: float) -> dict[str, float]:
            return {n: max(0.0, scale * c - passive[n]) for n, c in total.items()}

        scale = _least_scale(lambda s: _min_zeta(system, kp, {**kv, **damped(s)}) >= zeta)
        if scale is None:
            scale = 1.0
            worst = _min_zeta(system, kp, {**kv, **damped(scale)})
            notes.append(
                Note(
                    "warning",
                    "actuators",
                    f"a coupled servo mode is damped only zeta = {worst:.2f} (given kv?)",
                )
            )
        kv.update({n: _sig(v) for n, v in damped(scale).items()})
        for name in total:
            u = units[name]
            extra = f", x{scale:.2f} for coupled modes" if scale > 1.0 else ""
            notes.append(
                Note(
                    "info",
                    f"joint '{name}'",
                    f"position servo kp {kp[name]} {u.stiffness}"
                    + (f" ({why[name]})" if name in why else " (given)")
                    + f", kv {kv[name]} {u.damping} (damping ratio "
                    f"{requests[name].damping_ratio} on {_sig(inertia[name])} {u.inertia}"
                    f"{extra})",
                )
            )
    for name in chosen:
        if name not in total:
            u = units[name]
            notes.append(
                Note(
                    "info",
                    f"joint '{name}'",
                    f"position servo kp {kp[name]} {u.stiffness} ({why[name]})",
                )
            )
    out: dict[str, tuple[float | None, float | None]] = {}
    for name, r in requests.items():
        out[name] = (kp.get(name), kv.get(name)) if r.kind == "position" else (None, kv.get(name))
    return out, notes


# -- the coupled linear system --------------------------------------------------


def _stiffness(system: ServoSystem, kp: Mapping[str, float]) -> np.ndarray:
    k = np.zeros(len(system.inertia))
    for name, value in kp.items():
        k[system.index[name]] += value
    return np.diag(k)


def _top_mode(system: ServoSystem, kp: Mapping[str, float]) -> tuple[float, np.ndarray]:
    """Largest omega^2 of M q'' + Kp q = 0 and its mode shape (M-normalised)."""
    if not kp:
        return 0.0, np.zeros(len(system.inertia))
    chol = np.linalg.cholesky(system.inertia)
    inv = np.linalg.inv(chol)
    a = inv @ _stiffness(system, kp) @ inv.T
    lam, vec = np.linalg.eigh((a + a.T) / 2)
    return float(lam[-1]), inv.T @ vec[:, -1]


def _stabilise(
    system: ServoSystem, kp: dict[str, float], chosen: list[str], limit: float
) -> set[str]:
    """Lower the chosen kp until the fastest servo mode has omega^2 <= ``limit``;
    each round lowers the joint carrying most of that mode's stiffness energy."""
    capped: set[str] = set()
    for _ in range(200):
        lam, shape = _top_mode(system, kp)
        if lam <= limit * (1 + 1e-9) or not chosen:
            break
        energy = {n: kp[n] * shape[system.index[n]] ** 2 for n in chosen}
        if sum(energy.values()) < (lam - limit) * 1.01:
            break  # the mode is the given gains' doing: warned about below
        name = max(energy, key=energy.__getitem__)
        kp[name] = max(kp[name] - (lam - limit) / shape[system.index[name]] ** 2, kp[name] / 4)
        capped.add(name)
    return capped


def _min_zeta(system: ServoSystem, kp: Mapping[str, float], kv: Mapping[str, float]) -> float:
    """Least damping ratio over the oscillating modes of the linear system."""
    n = len(system.inertia)
    damping = system.damping + _stiffness(system, kv)
    minv = np.linalg.inv(system.inertia)
    state = np.zeros((2 * n, 2 * n))
    state[:n, n:] = np.eye(n)
    state[n:, :n] = -minv @ _stiffness(system, kp)
    state[n:, n:] = -minv @ damping
    s = np.linalg.eigvals(state)
    scale = max(float(np.abs(s).max()), 1e-12)
    s = s[np.abs(s) > 1e-5 * scale]  # rigid-body modes of unservoed joints
    if s.size == 0:
        return 1.0
    return float(np.min(-s.real / np.abs(s)))


def _least_scale(ok: Callable[[float], bool]) -> float | None:
    """Least factor in [1, 10] for which ``ok`` holds (None when even 10 fails)."""
    if ok(1.0):
        return 1.0
    if not ok(_MAX_KV_SCALE):
        return None
    lo, hi = 1.0, _MAX_KV_SCALE
    for _ in range(40):
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
        if hi / lo < 1.001:
            break
    return hi


# -- helpers -------------------------------------------------------------------


@dataclass(frozen=True)
class _Units:
    force: str
    stiffness: str
    damping: str
    inertia: str
    position: str


def _units(linear: bool) -> _Units:
    if linear:
        return _Units("N", "N/m", "N s/m", "kg", "m")
    return _Units("N m", "N m/rad", "N m s/rad", "kg m^2", "rad")


def _tolerance(params: DesignParams, linear: bool) -> float:
    return params.sag_tolerance_linear if linear else params.sag_tolerance


def _sig(x: float, up: bool = False) -> float:
    """``x`` to 3 significant digits (rounded up when ``up``)."""
    if not x > 0 or not math.isfinite(x):
        return max(x, 0.0)
    exponent = math.floor(math.log10(x)) - 2
    scaled = x / 10.0**exponent
    digits = math.ceil(scaled - 1e-9) if up else round(scaled)
    return float(f"{digits}e{exponent}")
