"""Replay logged commands in MuJoCo and fit the free parameters to the tracking error.

Each trajectory is cut into windows of :attr:`FitConfig.window` seconds; each window
starts from the measured state and is rolled out open-loop under the logged commands
(``mujoco.rollout``: every window and every parameter set of a finite-difference Jacobian
in one batched call). The residual is the measured minus the simulated position and
velocity of every joint, each signal scaled by its noise (the RMS of its residual after a
first fit), so that the intervals from the Jacobian are those of a least-squares fit with
white measurement noise: ``cov = s^2 (J^T J)^-1``, 95 % intervals ``+-1.96 sqrt(cov_ii)``.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from .logs import Trajectory
from .params import Applier, Param, base_joint_id, joint_ids

log = logging.getLogger(__name__)

FD_STEP = 1e-4
"""Finite-difference step of the Jacobian, as a fraction of each bound span."""
BLOCK = 0.25
START_INSIDE = 0.01
"""A start on a bound is moved this fraction of the span inside."""
"""Seconds of residual treated as one correlated block for the intervals."""

NEAR_LIMIT = 0.05
"""A step whose servo force (unclamped, from the logged state and command) is within this
fraction of its force range's half-span of a limit (or, with a delay off the log's rows,
crosses a limit before the next step) ends the fit's window; the next starts after it.
There a clamped servo drops out of an implicit integrator's damping, and the replay's
result jumps with the parameters."""
STAGES = 5
"""Fits in turn at most: the first on the whole windows, uncut, each signal weighed by its
spread; each next one weighed by the noise the last left, on the windows cut as the last
stage's values have them, until that cut no longer changes."""
MIN_WINDOW = 10
"""Steps a window between two such steps must span to be fitted."""
PADDED = 2.0
"""Steps rolled out, padding included, per step fitted, at most, in windows so cut."""
LIMITED = 0.001
"""A servo at its force limit in more than this fraction of the samples is warned of."""
MAX_CHECKED = 5000
"""Samples checked for force limits at most (evenly spread)."""
Z95 = 1.959964
"""Two-sided 95 % quantile of the normal distribution."""


@dataclass(frozen=True)
class FitConfig:
    """How the fit runs."""

    window: float = 2.0
    """Seconds of each open-loop replay, from a measured state."""
    max_evals: int = 200
    """Most Jacobian evaluations of the least-squares solver, per stage."""
    threads: int = 0
    """Rollout threads (0: the CPUs this process may use)."""


@dataclass(frozen=True)
class Tracking:
    """Tracking error of one model on some trajectories, per joint."""

    q_rms: np.ndarray
    """(njoint,) RMS position error, rad or m."""
    q_max: np.ndarray
    v_rms: np.ndarray
    """(njoint,) RMS velocity error, rad/s or m/s."""
    v_max: np.ndarray


@dataclass(frozen=True)
class FitResult:
    params: list[Param]
    x: np.ndarray
    """(p,) fitted values."""
    interval: np.ndarray
    """(p,) 95 % half-widths (inf where the data do not determine the parameter)."""
    correlation: np.ndarray
    """(p, p) correlation of the estimates."""
    at_bound: list[bool]
    evaluations: int
    """Rollouts of every window, counted in parameter sets."""


@dataclass(frozen=True)
class _Windows:
    start: np.ndarray
    """(w, nstate) initial full-physics states."""
    ctrl: np.ndarray
    """(w, history + n, nu): the commands of the ``history`` rows before each window's
    start (where a delayed sensor's replay reads them, :meth:`Replay.simulate`), then of its
    steps."""
    q: np.ndarray
    """(w, n, nj) measured positions after each step."""
    v: np.ndarray
    keep: np.ndarray
    """(w, n) whether each step is fitted (a window cut short is padded)."""


class Replay:
    """The windows of some trajectories, ready to be replayed by any parameter set."""

    def __init__(
        self,
        applier: Applier,
        trajectories: Sequence[Trajectory],
        cfg: FitConfig,
        spans: list[tuple[int, int, int]] | None = None,
    ):
        """``spans``: (trajectory, first step, steps) of each window (see :meth:`cut`);
        none: each trajectory tiled into equal windows."""
        self.applier = applier
        m = applier.base
        self.dt = float(m.opt.timestep)
        ids = joint_ids(m)
        self.qadr = np.array(m.jnt_qposadr[ids], dtype=int)
        self.vadr = np.array(m.jnt_dofadr[ids], dtype=int)
        # a floating base: each window starts from its logged state too
        b = base_joint_id(m)
        qa, va = (0, 0) if b is None else (int(m.jnt_qposadr[b]), int(m.jnt_dofadr[b]))
        self._base_q = None if b is None else slice(qa, qa + 7)
        self._base_v = None if b is None else slice(va, va + 6)
        self.nq, self.nv = m.nq, m.nv
        self.trajectories = list(trajectories)
        self.cfg = cfg
        self.steps = max(2, int(round(cfg.window / self.dt)))
        """Steps of a window at most."""
        self.history = history(applier)
        """Rows of commands before a window's start that its replay may read (a delay's
        upper bound): no window starts before this row of its trajectory."""
        steps, h = self.steps, self.history
        if spans is None:
            # one length for every window (they are replayed in one batch), at most
            # ``steps``, that tiles each trajectory's len - 1 - h steps with little left over
            length = min(
                (len(t.q) - 1 - h) // math.ceil((len(t.q) - 1 - h) / steps) for t in trajectories
            )
            spans = [
                (i, k, length)
                for i, tr in enumerate(trajectories)
                for k in range(h, len(tr.q) - length, length)  # k + length <= len - 1
            ]
        # a window starts from a sampled state, not one interpolated between samples: an
        # interpolated state is on no trajectory, and its error is replayed all window long
        spans = [(i, *_sampled_start(self.trajectories[i], k, n)) for i, k, n in spans]
        length = max(n for _, _, n in spans)
        self.spans = list(spans)
        data = mujoco.MjData(m)
        starts, ctrl, q, v, keep = [], [], [], [], []
        for i, k, n in spans:
            tr = self.trajectories[i]
            starts.append(self._start(m, data, tr, k))
            # a window cut short is padded with its last row, and not fitted there
            rows = np.minimum(np.arange(k, k + length), k + n - 1)
            ctrl.append(tr.u[np.concatenate([np.arange(k - h, k), rows])])
            q.append(tr.q[rows + 1])
            v.append(tr.v[rows + 1])
            # a row interpolated between samples is no measurement: not fitted
            sampled = np.ones(length, bool) if tr.sampled is None else tr.sampled[rows + 1]
            keep.append((np.arange(length) < n) & sampled)
        self.windows = _Windows(
            np.array(starts), np.array(ctrl), np.array(q), np.array(v), np.array(keep)
        )
        self.length = length
        nthread = cfg.threads or len(os.sched_getaffinity(0))
        self.nthread = max(1, min(nthread, 16))
        self.datas = [mujoco.MjData(m) for _ in range(self.nthread)]
        self.q_scale = np.ones(len(self.qadr))
        self.v_scale = np.ones(len(self.vadr))
        self.evaluations = 0

    def _start(self, m: Any, data: Any, tr: Trajectory, k: int) -> np.ndarray:
        """The full-physics state of ``tr``'s sample ``k``."""
        mujoco.mj_resetData(m, data)
        data.qpos[self.qadr] = tr.q[k]
        data.qvel[self.vadr] = tr.v[k]
        if self._base_q is not None and self._base_v is not None:
            if tr.base_q is None or tr.base_v is None:
                raise ValueError(f"{tr.name}: no state of the floating base")
            data.qpos[self._base_q] = tr.base_q[k]
            data.qvel[self._base_v] = tr.base_v[k]
        state = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
        mujoco.mj_getState(m, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        return state

    def cut(self, m: Any, delay: float = 0.0) -> Replay:
        """These trajectories in windows that end where ``m``'s servo forces near their
        limits (itself where none does), the logs read ``delay`` seconds late."""
        if not np.asarray(m.actuator_forcelimited, dtype=bool).any():
            return self
        spans = _cut(m, self.trajectories, self.steps, delay / self.dt, self.history)
        if spans is None:
            return self
        out = Replay(self.applier, self.trajectories, self.cfg, spans)
        out.q_scale, out.v_scale = self.q_scale, self.v_scale
        return out

    @property
    def samples(self) -> int:
        return int(self.windows.keep.sum())

    def simulate(self, xs: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurements for each parameter vector: (len(xs), w, n, nj) positions
        and velocities, the sensor delay applied.

        A sensor ``delay`` late shows at row k what was true at row k - delay / dt. So each
        window is replayed on that later grid: from the state measured at its start, each
        step under the command in force then, which for a command held between rows is
        the commands either side weighed by how long each held (linear interpolation).
        No state is interpolated; a log made by interpolating a simulation's states is
        replayed exactly where the dynamics are linear."""
        win = self.windows
        nw = len(win.start)
        models = [self.applier.model(x) for x in xs]
        batch = [mm for mm in models for _ in range(nw)]
        qa, va = 1 + self.qadr, 1 + self.nq + self.vadr
        init = np.tile(win.start, (len(xs), 1))
        steps = self.history + np.arange(self.length)
        ctrl = np.concatenate(
            [
                _interpolated(win.ctrl, steps - self.applier.delay(x) / self.dt, axis=1)
                for x in xs
            ]
        )
        with mj_rollout.Rollout(nthread=self.nthread if self.nthread > 1 else 0) as r:
            # every replay from a zero warm start: else a thread's last solution seeds the
            # next replay's constraint solver, and the residual is not a function of x alone
            warm = np.zeros((len(batch), self.nv))
            state, _ = r.rollout(batch, self.datas, init, ctrl, initial_warmstart=warm)
        self.evaluations += len(xs)
        state = state.reshape(len(xs), nw, self.length, -1)
        return state[..., qa], state[..., va]

    def residuals(self, xs: Sequence[np.ndarray]) -> np.ndarray:
        """(len(xs), N) scaled residuals."""
        q, v = self.simulate(xs)
        keep = self.windows.keep[None, :, :, None]
        rq = (q - self.windows.q[None]) / self.q_scale * keep
        rv = (v - self.windows.v[None]) / self.v_scale * keep
        return np.concatenate([rq.reshape(len(xs), -1), rv.reshape(len(xs), -1)], axis=1)

    def tracking(self, x: np.ndarray) -> Tracking:
        q, v = self.simulate([x])
        keep = self.windows.keep
        eq = np.abs(q[0] - self.windows.q)[keep]
        ev = np.abs(v[0] - self.windows.v)[keep]
        return Tracking(
            np.sqrt((eq**2).mean(axis=0)),
            eq.max(axis=0),
            np.sqrt((ev**2).mean(axis=0)),
            ev.max(axis=0),
        )


def _sampled_start(tr: Trajectory, k: int, n: int) -> tuple[int, int]:
    """The span ``(k, n)`` of ``tr`` from its first sampled row on (see
    :attr:`Trajectory.sampled`), unchanged where that leaves under :data:`MIN_WINDOW`
    steps."""
    if tr.sampled is None or tr.sampled[k]:
        return k, n
    later = np.flatnonzero(tr.sampled[k : k + n - MIN_WINDOW + 1])
    return (k, n) if not len(later) else (k + int(later[0]), n - int(later[0]))


def history(applier: Applier) -> int:
    """Rows of commands before a window's start that a replay with the applier's largest
    delay reads (0 where the delay is not free)."""
    hi = max((p.hi for p in applier.params if p.field == "delay"), default=0.0)
    return int(math.ceil(hi / float(applier.base.opt.timestep) - 1e-9))


def _cut(
    m: Any, trajectories: Sequence[Trajectory], steps: int, shift: float = 0.0, first: int = 0
) -> list[tuple[int, int, int]] | None:
    """(trajectory, first step, steps) of each window between the steps at which a servo
    of ``m`` nears a force limit, at most ``steps`` long, none starting before row
    ``first``; None where no step does. The command of step k is the one in force
    ``shift`` steps earlier (a sensor's delay: see :meth:`Replay.simulate`)."""
    limited = np.flatnonzero(np.asarray(m.actuator_forcelimited, dtype=bool))
    lo, hi = m.actuator_forcerange[limited, 0], m.actuator_forcerange[limited, 1]
    band = NEAR_LIMIT * (hi - lo) / 2
    free = m.__copy__()
    free.actuator_forcelimited[:] = 0  # the force the servo asks for, before its clamp
    d = mujoco.MjData(free)
    ids = joint_ids(m)
    qadr, vadr = m.jnt_qposadr[ids], m.jnt_dofadr[ids]
    near = []
    for tr in trajectories:
        n = len(tr.q) - 1
        u = _interpolated(tr.u, np.arange(n) - shift)
        f = np.array(
            [
                _actuator_force(free, d, qadr, vadr, tr.q[k], tr.v[k], u[k])[limited]
                for k in range(first, n)
            ]
        ).reshape(n - first, len(limited))
        close = np.minimum(np.abs(f - lo), np.abs(f - hi)) < band
        if abs(shift - round(shift)) > 1e-9:
            # a delay off the rows: each step's command is a blend of two (Replay.simulate),
            # which replays wrong a step where the force jumps across a limit, near it or not
            across = np.diff(np.sign(f - lo), axis=0) != 0
            across |= np.diff(np.sign(f - hi), axis=0) != 0
            close[:-1] |= across
            close[1:] |= across
        flags = np.ones(n, dtype=bool)  # before the commands a replay reads: not fitted
        flags[first:] = close.any(axis=1)
        near.append(flags)
    if not any(f[first:].any() for f in near):
        return None
    segments = []  # (trajectory, first step, steps) of each run of steps away from a limit
    for i, flags in enumerate(near):
        k = 0
        while k < len(flags):
            if flags[k]:
                k += 1
                continue
            end = k
            while end < len(flags) and not flags[end]:
                end += 1
            if end - k >= MIN_WINDOW:
                segments.append((i, k, end - k))
            k = end
    if not segments:
        return None  # every step near a limit: nothing is left to cut to
    # one window length for the batch, the shorter segments padded to it and the longer
    # ones split into near-equal parts (each at least MIN_WINDOW long: a length split is at
    # least twice that): the longest that rolls out at most PADDED times the steps fitted
    # (a longer window fits better; a shorter one wastes less)
    longest = min(max(n for _, _, n in segments), steps)
    lengths = sorted({min(n, steps) for _, _, n in segments if n >= 2 * MIN_WINDOW} | {longest})
    kept = sum(n for _, _, n in segments)
    cost = [sum(math.ceil(n / L) * L for _, _, n in segments) for L in lengths]
    fits = [L for L, c in zip(lengths, cost, strict=True) if c <= PADDED * kept]
    length = max(fits) if fits else lengths[int(np.argmin(cost))]
    spans = []
    for i, k, n in segments:
        parts = math.ceil(n / length)
        edges = [k + (n * j) // parts for j in range(parts + 1)]
        spans += [(i, a, b - a) for a, b in zip(edges, edges[1:], strict=False)]
    return spans


def _actuator_force(
    m: Any,
    d: Any,
    qadr: np.ndarray,
    vadr: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    u: np.ndarray,
    base: tuple[int, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """``m``'s actuator forces at a logged state (the joints', and a floating base's
    ``(joint, qpos, qvel)``; the rest at ``qpos0`` and rest) and command."""
    d.qpos[:], d.qvel[:] = m.qpos0, 0.0
    d.qpos[qadr], d.qvel[vadr], d.ctrl[:] = q, v, u
    if base is not None:
        b, bq, bv = base
        qa, va = int(m.jnt_qposadr[b]), int(m.jnt_dofadr[b])
        d.qpos[qa : qa + 7], d.qvel[va : va + 6] = bq, bv
    mujoco.mj_fwdPosition(m, d)
    mujoco.mj_fwdVelocity(m, d)
    mujoco.mj_fwdActuation(m, d)
    return d.actuator_force


def force_limited(
    m: Any, trajectories: Sequence[Trajectory], delay: float = 0.0
) -> dict[str, float]:
    """Actuator name -> the fraction of the trajectories' samples at which its force, as
    model ``m`` computes it from the logged state and the command in force then (the logs
    ``delay`` seconds late), is at its force limit; only
    those above :data:`LIMITED`. There the replay's residual jumps (a clamped servo drops
    out of an implicit integrator's damping) and the fit can stop in a local minimum."""
    limited = np.asarray(m.actuator_forcelimited, dtype=bool)
    rows = [(tr, k) for tr in trajectories for k in range(len(tr.q))]
    if not limited.any() or not rows:
        return {}
    rows = rows[:: max(1, len(rows) // MAX_CHECKED)]
    ids = joint_ids(m)
    qadr, vadr = m.jnt_qposadr[ids], m.jnt_dofadr[ids]
    b = base_joint_id(m)
    limit = np.abs(m.actuator_forcerange).min(axis=1) * (1 - 1e-9)
    d = mujoco.MjData(m)
    hits = np.zeros(m.nu)
    shift = delay / float(m.opt.timestep)
    for tr, k in rows:
        base = None
        if b is not None and tr.base_q is not None and tr.base_v is not None:
            base = (b, tr.base_q[k], tr.base_v[k])
        u = _interpolated(tr.u, k - shift)
        force = _actuator_force(m, d, qadr, vadr, tr.q[k], tr.v[k], u, base)
        hits += limited & (np.abs(force) >= limit)
    out = {}
    for a in np.flatnonzero(hits / len(rows) > LIMITED):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, int(a)) or f"actuator {a}"
        out[name] = float(hits[a] / len(rows))
    return out


def _interpolated(rows: np.ndarray, pos: Any, axis: int = 0) -> np.ndarray:
    """``rows`` read at the (fractional) row or rows ``pos`` along ``axis``, linearly
    interpolated, clamped to the first and last row."""
    n = rows.shape[axis] - 1
    p = np.clip(np.asarray(pos, dtype=float), 0.0, float(n))
    lo = np.minimum(np.floor(p).astype(int), n)
    hi = np.minimum(lo + 1, n)
    f = np.expand_dims(p - lo, tuple(range(1, rows.ndim - axis))) if p.ndim else p - lo
    return np.take(rows, lo, axis) * (1 - f) + np.take(rows, hi, axis) * f


def fit(
    replay: Replay, params: Sequence[Param], cfg: FitConfig, start: np.ndarray | None = None
) -> FitResult:
    """The least-squares fit of ``params`` on ``replay``, from ``start`` (default: their
    nominal values)."""
    from scipy.optimize import least_squares

    lo = np.array([p.lo for p in params])
    hi = np.array([p.hi for p in params])
    x0 = np.array([p.nominal for p in params]) if start is None else np.asarray(start)
    x0 = np.clip(x0, lo, hi)
    span = np.maximum(hi - lo, 1e-12)
    # a start on a bound (no friction, no armature) is moved inside: the solver's first
    # steps there see only one side of the cost
    x0 = np.clip(x0, lo + START_INSIDE * span, hi - START_INSIDE * span)

    work = replay  # the windows fitted now (see Replay.cut)

    # the solver works on z = (x - lo) / (hi - lo) in [0, 1]: one scale for every kind
    def jac_z(z: np.ndarray) -> np.ndarray:
        step = np.where(z + FD_STEP > 1.0, -FD_STEP, FD_STEP)  # step inward at an upper bound
        xs = [lo + z * span] + [
            lo + (z + np.eye(len(z))[i] * step[i]) * span for i in range(len(z))
        ]
        r = work.residuals(xs)
        return ((r[1:] - r[0]) / step[:, None]).T

    def fun_z(z: np.ndarray) -> np.ndarray:
        return work.residuals([lo + z * span])[0]

    def jac_of(x: np.ndarray) -> np.ndarray:
        return jac_z((x - lo) / span) / span

    # first with each signal scaled by its spread, then by the noise the fit leaves
    keep = replay.windows.keep
    replay.q_scale = np.maximum(replay.windows.q[keep].std(axis=0), 1e-6)
    replay.v_scale = np.maximum(replay.windows.v[keep].std(axis=0), 1e-6)
    x = x0
    used: list[Replay] = []
    for stage in range(STAGES):
        # after the first stage, the windows cut where a servo nears its force limit as the
        # model at x has them (the nominal model's cut, its gains and delay off, misleads)
        work = replay.cut(replay.applier.model(x), replay.applier.delay(x)) if stage else replay
        if stage >= 2 and work.spans == used[-1].spans:
            work = used[-1]
            break  # the cut the last stage fitted on is the fit's own: settled
        used.append(work)
        if len(params):
            sol = least_squares(
                fun_z,
                (x - lo) / span,
                jac=jac_z,
                bounds=(0.0, 1.0),
                max_nfev=cfg.max_evals,
                method="trf",
                xtol=1e-10,
                ftol=1e-10,
                gtol=1e-10,
            )
            x = lo + sol.x * span
        r = work.residuals([x])[0]
        nj = len(work.qadr)
        kept = work.windows.keep.reshape(-1)
        per = r.reshape(2, -1, nj)[:, kept]
        work.q_scale = work.q_scale * np.maximum(np.sqrt((per[0] ** 2).mean(axis=0)), 1e-9)
        work.v_scale = work.v_scale * np.maximum(np.sqrt((per[1] ** 2).mean(axis=0)), 1e-9)
        replay.q_scale, replay.v_scale = work.q_scale, work.v_scale
    interval, corr = _intervals(work, x, jac_of, len(params))
    at_bound = [
        bool(x[i] - lo[i] < 1e-6 * span[i] or hi[i] - x[i] < 1e-6 * span[i])
        for i in range(len(params))
    ]
    evaluations = replay.evaluations + sum(w.evaluations for w in used if w is not replay)
    return FitResult(list(params), x, interval, corr, at_bound, evaluations)


def _intervals(replay: Replay, x: np.ndarray, jac_of: Any, p: int) -> tuple[np.ndarray, np.ndarray]:
    if p == 0:
        return np.zeros(0), np.zeros((0, 0))
    r = replay.residuals([x])[0]
    jac = jac_of(x)
    dof = max(2 * replay.samples * len(replay.qadr) - p, 1)  # the fitted residuals
    s2 = float(r @ r) / dof
    jtj = jac.T @ jac
    scale = np.sqrt(np.maximum(np.diag(jtj), 1e-300))
    normed = jtj / np.outer(scale, scale)
    w, vecs = np.linalg.eigh(normed)
    # directions the data barely see (relative eigenvalue below 1e-10) are not determined
    good = w > 1e-10 * max(w.max(), 1e-300)
    inv = ((vecs[:, good] / w[good]) @ vecs[:, good].T) / np.outer(scale, scale)
    # the residual of a replay is correlated in time (a window starts from a noisy state):
    # the covariance is the larger of the white-noise one and the one robust to correlation
    # within blocks of BLOCK seconds (a sandwich over the blocks' score sums)
    block = max(1, min(replay.length, int(round(BLOCK / replay.dt))))
    nw, nj = replay.windows.q.shape[0], len(replay.qadr)
    nb = replay.length // block
    shaped = (2, nw, replay.length, nj)
    scores = (jac * r[:, None]).reshape(*shaped, p)[:, :, : nb * block]
    sums = scores.reshape(2, nw, nb, block, nj, p).sum(axis=(0, 3, 4)).reshape(-1, p)
    meat = sums.T @ sums
    robust = inv @ meat @ inv
    var = np.maximum(np.diag(s2 * inv), np.diag(robust))
    cov = robust.copy()
    np.fill_diagonal(cov, var)
    undetermined = np.abs(vecs[:, ~good]).max(axis=1) > 0.1 if (~good).any() else np.zeros(p, bool)
    half = Z95 * np.sqrt(np.maximum(var, 0.0))
    half[undetermined] = np.inf
    sd = np.sqrt(np.maximum(var, 1e-300))
    corr = np.clip(cov / np.outer(sd, sd), -1.0, 1.0)
    return half, corr
