"""A function run in a child process of its own (``urdf2mjcf.isolated``): what MuJoCo
compiles for a stranger's model comes back, and a crash, a hang or an allocation
without end in the child is one error in the caller, which goes on."""

from __future__ import annotations

import os
import signal
import time

import pytest

from urdf2mjcf import isolated
from urdf2mjcf.errors import InputError


def test_the_value_comes_back():
    import mujoco

    def compile_box() -> object:
        return mujoco.MjModel.from_xml_string(
            "<mujoco><worldbody><geom size='1'/></worldbody></mujoco>"
        )

    m = isolated.call(compile_box, timeout=60)
    assert m.ngeom == 1 and m.geom_size[0][0] == 1.0


def test_a_conversion_error_comes_back_with_its_file_and_element():
    def refuse() -> None:
        raise InputError("too big", file="m.xml", element="<mesh>")

    with pytest.raises(isolated.ChildFailed) as info:
        isolated.call(refuse, timeout=60)
    assert (info.value.detail, info.value.file, info.value.element) == (
        "too big",
        "m.xml",
        "<mesh>",
    )


def test_a_crash_is_lost_not_ours():
    def crash() -> None:
        os.kill(os.getpid(), signal.SIGSEGV)

    with pytest.raises(isolated.ChildLost, match="Segmentation fault"):
        isolated.call(crash, timeout=60)


def test_a_hang_ends_at_the_time_limit_and_leaves_no_process(monkeypatch):
    def hang() -> None:
        time.sleep(3600)

    forked: list[int] = []
    fork = os.fork

    def recording_fork() -> int:
        pid = fork()
        if pid:
            forked.append(pid)
        return pid

    monkeypatch.setattr(os, "fork", recording_fork)
    start = time.monotonic()
    with pytest.raises(isolated.ChildLost, match="within 1 s"):
        isolated.call(hang, timeout=1)
    assert time.monotonic() - start < 10
    (pid,) = forked
    # killed and reaped: no such process (other tests in this worker may hold children)
    with open(f"/proc/{os.getpid()}/task/{os.getpid()}/children") as f:
        assert str(pid) not in f.read().split()
    with pytest.raises(ChildProcessError):
        os.waitpid(pid, os.WNOHANG)


def test_an_allocation_past_the_cap_fails_in_the_child():
    def allocate() -> int:
        return len(bytearray(8 * 2**30))

    with pytest.raises(isolated.ChildLost, match="MemoryError"):
        isolated.call(allocate, timeout=60, memory=2**30)
    assert isolated.call(lambda: len(bytearray(2**20)), timeout=60, memory=2**30) == 2**20
