"""A function run in a child process of its own: SIGTERM and Ctrl-C end the caller at
any point, and the work is bounded in time and address space.

MuJoCo parses and compiles a model in one long C call; while it runs, Python's
signal handlers cannot (SIGTERM would wait for the call to end), and a model
written by a stranger can make it allocate without end or crash. So the call runs
in a forked child. The parent waits in a system call that signals interrupt: its
handlers run as usual (staged output unwinds; the exit code is 143 or 130) and the
child is killed on the way out. The child dies with the parent (Linux's
``PR_SET_PDEATHSIG``), is killed when its time is up, and has its address space
capped. Its result comes back pickled through a pipe (the child is this program;
nothing else writes to the pipe).

Where processes cannot be forked the function runs in the caller, unbounded.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import os
import pickle
import resource
import selectors
import signal
import sys
import time
from collections.abc import Callable
from typing import Any, TypeVar

from .errors import ForgeError

T = TypeVar("T")

_CHUNK = 1 << 20


class ChildFailed(Exception):
    """The function raised a :class:`~urdf2mjcf.errors.ForgeError` in the child: its parts."""

    def __init__(self, detail: str, file: str | None, element: str | None):
        super().__init__(detail)
        self.detail, self.file, self.element = detail, file, element


class ChildLost(Exception):
    """The child gave no result: its time ran out, it died (a crash, out of memory)
    or it raised something other than a :class:`~urdf2mjcf.errors.ForgeError`."""


def can_fork() -> bool:
    return hasattr(os, "fork") and sys.platform != "win32"


def call(fn: Callable[[], T], *, timeout: float, memory: int | None = None) -> T:
    """``fn()`` computed in a forked child within ``timeout`` seconds and ``memory``
    bytes of address space beyond what this process holds; its value, pickled back.
    :class:`ChildFailed` when it raised a :class:`~urdf2mjcf.errors.ForgeError`, :class:`ChildLost`
    when it gave nothing. SIGTERM or Ctrl-C meanwhile ends the child and raises here
    as the caller's handlers say."""
    if not can_fork():
        return fn()
    for stream in (sys.stdout, sys.stderr):  # nothing buffered is written twice
        with contextlib.suppress(Exception):
            stream.flush()
    read_end, write_end = os.pipe()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: never returns into the caller's frames
        code = 0
        try:
            os.close(read_end)
            _child_start(parent, memory)
            _send(write_end, _outcome(fn))
        except BaseException:
            code = 70
        finally:
            os._exit(code)
    os.close(write_end)
    try:
        data = _receive(read_end, timeout)
    finally:
        os.close(read_end)
        status = _end(pid)
    return _result(data, status)


def _child_start(parent: int, memory: int | None) -> None:
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, signal.SIG_DFL)  # the parent handles them; we just end
    faulthandler.disable()  # a crash is one error line of the parent's, not a stack dump
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the line above
        os._exit(1)
    if memory is not None:
        _cap_address_space(memory)


def _cap_address_space(memory: int) -> None:
    """At most ``memory`` bytes mapped beyond what the child holds at the fork (the
    caller's libraries and data, shared until written)."""
    try:
        with open("/proc/self/statm") as f:
            held = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = held + memory
    for limit in (soft, hard):
        if limit != resource.RLIM_INFINITY:
            cap = min(cap, limit)
    with contextlib.suppress(ValueError, OSError):
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))


def _outcome(fn: Callable[[], Any]) -> tuple[str, Any]:
    try:
        return ("value", fn())
    except ForgeError as exc:
        return ("failed", (exc.detail, exc.file, exc.element))
    except BaseException as exc:  # MuJoCo's own failures: out of memory, a bad_alloc
        return ("lost", f"{type(exc).__name__}: {exc}")


def _send(fd: int, outcome: tuple[str, Any]) -> None:
    try:
        data = pickle.dumps(outcome, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as exc:  # an unpicklable value: say so rather than nothing
        data = pickle.dumps(("lost", f"cannot send the result: {exc}"))
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _receive(fd: int, timeout: float) -> bytes:
    deadline = time.monotonic() + timeout
    chunks: list[bytes] = []
    with selectors.DefaultSelector() as waiting:
        waiting.register(fd, selectors.EVENT_READ)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise ChildLost(f"it did not finish within {timeout:g} s")
            # a signal interrupts the wait: its handler runs here, what it raises ends us
            if not waiting.select(left):
                continue
            chunk = os.read(fd, _CHUNK)
            if not chunk:
                return b"".join(chunks)
            chunks.append(chunk)


def _end(pid: int) -> int | None:
    """The child killed if it still runs, and reaped: its wait status."""
    try:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done == 0:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            _, status = os.waitpid(pid, 0)
        return status
    except ChildProcessError:
        return None


def _result(data: bytes, status: int | None) -> Any:
    if not data:
        how = ""
        if status is not None and os.WIFSIGNALED(status):
            how = f" ({signal.strsignal(os.WTERMSIG(status)) or 'a signal'})"
        raise ChildLost(f"it ended without a result{how}: a crash, or out of memory")
    kind, payload = pickle.loads(data)  # written by our own child, above
    if kind == "value":
        return payload
    if kind == "failed":
        raise ChildFailed(*payload)
    raise ChildLost(str(payload))
