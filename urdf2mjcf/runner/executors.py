"""Where many independent jobs run: a local process pool, or a Ray cluster.

Both ``facility-demo --trials`` and ``urdf2mjcf batch`` hand a list of jobs and
a module-level function to :func:`run_jobs`; each job is one process-pool task
(``local``) or one Ray task (``ray``). Results come back in the order of the
jobs, whatever order they finished in, so nothing downstream depends on which
worker ran what; ``on_done`` is called in the order they finish (progress).

Ray is optional (``pip install 'mjcf-forge[ray]'``) and imported only when
asked for. Jobs and results travel by pickling, so a job names its inputs by
path (the same on every node) and returns what it made as bytes, never as
files written on the worker.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any, Literal, TypeVar

from ..errors import ConversionError

log = logging.getLogger(__name__)

J = TypeVar("J")
R = TypeVar("R")
Kind = Literal["local", "ray"]
EXECUTORS: tuple[Kind, ...] = ("local", "ray")
RAY_INSTALL = "pip install 'mjcf-forge[ray]'"


class ExecutorError(ConversionError):
    """The executor asked for cannot be used (Ray missing, no cluster at the address)."""


def run_jobs(
    fn: Callable[[J], R],
    jobs: Sequence[J],
    *,
    executor: Kind = "local",
    workers: int | None = None,
    address: str | None = None,
    on_done: Callable[[int, R], None] | None = None,
) -> list[R]:
    """``[fn(job) for job in jobs]``, run in parallel; ``on_done(index, result)`` as each ends.

    ``local``: a pool of ``workers`` spawned processes (default: one per job, at most 8).
    ``ray``: one Ray task per job, on the cluster at ``address`` or, without one, on a
    Ray instance started here with ``workers`` CPUs (stopped again at the end).
    ``fn`` must be a module-level function; an exception in a job propagates.
    """
    if executor == "local":
        return _run_local(fn, jobs, workers, on_done)
    if executor == "ray":
        return _run_ray(fn, jobs, workers, address, on_done)
    raise ExecutorError(f"unknown executor '{executor}'; use one of {', '.join(EXECUTORS)}")


def _run_local(
    fn: Callable[[J], R],
    jobs: Sequence[J],
    workers: int | None,
    on_done: Callable[[int, R], None] | None,
) -> list[R]:
    results: dict[int, R] = {}
    if not jobs:
        return []
    # spawn, not fork: MuJoCo's OpenGL contexts and thread pools do not survive a fork
    pool = ProcessPoolExecutor(
        max_workers=workers or min(len(jobs), 8), mp_context=mp.get_context("spawn")
    )
    try:
        pending = {pool.submit(fn, job): i for i, job in enumerate(jobs)}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in sorted(done, key=pending.__getitem__):
                i = pending.pop(fut)
                results[i] = fut.result()
                if on_done:
                    on_done(i, results[i])
    except BaseException:  # Ctrl-C or a failed job: the queued jobs do not start
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return [results[i] for i in range(len(jobs))]


def import_ray() -> Any:
    """The ``ray`` module, or an error that says how to install it."""
    try:
        import ray
    except ImportError:
        raise ExecutorError(
            f"--executor ray needs Ray, which is not installed: {RAY_INSTALL}",
            element="--executor",
        ) from None
    return ray


def _run_ray(
    fn: Callable[[J], R],
    jobs: Sequence[J],
    workers: int | None,
    address: str | None,
    on_done: Callable[[int, R], None] | None,
) -> list[R]:
    ray = import_ray()
    started = False
    if not ray.is_initialized():
        try:
            if address:
                ray.init(address=address, logging_level=logging.WARNING, log_to_driver=False)
            else:
                ray.init(
                    num_cpus=workers or min(max(len(jobs), 1), 8),
                    include_dashboard=False,
                    logging_level=logging.ERROR,  # our instance: no notes on its set-up
                    log_to_driver=False,  # our progress lines, not the workers' logs
                )
        except (ConnectionError, RuntimeError, ValueError) as exc:
            # Ray >= 2.59 starts clusters with token authentication; a driver connecting by
            # address sends the token only with RAY_AUTH_MODE=token, else it is refused.
            hint = (
                "; is it running (ray status), and if it uses token authentication, is "
                "RAY_AUTH_MODE=token set here with its token (see docs/scale.md)?"
                if address
                else ""
            )
            where = f"at {address}" if address else "here"
            raise ExecutorError(
                f"cannot start or reach a Ray cluster {where}: {exc}{hint}", element="--address"
            ) from None
        started = True
    try:
        task = ray.remote(num_cpus=1)(fn)  # one CPU per job, as one pool process
        refs = {task.remote(job): i for i, job in enumerate(jobs)}
        results: dict[int, R] = {}
        pending = list(refs)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    i = refs[ref]
                    results[i] = ray.get(ref)
                    if on_done:
                        on_done(i, results[i])
        except BaseException:  # Ctrl-C or a failed job: the cluster drops what is left
            for ref in pending:
                ray.cancel(ref)
            raise
        return [results[i] for i in range(len(jobs))]
    finally:
        if started:
            ray.shutdown()
