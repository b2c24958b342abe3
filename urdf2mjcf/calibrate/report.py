"""What a calibration found, for a user: figures, warnings they can act on, JSON and HTML."""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .fit import FitResult, Tracking

WIDE = 0.25
"""An interval wider than this fraction of its value (either side) is 'not identified'."""
FLOOR = 0.002
"""...unless the interval is also narrower than this fraction of the bounds' span: a value
near zero (no friction) that the log pins down to a little is identified."""
CORRELATED = 0.95
"""Estimates correlated beyond this cannot be told apart."""

_REMEDY = {
    frozenset({"damping", "frictionloss"}): "move it over a wider range of speeds, slow and fast",
    frozenset({"armature", "frictionloss"}): "excite it faster",
    frozenset({"armature", "damping"}): "excite it at more frequencies (faster changes of speed)",
    frozenset({"armature", "kp"}): "excite it faster",
    frozenset({"damping", "kp"}): "move it through larger position steps",
    frozenset({"frictionloss", "kp"}): "move it through larger position steps",
}
_WORDS = {
    "damping": "damping",
    "frictionloss": "friction",
    "armature": "armature",
    "kp": "position gain",
    "kv": "velocity gain",
    "gain": "gain",
    "mass": "mass",
    "payload": "payload",
    "delay": "sensor delay",
}


@dataclass(frozen=True)
class Summary:
    """Everything the report says."""

    fit: FitResult
    joints: list[str]
    before_fitted: Tracking
    after_fitted: Tracking
    before_held: Tracking | None
    after_held: Tracking | None
    seconds: float
    """Wall-clock seconds of the fit."""
    samples: int
    """Time steps fitted."""
    held_name: str
    force_limited: Mapping[str, float] = field(default_factory=dict)
    """Actuator -> the fraction of the fitted samples at which its force is at its limit
    (:func:`.fit.force_limited`)."""


def rounded(x: float) -> float:
    """Six significant digits: what the data determine, and stable text."""
    return float(f"{x:.6g}")


def warnings(fit: FitResult, force_limited: Mapping[str, float] | None = None) -> list[str]:
    """Each parameter the logs do not determine, or determine only together with another,
    and each servo the logs drive into its force limit, as a sentence that says what to
    record instead."""
    out = [
        f"actuator '{name}': its force is at its limit in {100 * share:.1f} % of the fitted "
        "samples; the fit leaves out the steps where it nears the limit (the replay jumps "
        "there; see docs/calibrate.md), and a servo held at its limit tells little of its "
        "gains: record a log within the servos' force ranges (urdf2mjcf excite keeps under "
        "90 %)"
        for name, share in sorted((force_limited or {}).items())
    ]
    ps = fit.params
    for i, p in enumerate(ps):
        half, x = float(fit.interval[i]), float(fit.x[i])
        if (
            not math.isfinite(half)
            or half > WIDE * max(abs(x), 1e-9)
            and half > FLOOR * (p.hi - p.lo)
        ):
            out.append(
                f"{p.owner}: {_WORDS[p.field]} is not identified from these logs "
                f"({_number(x)} +- {_number(half)}): record a log that moves it more, or fix it "
                "(--params: false)"
            )
        if fit.at_bound[i]:
            out.append(
                f"{p.owner}: {_WORDS[p.field]} ended on its bound ({_number(x)}, bounds "
                f"[{_number(p.lo)}, {_number(p.hi)}]): widen the bounds with --params if the "
                "value is plausible, or check the log's units"
            )
    for i in range(len(ps)):
        for j in range(i + 1, len(ps)):
            if abs(fit.correlation[i, j]) < CORRELATED:
                continue
            a, b = ps[i], ps[j]
            if a.target == b.target:  # a joint and its own actuator share its name
                owner = a.owner if a.owner == b.owner else f"joint '{a.target}'"
                what = f"{owner}: {_WORDS[a.field]} and {_WORDS[b.field]}"
                remedy = _REMEDY.get(frozenset({a.field, b.field}), "excite it differently")
            else:
                what = f"the {_WORDS[a.field]} of {a.owner} and the {_WORDS[b.field]} of {b.owner}"
                remedy = "move the two separately"
            out.append(f"{what} cannot be told apart from these logs: {remedy}")
    return out


def _number(x: float) -> str:
    return f"{x:.4g}"


def _tracking(joints: Sequence[str], t: Tracking | None) -> dict[str, Any] | None:
    if t is None:
        return None
    return {
        j: {
            "q_rms": rounded(t.q_rms[k]),
            "q_max": rounded(t.q_max[k]),
            "v_rms": rounded(t.v_rms[k]),
            "v_max": rounded(t.v_max[k]),
        }
        for k, j in enumerate(joints)
    }


def improvement(before: Tracking | None, after: Tracking | None) -> float | None:
    """How many times smaller the RMS position error is, over all joints."""
    if before is None or after is None:
        return None
    b = float(np.sqrt((before.q_rms**2).mean()))
    a = float(np.sqrt((after.q_rms**2).mean()))
    return rounded(b / a) if a > 0 else None


def as_json(s: Summary) -> dict[str, Any]:
    """``report.json``'s content (``generator`` and ``files`` added by the command)."""
    fit = s.fit
    return {
        "parameters": [
            {
                "name": p.label,
                "owner": p.owner,
                "field": p.field,
                "before": rounded(p.nominal),
                "after": rounded(float(fit.x[i])),
                "interval95": None
                if not math.isfinite(fit.interval[i])
                else rounded(float(fit.interval[i])),
                "bounds": [rounded(p.lo), rounded(p.hi)],
            }
            for i, p in enumerate(fit.params)
        ],
        "tracking": {
            "fitted": {
                "before": _tracking(s.joints, s.before_fitted),
                "after": _tracking(s.joints, s.after_fitted),
            },
            "held_out": {
                "before": _tracking(s.joints, s.before_held),
                "after": _tracking(s.joints, s.after_held),
            },
        },
        "held_out_improvement": improvement(s.before_held, s.after_held),
        "held_out": s.held_name,
        "warnings": warnings(fit, s.force_limited),
        # no wall-clock time here: the same inputs give the same bytes (the command prints it)
        "cost": {
            "rollouts": fit.evaluations,
            "steps_fitted": s.samples,
        },
    }


def as_html(s: Summary, data: dict[str, Any]) -> str:
    """``report.html``: the tables of :func:`as_json` and a bar chart of held-out tracking."""
    e = html.escape

    def interval(p: dict[str, Any]) -> str:
        half = p["interval95"]
        return "not determined" if half is None else f"&plusmn;{half:g}"

    rows = "".join(
        f"<tr><td>{e(p['name'])}</td><td>{p['before']:g}</td><td>{p['after']:g}</td>"
        f"<td>{interval(p)}</td></tr>"
        for p in data["parameters"]
    )
    track = []
    for part in ("fitted", "held_out"):
        before, after = data["tracking"][part]["before"], data["tracking"][part]["after"]
        if before is None:
            continue
        for j in s.joints:
            b, a = before[j], after[j]
            track.append(
                f"<tr><td>{e(part.replace('_', ' '))}</td><td>{e(j)}</td><td>{b['q_rms']:.3g}</td>"
                f"<td>{a['q_rms']:.3g}</td><td>{b['v_rms']:.3g}</td><td>{a['v_rms']:.3g}</td></tr>"
            )
    warn = "".join(f"<li>{e(w)}</li>" for w in data["warnings"]) or "<li>none</li>"
    chart = _chart(s)
    return (
        "<!doctype html><html><head><meta charset='utf-8'><title>calibration report</title>"
        "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
        "td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}</style></head><body>"
        "<h1>Calibration report</h1>"
        f"<p>Held-out data: {e(s.held_name)}. RMS position error on it "
        f"{data['held_out_improvement'] or '?'} times smaller after calibration.</p>"
        "<h2>Parameters</h2><table><tr><th>parameter</th><th>before</th><th>after</th>"
        f"<th>95 % interval</th></tr>{rows}</table>"
        "<h2>Tracking error (RMS)</h2><table><tr><th>data</th><th>joint</th><th>q before</th>"
        f"<th>q after</th><th>v before</th><th>v after</th></tr>{''.join(track)}</table>"
        f"<h2>Held-out position error per joint</h2>{chart}"
        f"<h2>Warnings</h2><ul>{warn}</ul></body></html>\n"
    )


def _chart(s: Summary) -> str:
    """Bars of the held-out RMS position error per joint, before (grey) and after (blue),
    on a log scale."""
    if s.before_held is None or s.after_held is None:
        return "<p>no held-out data</p>"
    values = np.concatenate([s.before_held.q_rms, s.after_held.q_rms])
    lo = math.log10(max(float(values.min()), 1e-12)) - 0.5
    hi = math.log10(max(float(values.max()), 1e-12)) + 0.2
    width, row = 400, 22
    parts = []
    for k, j in enumerate(s.joints):
        y = k * 2 * row
        for n, (t, colour) in enumerate(((s.before_held, "#999"), (s.after_held, "#36c"))):
            w = width * (math.log10(max(float(t.q_rms[k]), 1e-12)) - lo) / (hi - lo)
            parts.append(
                f"<rect x='120' y='{y + n * (row - 4)}' width='{w:.1f}' height='{row - 6}' "
                f"fill='{colour}'/>"
            )
        parts.append(f"<text x='0' y='{y + row}' font-size='12'>{html.escape(j)}</text>")
    height = 2 * row * len(s.joints)
    return (
        f"<svg xmlns='http://www.w3.org/2000/svg' width='{width + 140}' height='{height}'>"
        + "".join(parts)
        + "</svg><p>grey: before, blue: after (log scale)</p>"
    )
