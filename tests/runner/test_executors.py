"""Executors: results in the order of the jobs whatever order they finish in; Ray is
optional with an error that says how to install it; seeded trials give the same
verdicts on the local process pool and on a local Ray instance (2 CPUs)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from urdf2mjcf.runner.cli import facility_demo_command
from urdf2mjcf.runner.executors import ExecutorError, run_jobs
from urdf2mjcf.runner.trials import TrialJob, run_trial, run_trials

ROOT = Path(__file__).resolve().parents[2]
RECIPE = ROOT / "recipes" / "imetro.yaml"
WAYPOINTS = ROOT / "recipes" / "demo" / "imetro.yaml"
VERDICT = ("seed", "ok", "failed_step", "message", "verdict", "sim_time", "steps", "offsets")
"""What a trial decides: everything but its wall times and log."""


def _wait_for_the_other(job: tuple[int, str]) -> int:
    """Job 0 ends only after the caller has seen job 1 end: they finish in the reverse
    of their order, whatever the machine's load."""
    index, folder = job
    if index == 0:
        seen = Path(folder) / "seen-1"  # written by the caller's progress callback
        deadline = time.monotonic() + 120
        while not seen.exists():
            if time.monotonic() > deadline:
                raise TimeoutError("the caller never saw job 1 end")
            time.sleep(0.02)
    return index * 10


def test_local_results_come_in_job_order_and_progress_in_finishing_order(tmp_path):
    finished: list[tuple[int, int]] = []

    def on_done(i: int, result: int) -> None:
        finished.append((i, result))
        (tmp_path / f"seen-{i}").write_text("")

    jobs = [(0, str(tmp_path)), (1, str(tmp_path))]
    results = run_jobs(_wait_for_the_other, jobs, workers=2, on_done=on_done)
    assert results == [0, 10]
    assert finished == [(1, 10), (0, 0)]


def test_without_ray_installed_the_ray_executor_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # what `import ray` sees where it is absent
    with pytest.raises(ExecutorError, match=r"pip install 'mjcf-forge\[ray\]'"):
        run_jobs(abs, [1], executor="ray")


def test_an_unknown_executor_is_an_error():
    with pytest.raises(ExecutorError, match="use one of local, ray"):
        run_jobs(abs, [1], executor="dask")  # type: ignore[arg-type]


def test_a_trial_that_raises_is_a_failed_trial_not_the_end_of_the_run(tmp_path):
    res = run_trial(TrialJob(str(tmp_path / "nope.yaml"), str(ROOT), str(WAYPOINTS), 3, False))
    assert not res["ok"] and res["failed_step"] == "error" and res["seed"] == 3
    assert "nope.yaml" in res["message"]
    assert res["frames"] == {} and res["log"], "the traceback is in the trial's log"


# -- seeded trials on both executors (slow: each trial builds and runs the demo) ---------


@pytest.fixture(scope="module")
def facility(imetro_bundle: Path) -> Path:
    return imetro_bundle


def _decided(results: list[dict]) -> list[dict]:
    def step(s: dict) -> dict:  # a planned move's planning time is a wall time too
        plan = {k: v for k, v in (s.get("plan") or {}).items() if k != "planning_time_s"}
        return {**s, "plan": plan}

    return [
        {k: [step(s) for s in r[k]] if k == "steps" else r[k] for k in VERDICT} for r in results
    ]


@pytest.mark.slow
def test_same_seeds_give_the_same_verdicts_on_the_local_pool_and_on_ray(facility, tmp_path):
    pytest.importorskip("ray")
    local = run_trials(RECIPE, ROOT, WAYPOINTS, [0, 1], workers=2, frames=tmp_path / "local")

    report = tmp_path / "ray.json"
    res = CliRunner().invoke(
        facility_demo_command,
        [str(facility), "--trials", "2", "--seed", "0", "--executor", "ray", "--workers", "2"]
        + ["--report", str(report), "--frames", str(tmp_path / "ray")],
    )
    assert res.exit_code in (0, 1), res.output
    data = json.loads(report.read_text())
    assert _decided(data["trials"]) == _decided(local)
    assert data["executor"] == "ray" and data["plot"] == "ray.png"
    assert (tmp_path / "ray.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    agg = data["aggregate"]
    assert agg["trials"] == 2 and agg["successes"] == sum(r["ok"] for r in local)
    assert res.exit_code == (0 if agg["successes"] == 2 else 1)
    # one progress line per finished trial, and the pictures of each seed came back
    assert (
        sum(line.startswith(("[1/2] seed", "[2/2] seed")) for line in res.output.splitlines()) == 2
    )
    for seed in (0, 1):
        local_frames = sorted(p.name for p in (tmp_path / "local" / f"seed-{seed}").iterdir())
        ray_frames = sorted(p.name for p in (tmp_path / "ray" / f"seed-{seed}").iterdir())
        assert local_frames and local_frames == ray_frames


@pytest.mark.slow
def test_facility_demo_without_ray_refuses_the_ray_executor_before_running(facility, tmp_path):
    code = (
        "import sys; sys.modules['ray'] = None; "
        "from urdf2mjcf.cli import facility_demo_main; facility_demo_main()"
    )
    report = tmp_path / "r.json"
    proc = subprocess.run(
        [sys.executable, "-c", code, str(facility), "--trials", "2", "--executor", "ray"]
        + ["--report", str(report)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and "pip install 'mjcf-forge[ray]'" in lines[0], proc.stderr
    assert list(tmp_path.iterdir()) == []

    res = CliRunner().invoke(facility_demo_command, [str(facility), "--executor", "ray"])
    assert res.exit_code == 2 and "--executor ray runs --trials" in res.output, res.output
