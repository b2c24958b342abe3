"""Running our commands as an attacker's victim would: in a fresh process, with a
time limit and a memory limit, and checking the error contract and that nothing
happened on disk that should not have."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ENTRY = {
    "urdf2mjcf": "urdf2mjcf_main",
    "make-facility": "make_facility_main",
    "facility-demo": "facility_demo_main",
    "rover-drive": "rover_drive_main",
}
ROOT = Path(__file__).resolve().parents[2]

MEMORY_LIMIT = 3 * 2**30
"""Address space a probe may use: a conversion needs well under this; a /dev/zero
read or an alias bomb would go far past it (MuJoCo and numpy map a lot, so this is
the address space, not the resident memory)."""


@dataclass
class Result:
    returncode: int
    stdout: str
    stderr: str
    seconds: float


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run(
    command: str,
    *args: str,
    cwd: Path,
    timeout: float = 120,
    env: dict[str, str] | None = None,
    memory: bool = True,
) -> Result:
    """``command ARGS`` run as a user runs it; fails the test (TimeoutExpired) when it
    takes longer than ``timeout`` seconds."""
    entry = ENTRY[command]
    code = f"from urdf2mjcf.cli import {entry}; {entry}()"
    full_env = {**os.environ, **(env or {})}
    start = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=timeout,
        env=full_env,
        stdin=subprocess.DEVNULL,
        preexec_fn=_limit_memory if memory else None,
    )
    return Result(proc.returncode, proc.stdout, proc.stderr, time.monotonic() - start)


def assert_one_error(res: Result, *needles: str) -> str:
    """Exit 2, exactly one ``error:`` line on stderr holding every needle, no traceback,
    never the last-resort 'internal error'."""
    assert res.returncode == 2, (res.returncode, res.stderr[-2000:])
    assert "Traceback" not in res.stderr, res.stderr[-2000:]
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error: ")]
    assert len(errors) == 1, res.stderr[-2000:]
    line = errors[0]
    assert "internal error" not in line, line
    for needle in needles:
        assert needle in line, (needle, line)
    return line


def snapshot(*folders: Path) -> dict[str, bytes | None]:
    """Every file (its bytes) and folder (None) under ``folders``, symlinks as their
    target text: compare two snapshots to see that nothing changed."""
    out: dict[str, bytes | None] = {}
    for folder in folders:
        for p in sorted(folder.rglob("*")):
            if p.is_symlink():
                out[str(p)] = b"-> " + os.readlink(p).encode()
            elif p.is_file():
                out[str(p)] = p.read_bytes()
            else:
                out[str(p)] = None
    return out
