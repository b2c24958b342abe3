"""The aggregate report of many trials: the Wilson interval against published values
and its own definition, failures grouped by step and reason, the replay command, and
the outcomes plot (a PNG matplotlib reads back)."""

from __future__ import annotations

import json
import math
import statistics
from dataclasses import asdict

import pytest
from matplotlib import image as mpimg

from urdf2mjcf.errors import OutputError
from urdf2mjcf.runner.aggregate import (
    aggregate,
    check_plot,
    plot_outcomes,
    plot_path,
    reason_of,
    summary_lines,
    wilson_interval,
)
from urdf2mjcf.runner.demo import DemoResult, StepResult

# Newcombe, "Two-sided confidence intervals for the single proportion: comparison of
# seven methods", Statistics in Medicine 17 (1998) 857-872, Table II, method 3 (score
# interval without continuity correction), and 19/20 as quoted in textbooks.
PUBLISHED = [
    (19, 20, 0.764, 0.991, 3),
    (81, 263, 0.2553, 0.3662, 4),
    (15, 148, 0.0624, 0.1605, 4),
    (0, 20, 0.0, 0.1611, 4),
    (1, 29, 0.0061, 0.1718, 4),
]


@pytest.mark.parametrize(("k", "n", "low", "high", "digits"), PUBLISHED)
def test_wilson_interval_matches_published_values(k, n, low, high, digits):
    lo, hi = wilson_interval(k, n)
    assert round(lo, digits) == low and round(hi, digits) == high


@pytest.mark.parametrize(("k", "n"), [(3, 10), (19, 20), (7, 50), (1, 2)])
def test_wilson_bounds_are_where_the_score_test_is_at_its_critical_value(k, n):
    # Definition: the bounds are the p0 at which |p - p0| / sqrt(p0 (1 - p0) / n) = z.
    z = statistics.NormalDist().inv_cdf(0.975)
    p = k / n
    for p0 in wilson_interval(k, n):
        assert abs(p - p0) / math.sqrt(p0 * (1 - p0) / n) == pytest.approx(z, rel=1e-9)


def test_wilson_interval_at_all_successes_and_none():
    assert wilson_interval(20, 20)[1] == 1.0 and wilson_interval(20, 20)[0] < 1.0
    assert wilson_interval(0, 20)[0] == 0.0 and wilson_interval(0, 20)[1] > 0.0
    with pytest.raises(ValueError):
        wilson_interval(3, 0)


STEPS = ["init", "find_handle", "close", "lower"]


def trial(seed: int, fail_at: str | None = None, message: str = "", check: bool = False) -> dict:
    """A trial dict as run_trial returns it: DemoResult.to_json() plus seed and times."""
    steps = []
    for name in STEPS:
        failed = name == fail_at
        steps.append(StepResult(name, "move", not failed, 1.0, [], message if failed else ""))
        if failed:
            break
    ok = fail_at is None and not check
    res = DemoResult(
        ok=ok,
        steps=steps,
        verdict=None,
        sim_time=2.0 * len(steps),
        wall_time=3.0,
        failed_step=fail_at or ("success check" if check else None),
        message=message if not ok else "the CTB rests in the bin",
    )
    return {**res.to_json(), "seed": seed, "trial_wall": 4.0 + seed}


def results() -> list[dict]:
    return [
        trial(0),
        trial(1, "find_handle", "the handle is not in the wrist camera's view (0.71 m off)"),
        trial(2),
        trial(3, "find_handle", "the handle is not in the wrist camera's view (0.93 m off)"),
        trial(4, "close", "the gripper closed on nothing"),
        trial(5, check=True, message="the CTB lies 12.5 mm outside the bin"),
    ]


def replay(seed: int) -> list[str]:
    return ["facility-demo", "build/imetro", "--trials", "1", "--seed", str(seed)]


def test_failures_are_counted_by_step_and_reason_with_their_seeds():
    agg = aggregate(results(), wall_time=20.0, replay=replay)
    assert (agg["trials"], agg["successes"]) == (6, 2)
    assert agg["wilson_95"] == list(wilson_interval(2, 6))
    assert agg["failures"] == [
        {
            "step": "find_handle",
            "reason": "the handle is not in the wrist camera's view (# m off)",
            "count": 2,
            "seeds": [1, 3],
        },
        {"step": "close", "reason": "the gripper closed on nothing", "count": 1, "seeds": [4]},
        {
            "step": "success check",
            "reason": "the CTB lies # mm outside the bin",
            "count": 1,
            "seeds": [5],
        },
    ]
    assert agg["failed_seeds"] == [1, 3, 4, 5]
    assert agg["replay"] == {"seed": 1, "command": replay(1)}
    assert agg["wall_time"]["all_trials"] == 20.0
    assert agg["wall_time"]["per_trial"]["max"] == 9.0  # trial_wall of seed 5
    assert agg["sim_time"]["per_trial"]["total"] == sum(r["sim_time"] for r in results())


def test_outcomes_per_step_add_up_to_the_trials():
    rows = {
        r["step"]: r for r in aggregate(results(), wall_time=1, replay=replay)["outcomes_per_step"]
    }
    assert list(rows) == [*STEPS, "success check"]
    assert rows["init"] == {"step": "init", "passed": 6, "failed": 0, "not_reached": 0}
    assert rows["find_handle"] == {
        "step": "find_handle",
        "passed": 4,
        "failed": 2,
        "not_reached": 0,
    }
    assert rows["close"] == {"step": "close", "passed": 3, "failed": 1, "not_reached": 2}
    assert rows["success check"] == {
        "step": "success check",
        "passed": 2,
        "failed": 1,
        "not_reached": 3,
    }


def test_a_crashed_trial_is_a_failure_at_error():
    crashed = {**trial(7), "ok": False, "steps": [], "failed_step": "error", "message": "boom"}
    agg = aggregate([trial(6), crashed], wall_time=1, replay=replay)
    rows = {r["step"]: r for r in agg["outcomes_per_step"]}
    assert rows["error"] == {"step": "error", "passed": 0, "failed": 1, "not_reached": 1}
    assert rows["init"]["not_reached"] == 1
    assert agg["failures"] == [{"step": "error", "reason": "boom", "count": 1, "seeds": [7]}]


def test_reason_drops_measured_numbers_only():
    assert (
        reason_of("tilted 12.5 deg, -3 mm/s, 1e-3 m, at 3.") == "tilted # deg, # mm/s, # m, at #."
    )
    assert reason_of("no 'trainer_seat_bin'") == "no 'trainer_seat_bin'"
    assert (
        reason_of("unintended contact: finger_1_link with rail_to_0.5 (3.2 mm deep)")
        == "unintended contact: finger_1_link with rail_to_0.5 (# mm deep)"
    )


def test_summary_names_rate_interval_failures_and_the_replay_command():
    text = "\n".join(summary_lines(aggregate(results(), wall_time=20, replay=replay)))
    assert "success rate: 2/6 (33 %), 95 % Wilson interval [9.7 %, 70.0 %]" in text
    assert "2 failed at 'find_handle'" in text and "(seeds 1, 3)" in text
    assert "replay seed 1: facility-demo build/imetro --trials 1 --seed 1" in text


def test_the_plot_is_a_png_beside_the_report(tmp_path):
    agg = aggregate(results(), wall_time=20, replay=replay)
    report = tmp_path / "trials.json"
    plot = plot_path(report)
    assert plot == tmp_path / "trials.png"
    assert plot_path(tmp_path / "odd.png") == tmp_path / "odd-outcomes.png"  # never the report
    plot_outcomes(agg, plot)
    pixels = mpimg.imread(plot)
    assert pixels.ndim == 3 and pixels.shape[0] > 200 and pixels.shape[1] > 400
    red = (pixels[..., 0] > 0.7) & (pixels[..., 1] < 0.3) & (pixels[..., 2] < 0.3)
    assert red.any(), "failed trials show as red bars"
    assert [p.name for p in tmp_path.iterdir()] == ["trials.png"], "no temporary file left"


def test_a_plot_we_did_not_write_is_not_replaced(tmp_path):
    report, plot = tmp_path / "r.json", tmp_path / "r.png"
    plot.write_bytes(b"my picture")
    with pytest.raises(OutputError, match="--overwrite"):
        check_plot(plot, report, False, "facility-demo")
    check_plot(plot, report, True, "facility-demo")  # --overwrite
    report.write_text(json.dumps({"generator": "facility-demo", "plot": "r.png"}))
    check_plot(plot, report, False, "facility-demo")  # ours: named by our report


def test_step_results_keep_the_fields_the_aggregate_reads():
    # The trial dict is the demo's interface: these names are what aggregate() reads.
    fields = set(asdict(StepResult("a", "move", True, 1.0)))
    assert {"name", "ok"} <= fields
    assert {"ok", "steps", "sim_time", "failed_step", "message"} <= set(trial(0))
