"""CoACD in worker processes: a native crash or hang costs one mesh, not the conversion.

CoACD is C++ that can abort the whole process (``Assertion `d0 != d2'
failed`` in its triangle-intersection test, reached by a sliver triangle
lying within 1e-6 of another face) or run for many minutes (triangle soups).
So every decomposition runs in a worker process. The parent
(:func:`decompose_all`) hands each worker one job at a time, so it always
knows which mesh a dead or overdue worker had: a worker that dies is
replaced, one past the per-mesh timeout is killed (SIGKILL) and replaced, and
that job alone reports a failure, for which the caller uses the convex hull.

Workers are ``python -c`` subprocesses, not multiprocessing ones: spawn and
forkserver re-import the caller's ``__main__`` (re-running a user script that
has no ``if __name__ == "__main__"`` guard), and fork is unsafe in a process
that holds threads (OpenMP, MuJoCo). Messages are length-prefixed pickles
over the child's stdin and a copy of its stdout; the child points fd 1 at
stderr so that native prints cannot corrupt them. Its stderr goes to a
temporary file whose last line says why it died.

A worker imports only numpy and coacd (about 0.3 s) and is started only when
there is a decomposition that the cache does not answer.
"""

from __future__ import annotations

import json
import logging
import os
import pickle
import queue
import re
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import IO, Any

import numpy as np

logger = logging.getLogger(__name__)

Job = tuple[np.ndarray, np.ndarray, dict]
"""(float64 vertices, int64 faces, keyword arguments of ``coacd.run_coacd``)."""
Done = Callable[[int, "list[np.ndarray] | None", str], None]
"""Called with (job index, vertices of each part or None, why there are none:
``crashed (SIGABRT: ...)``, ``timed out after 120 s``, ``failed (...)`` or
``could not run (...)``)."""

START_TIMEOUT = 60.0
"""Seconds a worker may take to import numpy and coacd."""
INF = float("inf")

_HEADER = struct.Struct("<Q")
_EOF = object()
_BOOTSTRAP = (
    "import json, sys; sys.path[:] = json.loads(sys.argv[1]); "
    "from urdf2mjcf.passes.collision.worker import main; main(int(sys.argv[2]))"
)


# ---------------------------------------------------------------------------
# Messages
# ---------------------------------------------------------------------------


def _send(stream: IO[bytes], message: Any) -> None:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)
    stream.flush()


def _receive(stream: IO[bytes]) -> Any:
    """The next message, or ``_EOF`` when the other side is gone (mid-message included)."""
    header = stream.read(_HEADER.size)
    if len(header) < _HEADER.size:
        return _EOF
    (size,) = _HEADER.unpack(header)
    data = stream.read(size)
    if len(data) < size:
        return _EOF
    return pickle.loads(data)


# ---------------------------------------------------------------------------
# The worker process
# ---------------------------------------------------------------------------


def main(parent_pid: int) -> None:
    """Worker entry point: decompose jobs from stdin until it closes."""
    replies = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    _die_with_parent(parent_pid)
    import coacd

    coacd.set_log_level("error")
    _send(replies, ("ready", os.getpid()))
    jobs = sys.stdin.buffer
    while (job := _receive(jobs)) is not _EOF:
        vertices, faces, params = job
        try:
            raw = coacd.run_coacd(coacd.Mesh(vertices, faces), **params)
            reply: tuple = ("ok", [np.asarray(v, dtype=np.float64) for v, _f in raw])
        except Exception as exc:  # CoACD raises assorted errors on broken input
            reply = ("error", f"failed ({type(exc).__name__}: {exc})")
        _send(replies, reply)


def _die_with_parent(parent_pid: int) -> None:
    """On Linux, have the kernel kill this worker if the parent dies (even by SIGKILL)."""
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):  # pragma: no cover - unusual libc
            pass
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)


# ---------------------------------------------------------------------------
# The parent side
# ---------------------------------------------------------------------------


class _Worker:
    """One worker process, the job it holds and when it must be done."""

    def __init__(self, events: queue.Queue):
        self.stderr = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(
            [sys.executable, "-c", _BOOTSTRAP, json.dumps(_path()), str(os.getpid())],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.stderr,
        )
        self.ready = False
        self.job: int | None = None
        self.deadline = time.monotonic() + START_TIMEOUT
        threading.Thread(target=self._pump, args=(events,), daemon=True).start()

    def _pump(self, events: queue.Queue) -> None:
        """Forward the worker's messages to ``events``, then ``_EOF`` when it is gone."""
        stream = self.proc.stdout
        assert stream is not None
        with stream:
            while True:
                try:
                    message = _receive(stream)
                except Exception:  # a garbled message: treat the worker as dead
                    message = _EOF
                events.put((self, message))
                if message is _EOF:
                    return

    def give(self, index: int, job: Job, timeout: float) -> None:
        assert self.proc.stdin is not None
        self.stderr.seek(0)
        self.stderr.truncate()  # so a crash report names this job's trouble only
        self.job = index
        self.deadline = time.monotonic() + timeout if timeout > 0 else INF
        try:
            _send(self.proc.stdin, job)
        except OSError:
            pass  # died meanwhile: its reader reports the end

    def close(self) -> None:
        """Close stdin: an idle worker exits when it sees that."""
        try:
            if self.proc.stdin is not None:
                self.proc.stdin.close()
        except OSError:
            pass

    def stop(self, kill: bool) -> None:
        """End the process (kill: at once) and reap it, so that nothing is left running."""
        if kill:
            self.proc.kill()
        self.close()
        try:
            self.proc.wait(timeout=None if kill else 10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def death(self) -> str:
        """Why the process ended: its signal or exit code and its last words."""
        code = self.proc.wait()
        if code < 0:
            try:
                how = signal.Signals(-code).name
            except ValueError:
                how = f"signal {-code}"
        else:
            how = f"exit code {code}"
        words = _last_words(self.stderr)
        self.stderr.close()
        return f"{how}: {words}" if words else how


def _path() -> list[str]:
    """The parent's import path, so the worker finds what the parent found."""
    return [p for p in sys.path if isinstance(p, str)]


def _last_words(stream: IO[bytes]) -> str:
    stream.seek(0, os.SEEK_END)
    stream.seek(max(0, stream.tell() - 4096))
    text = stream.read().decode("utf-8", "replace")
    assertion = re.findall(r"Assertion [`'](.+?)' failed", text)
    if assertion:
        return f"Assertion `{assertion[-1]}' failed"
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1][:200] if lines else ""


def decompose_all(jobs: Sequence[Job], workers: int, timeout: float, done: Done) -> None:
    """Run every job in at most ``workers`` worker processes; ``done`` is called once
    per job, in the parent, as each ends.

    ``timeout``: seconds one job may take (0: no limit). A job whose worker
    crashes or overruns gets ``None`` and the reason; the other jobs go on in
    a fresh worker.
    """
    workers = max(1, workers)
    events: queue.Queue = queue.Queue()
    pending = deque(range(len(jobs)))
    pool: list[_Worker] = []
    cannot_start = ""  # set once starting a worker failed: start no more

    def retire(w: _Worker, kill: bool) -> None:
        pool.remove(w)
        w.stop(kill)

    try:
        while True:
            for w in pool:
                if w.ready and w.job is None and pending:
                    i = pending.popleft()
                    w.give(i, jobs[i], timeout)
            starting = sum(not w.ready for w in pool)
            while not cannot_start and len(pool) < workers and len(pending) > starting:
                try:
                    pool.append(_Worker(events))
                except OSError as exc:
                    cannot_start = f"could not run (cannot start a worker process: {exc})"
                    break
                starting += 1
            if not pool:
                for i in pending:
                    done(i, None, cannot_start)
                return
            if all(w.ready and w.job is None for w in pool):
                return  # all done; the idle workers are closed below
            wait = min(w.deadline for w in pool) - time.monotonic()
            try:
                worker, message = events.get(timeout=None if wait == INF else max(wait, 0.0))
            except queue.Empty:
                now = time.monotonic()
                for w in [w for w in pool if w.deadline <= now]:
                    retire(w, kill=True)
                    w.stderr.close()
                    if w.job is not None:
                        logger.debug("killed worker %d after %g s", w.proc.pid, timeout)
                        done(w.job, None, f"timed out after {timeout:g} s")
                    else:
                        cannot_start = f"could not run (no worker started in {START_TIMEOUT:g} s)"
                continue
            if worker not in pool:
                continue  # the end of a worker already killed
            if message is _EOF:
                retire(worker, kill=True)
                why = worker.death()
                logger.debug("worker %d ended (%s)", worker.proc.pid, why)
                if worker.job is not None:
                    done(worker.job, None, f"crashed ({why})")
                elif not worker.ready:
                    cannot_start = f"could not run (the worker process failed to start: {why})"
            elif message[0] == "ready":
                worker.ready, worker.deadline = True, INF
                logger.debug("decomposition worker %d started", message[1])
            else:
                i, worker.job, worker.deadline = worker.job, None, INF
                kind, payload = message
                assert i is not None
                done(i, payload if kind == "ok" else None, "" if kind == "ok" else str(payload))
    finally:
        for w in pool:  # idle workers exit when stdin closes; busy ones are killed
            if w.ready and w.job is None:
                w.close()
            else:
                w.proc.kill()
        for w in pool:
            w.stop(kill=False)
            w.stderr.close()
