"""``rover-drive BUNDLE --task deliver [--trials N]``: one deliver run (its report adds
``task``), or seeded trials on an executor (``..executors``) judged with the demo's
aggregate (success rate, Wilson interval, failures by reason)."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import click

from ..executors import Kind
from ..task_kinds import family

TASKS = tuple(family("task"))
"""The ``--task`` choices: the registry's ``task`` kinds."""


@dataclass(frozen=True)
class TaskRun:
    """How ``--task`` was asked for."""

    scene: Path
    task: str
    trials: int
    seed: int | None
    workers: int | None
    executor: Kind


def check_task_options(
    ctx: click.Context, task: str | None, trials: int | None, seed: int | None
) -> None:
    """Usage errors of ``--task``/``--trials``/``--seed`` before anything runs."""
    if task is None:
        for name, given in (("--trials", trials is not None), ("--seed", seed is not None)):
            if given:
                raise click.UsageError(f"{name} needs --task deliver")
        return
    src = click.core.ParameterSource
    if not trials:
        for name in ("workers", "executor"):
            if ctx.get_parameter_source(name) not in (src.DEFAULT, None):
                raise click.UsageError(f"--{name} runs --trials; give --trials N")
    dropped = ("distance", "speed", "turn", "rate", "arm", "settle", "names", "record", "view")
    for name in (*dropped, "foxglove", "plot"):
        if ctx.get_parameter_source(name) not in (src.DEFAULT, None):
            flag = "--rover" if name == "names" else f"--{name}"
            raise click.UsageError(f"{flag} does not go with --task {task}")


def task_command(run: TaskRun, report: Path | None, overwrite: bool) -> None:
    """The whole ``--task`` command: the report reserved before running (all or nothing),
    exit 1 when the task (or a trial) failed."""
    from ... import output as out

    if report is not None:
        out.check_file(report, overwrite, "rover-drive")
    with out.reserved_file(report) if report else _nothing() as report_to:
        ok = run_task(run, report_to)
        if report_to is not None:
            report_to.commit()
    if not ok:
        sys.exit(1)


class _nothing:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def run_task(run: TaskRun, report_to: object) -> bool:
    """Run the task (or its trials), print what it did, write the report to
    ``report_to`` (a reserved file); whether it succeeded (every trial, with trials)."""
    from ... import output as out
    from .roles import RoverError

    try:
        if run.trials:
            data, ok = _trials(run)
        else:
            data, ok = _once(run)
    except RoverError as exc:
        raise click.ClickException(str(exc)) from None
    if report_to is not None:
        report_to.write(out.json_bytes(data, "rover-drive"))  # type: ignore[attr-defined]
    return ok


def _once(run: TaskRun) -> tuple[dict, bool]:
    from .deliver import run_deliver
    from .sim import RoverSim

    sim = RoverSim(run.scene)
    res, reports = run_deliver(sim, seed=run.seed, log=click.echo)
    warnings = sim.warnings()
    data = {
        "scene": str(run.scene),
        "tasks": reports,
        "warnings": warnings,
        "seed": run.seed,
        "task": res.task_json(),
    }
    if warnings:
        raise click.ClickException(f"MuJoCo warned while driving: {warnings}")
    return data, res.success


def _replay(run: TaskRun) -> object:
    def replay(seed: int) -> list[str]:
        return ["rover-drive", str(run.scene), "--task", run.task, "--seed", str(seed)]

    return replay


def _trials(run: TaskRun) -> tuple[dict, bool]:
    from ..aggregate import aggregate, summary_lines
    from ..executors import ExecutorError, run_jobs
    from .deliver import deliver_trial
    from .sim import RoverSim

    _check = RoverSim(run.scene)  # a bad bundle: one error line, before any worker starts
    from .deliver import check_pair

    check_pair(_check)
    del _check
    first = run.seed or 0
    seeds = list(range(first, first + run.trials))
    jobs = [(str(Path(run.scene).resolve()), s) for s in seeds]

    def done(_: int, result: dict) -> None:
        t = result.get("task") or {}
        verdict = "ok" if result["ok"] else f"FAILED ({result['message']})"
        click.echo(
            f"seed {result['seed']}: {verdict}; delivered {t.get('delivered_kg', 0):.2f} of "
            f"{t.get('collected_kg', 0):.2f} kg, printed {t.get('printed_path_m', 0):.3f} m",
            err=True,
        )

    start = time.perf_counter()
    try:
        results = run_jobs(
            deliver_trial, jobs, executor=run.executor, workers=run.workers, on_done=done
        )
    except ExecutorError as exc:
        raise click.ClickException(str(exc)) from None
    agg = aggregate(results, wall_time=time.perf_counter() - start, replay=_replay(run))  # type: ignore[arg-type]
    for line in summary_lines(agg):
        click.echo(line)
    closing = [r for r in results if r.get("task") and _closes(r["task"])]
    click.echo(f"mass balance closing within 1 %: {len(closing)}/{len(results)}")
    data = {
        "scene": str(run.scene),
        "task": run.task,
        "executor": run.executor,
        "seeds": seeds,
        "aggregate": agg,
        "trials": [{k: v for k, v in r.items() if k != "log"} for r in results],
        "python": sys.version.split()[0],
    }
    return data, agg["successes"] == agg["trials"]


def _closes(task: dict) -> bool:
    """Whether collected = delivered + spilled + still carried, within ``BALANCE``."""
    from .deliver import BALANCE

    parts = task["delivered_kg"] + task["spilled_kg"] + task["carried_kg"]
    return (
        task["collected_kg"] > 0
        and abs(task["collected_kg"] - parts) <= BALANCE * task["collected_kg"]
    )
