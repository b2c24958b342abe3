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

import contextlib
import ctypes
import itertools
import logging
import multiprocessing as mp
import os
import shutil
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any, Literal, TypeVar

from ..errors import ExecutorError

log = logging.getLogger(__name__)

J = TypeVar("J")
R = TypeVar("R")
Kind = Literal["local", "ray"]
EXECUTORS: tuple[Kind, ...] = ("local", "ray")
RAY_INSTALL = "pip install 'mjcf-forge[ray]'"
STOP_GRACE = 2.0
"""Seconds a worker has to end on SIGTERM (removing its temporary folders) before it is
killed; the whole stop stays well within the 5 s a SIGTERM or Ctrl-C is given."""


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
    size = workers or min(len(jobs), 8)
    # spawn, not fork: MuJoCo's OpenGL contexts and thread pools do not survive a fork
    pool = ProcessPoolExecutor(
        max_workers=size,
        mp_context=mp.get_context("spawn"),
        initializer=_worker_start,
        initargs=(os.getpid(),),
    )
    todo = iter(enumerate(jobs))
    pending: dict[Any, int] = {}
    try:
        # Ctrl-C and SIGTERM act only between the pool's calls: one raised inside them
        # (a lock taken, not given back) hangs the pool's own thread, and the exit with it.
        with _signals_between() as check:
            while True:
                for i, job in itertools.islice(todo, 2 * size - len(pending)):
                    pending[pool.submit(fn, job)] = i  # a few queued: no 100,000 futures
                if not pending:
                    break
                done, _ = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                check()
                for fut in sorted(done, key=pending.__getitem__):
                    i = pending.pop(fut)
                    results[i] = fut.result()
                    if on_done:
                        on_done(i, results[i])
    except BaseException:  # Ctrl-C, SIGTERM or a failed job: no job goes on running
        _stop_pool(pool)
        raise
    pool.shutdown()
    return [results[i] for i in range(len(jobs))]


# -- workers end with the run ------------------------------------------------------------

_cleanups: list[Path] = []
"""In a worker: folders to remove if it is told to stop (SIGTERM) mid-job."""


@contextlib.contextmanager
def removed_on_stop(folder: Path) -> Iterator[Path]:
    """In a worker: remove ``folder`` too when the worker is stopped during the block."""
    _cleanups.append(folder)
    try:
        yield folder
    finally:
        _cleanups.remove(folder)


def _worker_start(parent: int) -> None:
    """In each pool process: Ctrl-C is the parent's to handle (the terminal sends it to
    every process of the group); SIGTERM, from the parent stopping the pool, removes the
    job's temporary folders and ends the process at once; on Linux the kernel kills it
    if the parent dies, even by SIGKILL, so no worker outlives its run."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _worker_terminated)
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the line above
        os._exit(1)


def _worker_terminated(signum: int, frame: Any) -> None:
    for folder in list(_cleanups):
        shutil.rmtree(folder, ignore_errors=True)
    os._exit(128 + signum)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """End every process of ``pool`` now: queued jobs cancelled, running ones stopped
    (SIGTERM, then SIGKILL after :data:`STOP_GRACE` seconds), all reaped. A second
    Ctrl-C or SIGTERM meanwhile waits (it would cut the stop short into orphans)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    with _signals_held():
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            with contextlib.suppress(Exception):
                proc.terminate()
        for proc in procs:
            with contextlib.suppress(Exception):
                proc.join(STOP_GRACE)
                if proc.is_alive():
                    proc.kill()
                    proc.join(STOP_GRACE)


@contextlib.contextmanager
def _signals_between() -> Iterator[Callable[[], None]]:
    """Hold Ctrl-C and SIGTERM while the block runs; the check it yields acts on one
    that came (the handler it would have met: Terminated, KeyboardInterrupt)."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    got: list[int] = []
    watched = (signal.SIGINT, signal.SIGTERM)
    previous: dict[int, Any] = {
        s: signal.signal(s, lambda signum, frame: got.append(signum)) for s in watched
    }

    def restore() -> None:
        for s, handler in previous.items():
            signal.signal(s, handler)

    def check() -> None:
        if not got:
            return
        restore()
        handler = previous[got[0]]
        if callable(handler):
            handler(got[0], None)  # raises, as it would have
        elif handler == signal.SIG_DFL:
            if got[0] == signal.SIGINT:
                raise KeyboardInterrupt
            signal.raise_signal(got[0])

    try:
        yield check
    finally:
        restore()


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


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
