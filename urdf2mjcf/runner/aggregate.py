"""What many trials add up to: a success rate with its 95 % Wilson score interval,
failures counted by step and reason, the failed seeds with the command that replays
one, wall and simulated time, and a plot of the outcomes of each step.

The Wilson interval (E. B. Wilson, JASA 22, 1927) keeps its coverage near 95 % for
the few trials and rates near 0 or 1 that a demo run gives, where the normal
approximation p +- z sqrt(p(1-p)/n) collapses to a zero-width interval at 20/20.
"""

from __future__ import annotations

import json
import re
import statistics
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, BinaryIO

from ..errors import OutputError
from ..output import Reserved, check_output_file, read_own, reserve
from ..untrusted import limit_bytes

SUCCESS_CHECK = "success check"
"""The demo's final check, after every step passed (``DemoResult.failed_step``)."""
CRASH = "error"
"""``failed_step`` of a trial that raised (see :func:`.trials.run_trial`)."""


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion, (low, high).

    ``(p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)`` with ``p = k/n`` and
    ``z`` the two-sided normal quantile of ``confidence`` (1.95996 for 95 %)."""
    if trials <= 0 or not 0 <= successes <= trials:
        raise ValueError(f"need 0 <= successes <= trials and trials > 0, got {successes}/{trials}")
    z = statistics.NormalDist().inv_cdf(0.5 + confidence / 2)
    n, p = trials, successes / trials
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * ((p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5) / denom
    # at k = 0 (k = n) the lower (upper) bound is exactly 0 (1); float rounding is not
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return low, high


_NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?!\w|\.\d)")
"""A number on its own: not the digits of a name (``finger_1_link``, ``rail_to_0.5``)."""


def reason_of(message: str) -> str:
    """A failure message with its measured numbers replaced by ``#``: trials that failed the
    same way with other values count as one reason; the names in it stay whole."""
    return _NUMBER.sub("#", message.strip()) or "(no message)"


def _step_order(results: Sequence[dict]) -> list[str]:
    names: list[str] = []
    for r in results:
        for s in r.get("steps", []):
            if s["name"] not in names:
                names.append(s["name"])
    for extra in (SUCCESS_CHECK, CRASH):  # the pseudo-steps, last
        if extra == SUCCESS_CHECK or any(r.get("failed_step") == extra for r in results):
            names.append(extra)
    return names


def step_outcomes(results: Sequence[dict]) -> list[dict]:
    """Per step, in demo order: how many trials passed it, failed at it, never reached it."""
    rows = []
    for name in _step_order(results):
        passed = failed = 0
        for r in results:
            step = next((s for s in r.get("steps", []) if s["name"] == name), None)
            if name == SUCCESS_CHECK:
                reached = all(s["ok"] for s in r.get("steps", [])) and r.get("failed_step") in (
                    None,
                    SUCCESS_CHECK,
                )
                passed += reached and bool(r["ok"])
                failed += r.get("failed_step") == SUCCESS_CHECK
            elif name == CRASH:
                failed += r.get("failed_step") == CRASH
            elif step is not None:
                passed += bool(step["ok"])
                failed += not step["ok"]
        rows.append(
            {
                "step": name,
                "passed": passed,
                "failed": failed,
                "not_reached": len(results) - passed - failed,
            }
        )
    return rows


def _stats(values: Sequence[float]) -> dict[str, float]:
    return {
        "total": sum(values),
        "mean": statistics.fmean(values),
        "min": min(values),
        "max": max(values),
    }


def aggregate(
    results: Sequence[dict], *, wall_time: float, replay: Callable[[int], list[str]]
) -> dict[str, Any]:
    """The aggregate report of ``results`` (trial dicts, in seed order).

    ``wall_time``: seconds for all trials together; ``replay(seed)``: the command line
    (argv) that replays one trial."""
    if not results:
        raise ValueError("no trials to aggregate")
    n = len(results)
    ok = sum(bool(r["ok"]) for r in results)
    low, high = wilson_interval(ok, n)
    failed = [r for r in results if not r["ok"]]
    groups: dict[tuple[str, str], list[int]] = {}
    for r in failed:
        key = (str(r.get("failed_step")), reason_of(str(r.get("message", ""))))
        groups.setdefault(key, []).append(int(r["seed"]))
    failures = [
        {"step": step, "reason": reason, "count": len(seeds), "seeds": sorted(seeds)}
        for (step, reason), seeds in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0]))
    ]
    failed_seeds = sorted(int(r["seed"]) for r in failed)
    return {
        "trials": n,
        "successes": ok,
        "success_rate": ok / n,
        "wilson_95": [low, high],
        "failures": failures,
        "failed_seeds": failed_seeds,
        "replay": (
            {"seed": failed_seeds[0], "command": replay(failed_seeds[0])} if failed_seeds else None
        ),
        "outcomes_per_step": step_outcomes(results),
        "wall_time": {
            "all_trials": wall_time,
            "per_trial": _stats([float(r.get("trial_wall", r["wall_time"])) for r in results]),
        },
        "sim_time": {"per_trial": _stats([float(r["sim_time"]) for r in results])},
    }


def summary_lines(agg: dict[str, Any]) -> list[str]:
    """The aggregate for a terminal."""
    import shlex

    low, high = agg["wilson_95"]
    wall, sim = agg["wall_time"], agg["sim_time"]["per_trial"]
    lines = [
        f"success rate: {agg['successes']}/{agg['trials']} ({100 * agg['success_rate']:.0f} %), "
        f"95 % Wilson interval [{100 * low:.1f} %, {100 * high:.1f} %]"
    ]
    for f in agg["failures"]:
        seeds = ", ".join(map(str, f["seeds"]))
        lines.append(f"  {f['count']} failed at '{f['step']}': {f['reason']} (seeds {seeds})")
    if agg["replay"]:
        lines.append(f"replay seed {agg['replay']['seed']}: {shlex.join(agg['replay']['command'])}")
    per = wall["per_trial"]
    lines.append(
        f"wall time: {wall['all_trials']:.1f} s for all trials "
        f"({per['mean']:.1f} s per trial, {per['min']:.1f}-{per['max']:.1f} s); "
        f"simulated: {sim['total']:.1f} s ({sim['mean']:.1f} s per trial)"
    )
    return lines


def plot_path(report: Path) -> Path:
    """Where the plot of a JSON report goes: beside it, ``.png`` for its suffix (a report
    named ``x.png`` itself gets ``x-outcomes.png``)."""
    if report.suffix.lower() == ".png":
        return report.with_name(f"{report.stem}-outcomes.png")
    return report.with_suffix(".png")


def check_plot(plot: Path, report: Path, overwrite: bool, generator: str) -> None:
    """Before the work: refuse to replace a file at ``plot`` that we did not write.

    The plot is ours when the report beside it is ours and names it as its ``"plot"``."""
    if plot.is_dir():
        raise OutputError("is a folder; the plot of the report goes there", file=plot)

    def ours(_: BinaryIO) -> bool:
        data = read_own(report, lambda f: json.loads(f.read(limit_bytes("report") + 1)))
        return (
            isinstance(data, dict)
            and data.get("generator") == generator
            and data.get("plot") == plot.name
        )

    not_ours = f"is not the plot of an earlier {generator} report"
    check_output_file(plot, overwrite, ours, not_ours)


def plot_outcomes(agg: dict[str, Any], path: Path | Reserved) -> None:
    """A PNG of the outcomes per step (passed, failed, not reached), written atomically."""
    import matplotlib

    matplotlib.use("Agg")  # headless; before pyplot is imported
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    rows = agg["outcomes_per_step"]
    names = [r["step"] for r in rows]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.32 * len(names) + 3), 4.2), dpi=100)
    bottom = [0] * len(rows)
    for key, label, colour in (
        ("passed", "passed", "#2e7d32"),
        ("failed", "failed here", "#c62828"),
        ("not_reached", "not reached", "#bdbdbd"),
    ):
        values = [r[key] for r in rows]
        ax.bar(names, values, bottom=bottom, label=label, color=colour)
        bottom = [b + v for b, v in zip(bottom, values, strict=True)]
    low, high = agg["wilson_95"]
    ax.set_title(
        f"{agg['successes']}/{agg['trials']} trials succeeded "
        f"(95 % Wilson interval {100 * low:.0f}-{100 * high:.0f} %)"
    )
    ax.set_ylabel("trials")
    ax.set_ylim(0, agg["trials"])
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.tick_params(axis="x", labelrotation=60)
    for tick in ax.get_xticklabels():
        tick.set_horizontalalignment("right")
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")  # off the bars
    fig.tight_layout()
    # the reserved file of the caller (who renames it), or our own: named with our process
    # id, so that one a kill -9 leaves is removed by the next run (output.clean_stale)
    slot = path if isinstance(path, Reserved) else reserve(Path(path))
    try:
        fig.savefig(slot.tmp, format="png", metadata={"Software": None})  # byte-stable
        if slot is not path:
            slot.commit()
    finally:
        if slot is not path:
            slot.discard()
        plt.close(fig)
