"""A poisoned mesh-cache entry, through the real command: names that escape the
output, side files that are a device or a FIFO, a note with escape codes, an entry
that is a symlink to a user's file. Each run rebuilds what it cannot trust and
succeeds; nothing outside the output changes; no probe hangs or fills memory.

Entries are made by a real conversion of a textured OBJ (its .mtl names a PNG),
then edited as an attacker with write access to a shared cache folder would.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest
from lxml import etree

from . import attack

MESHES = Path(__file__).resolve().parents[1] / "data" / "meshes"
MAGIC = b"urdf2mjcf-mesh\0\0"
URDF = """<robot name="poisoned">
  <link name="base">
    <visual><geometry><mesh filename="meshes/textured_quad.obj"/></geometry></visual>
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
</robot>
"""
ESCAPE = "../../../../../../x/victim.txt"
"""The issue's payload: six levels up from ``<stage>/assets``."""
PEAK_RSS = 1536 * 2**20
"""Resident memory a probe may reach: a conversion of this robot needs a few hundred MB;
reading /dev/zero would take it to the 3 GiB address-space limit."""
TIMEOUT = 120


# -- the entry format, as an attacker reads and writes it ------------------------------


def unpack(data: bytes) -> tuple[dict, dict[str, bytes]]:
    (size,) = struct.unpack_from("<Q", data, len(MAGIC))
    base = len(MAGIC) + 8 + size
    meta = json.loads(data[len(MAGIC) + 8 : base])
    raw = {
        name: data[base + offset : base + offset + nbytes]
        for name, (_, _, offset, nbytes) in meta["arrays"].items()
    }
    return meta, raw


def pack(meta: dict, raw: dict[str, bytes]) -> bytes:
    layout, chunks, offset = {}, [], 0
    old = meta["arrays"]
    for name, data in raw.items():
        dtype, shape = old[name][:2] if name in old else ("|u1", [len(data)])
        if dtype == "|u1":
            shape = [len(data)]
        layout[name] = [dtype, shape, offset, len(data)]
        chunks.append(data + bytes(-len(data) % 8))
        offset += len(data) + (-len(data) % 8)
    header = json.dumps({**meta, "arrays": layout}).encode()
    header += b" " * (-len(header) % 8)
    return b"".join([MAGIC, struct.pack("<Q", len(header)), header, *chunks])


# -- a robot, its cache, a probe ------------------------------------------------------


class Setup:
    def __init__(self, tmp: Path):
        self.tmp = tmp
        self.robot = tmp / "robot"
        (self.robot / "meshes").mkdir(parents=True)
        for name in ("textured_quad.obj", "textured_quad.mtl", "quadrants.png"):
            shutil.copy(MESHES / name, self.robot / "meshes" / name)
        self.urdf = self.robot / "robot.urdf"
        self.urdf.write_text(URDF)
        self.cache = tmp / "cache"
        # deep, so that the payload's six '..' stay inside tmp
        self.out = tmp / "a" / "b" / "c" / "d" / "out"
        self.out.parent.mkdir(parents=True)
        self.victims = [tmp / "x" / "victim.txt", tmp / "a" / "x" / "victim.txt"]
        for victim in self.victims:
            victim.parent.mkdir(parents=True, exist_ok=True)
            victim.write_text("the user's file\n")

    def entry(self) -> Path:
        (entry,) = (self.cache / "meshes").glob("*.bin")
        return entry

    def convert(self, out: Path | None = None) -> tuple[attack.Result, int]:
        return run_measured(
            "urdf2mjcf",
            str(self.urdf),
            "-o",
            str((out or self.out) / "robot.xml"),
            "--cache-dir",
            str(self.cache),
            "--overwrite",
            cwd=self.tmp,
        )

    def outside(self) -> dict[str, bytes | None]:
        """Everything in tmp but the output and the cache (which the run may change)."""
        snap = attack.snapshot(self.tmp)
        skip = (str(self.out), str(self.cache))
        return {k: v for k, v in snap.items() if not k.startswith(skip)}


_LAUNCHER = """
import os, resource, signal, sys
limit, fd = int(sys.argv[1]), int(sys.argv[2])
pid = os.fork()
if pid == 0:
    os.close(fd)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    os.execv(sys.argv[3], sys.argv[3:])
_, status, usage = os.wait4(pid, 0)
os.write(fd, str(usage.ru_maxrss).encode())
if os.WIFSIGNALED(status):
    signal.signal(os.WTERMSIG(status), signal.SIG_DFL)
    os.kill(os.getpid(), os.WTERMSIG(status))
sys.exit(os.waitstatus_to_exitcode(status))
"""
"""Runs ``argv[3:]`` under the probe's memory limit and writes its peak resident memory
(KiB) to the descriptor ``argv[2]``; exits as it did."""


def run_measured(command: str, *args: str, cwd: Path) -> tuple[attack.Result, int]:
    """:func:`attack.run`'s probe (same limits), and the peak resident memory in bytes of
    that process alone (``wait4``'s rusage)."""
    code = f"from urdf2mjcf.cli import {attack.ENTRY[command]}; {attack.ENTRY[command]}()"
    peak_r, peak_w = os.pipe()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        start = time.monotonic()
        # Through a small launcher: Linux counts a forked child's peak from the address
        # space it was forked from (the test process, large late in a suite), so the
        # probe is forked from a process that is small.
        proc = subprocess.Popen(
            [sys.executable, "-c", _LAUNCHER, str(attack.MEMORY_LIMIT), str(peak_w)]
            + [sys.executable, "-c", code, *args],
            stdout=out,
            stderr=err,
            stdin=subprocess.DEVNULL,
            cwd=cwd,
            pass_fds=(peak_w,),
            start_new_session=True,
        )
        os.close(peak_w)
        timer = threading.Timer(TIMEOUT, lambda: os.killpg(proc.pid, signal.SIGKILL))
        timer.start()
        try:
            proc.wait()
        finally:
            timer.cancel()
        with os.fdopen(peak_r, "rb") as peak:
            maxrss = int(peak.read() or b"0")
        seconds = time.monotonic() - start
        assert seconds < TIMEOUT, f"{command} {args} ran past {TIMEOUT} s (killed)"
        out.seek(0)
        err.seek(0)
        result = attack.Result(
            proc.returncode,
            out.read().decode(errors="replace"),
            err.read().decode(errors="replace"),
            seconds,
        )
    return result, maxrss * 1024


@pytest.fixture(scope="module")
def clean(tmp_path_factory) -> tuple[Path, bytes, dict[str, bytes]]:
    """A cache made by one real conversion: its folder, its one entry's bytes, and the
    output files of that conversion (what a rebuilt run must write again)."""
    setup = Setup(tmp_path_factory.mktemp("clean"))
    res, _ = setup.convert()
    assert res.returncode == 0, res.stderr
    files = {
        p.relative_to(setup.out).as_posix(): p.read_bytes()
        for p in setup.out.rglob("*")
        if p.is_file()
    }
    return setup.cache, setup.entry().read_bytes(), files


@pytest.fixture
def setup(tmp_path, clean) -> Setup:
    s = Setup(tmp_path)
    shutil.copytree(clean[0], s.cache)
    return s


def poison(setup: Setup, edit) -> bytes:
    """Rewrite the entry with ``edit(meta, raw)`` applied; its good bytes."""
    entry = setup.entry()
    good = entry.read_bytes()
    meta, raw = unpack(good)
    edit(meta, raw)
    entry.write_bytes(pack(meta, raw))
    return good


def assert_rebuilt_inside(setup: Setup, res: attack.Result, good: bytes, clean_files) -> None:
    """The run succeeded by loading the mesh again: the same output as a clean run,
    the entry rewritten, and every file robot.xml names inside its folder."""
    assert res.returncode == 0, res.stderr[-2000:]
    assert "Traceback" not in res.stderr
    written = {
        p.relative_to(setup.out).as_posix(): p.read_bytes()
        for p in setup.out.rglob("*")
        if p.is_file()
    }
    assert written == clean_files
    assert setup.entry().read_bytes() == good, "the poisoned entry was rebuilt"
    root = etree.parse(str(setup.out / "robot.xml")).getroot()
    compiler = root.find("compiler")
    assetdir = (
        (compiler.get("meshdir") or compiler.get("texturedir")) if compiler is not None else ""
    )
    for el in root.iter():
        name = el.get("file")
        if name is not None:
            target = (setup.out / (assetdir or "") / name).resolve()
            assert target.is_relative_to(setup.out.resolve()), (el.tag, name)
            assert target.is_file(), name


def texture_payload(name: str, file: str, data: bytes | None):
    def edit(meta: dict, raw: dict[str, bytes]) -> None:
        ((old_name, _),) = meta["textures"]
        meta["textures"] = [[name, file]]
        for material in meta["materials"]:
            if material[4] == old_name:
                material[3] = material[4] = name
        if data is not None:
            raw["x0"] = data

    return edit


@pytest.mark.parametrize(
    "name, file, data",
    [
        # the payload, the texture's own valid PNG
        (ESCAPE, ESCAPE, None),
        ("quadrants", ESCAPE, None),
        (ESCAPE, ESCAPE, b"attacker bytes\n"),
        ("quadrants", ESCAPE, b"attacker bytes\n"),
        ("quadrants", "ABSOLUTE", None),  # the victim's absolute path
        ("..", "...png", None),
        ("q\x1b[31m", "q\x1b[31m.png", None),
        ("quadrants", "quadrants.png", b"\x89PNG\r\n\x1a\nnot really"),  # a garbage PNG
    ],
    ids=[
        "escape",
        "escape-file",
        "escape-garbage",
        "escape-file-garbage",
        "absolute",
        "dots",
        "escape-codes",
        "garbage-png",
    ],
)
def test_poisoned_texture_name_writes_nothing_outside(setup, clean, name, file, data):
    file = str(setup.victims[0]) if file == "ABSOLUTE" else file
    before = setup.outside()
    good = poison(setup, texture_payload(name, file, data))
    res, peak = setup.convert()
    assert setup.outside() == before, "nothing outside the output and the cache changed"
    for victim in setup.victims:
        assert victim.read_text() == "the user's file\n"
    assert_rebuilt_inside(setup, res, good, clean[2])
    assert peak < PEAK_RSS


@pytest.mark.parametrize(
    "field, value",
    [
        ("material", ESCAPE),
        ("material", "red\x07"),
        ("part", "../../x"),
        ("rgba", [float("nan"), 0, 0, 1]),
        ("rgba", [1e300, 0, 0, 1]),
    ],
)
def test_poisoned_material_is_a_miss(setup, clean, field, value):
    def edit(meta: dict, raw: dict[str, bytes]) -> None:
        material = meta["materials"][0]
        if field == "material":
            for part in meta["parts"]:
                part["material"] = value
            material[0] = material[1] = value
        elif field == "part":
            meta["parts"][0]["material"] = value
        else:
            material[2] = value

    before = setup.outside()
    good = poison(setup, edit)
    res, _ = setup.convert()
    assert setup.outside() == before
    assert_rebuilt_inside(setup, res, good, clean[2])


@pytest.mark.parametrize("side", ["/dev/zero", "fifo", "/dev/urandom", "dir"])
def test_side_file_that_is_not_a_regular_file_neither_hangs_nor_fills_memory(setup, clean, side):
    if side == "fifo":
        os.mkfifo(setup.robot / "meshes" / "side.fifo")
        side = "side.fifo"  # relative to the mesh, as the decoder names it
    elif side == "dir":
        side = ".."

    def edit(meta: dict, raw: dict[str, bytes]) -> None:
        meta["deps"].insert(0, [side, "0" * 64])

    before = setup.outside()
    good = poison(setup, edit)
    res, peak = setup.convert()
    assert setup.outside() == before
    assert_rebuilt_inside(setup, res, good, clean[2])
    assert peak < PEAK_RSS, f"peak resident memory {peak / 2**20:.0f} MB"
    assert res.seconds < TIMEOUT


def test_note_with_escape_codes_is_printed_escaped(setup, clean):
    payload = "\x1b[31mRED\x1b[0m \x1b]0;owned\x07 \x1b[2J\rdone"

    def edit(meta: dict, raw: dict[str, bytes]) -> None:
        meta["notes"].append(["warning", payload])

    poison(setup, edit)
    res, _ = setup.convert()
    assert res.returncode == 0, res.stderr
    for control in ("\x1b", "\x07", "\r"):
        assert control not in res.stderr + res.stdout
    assert "\\x1b[31mRED\\x1b[0m \\x1b]0;owned\\x07 \\x1b[2J\\x0ddone" in res.stderr


def test_note_of_an_unknown_kind_or_huge_is_a_miss(setup, clean):
    def edit(meta: dict, raw: dict[str, bytes]) -> None:
        meta["notes"] += [["error\x1b[2J", "x"], ["warning", "y" * 100_000]]

    good = poison(setup, edit)
    res, _ = setup.convert()
    assert_rebuilt_inside(setup, res, good, clean[2])
    assert "yyyy" not in res.stderr


def test_entry_that_is_a_symlink_to_a_users_file_is_neither_read_nor_touched(setup, clean):
    entry = setup.entry()
    good = entry.read_bytes()
    victim = setup.tmp / "x" / "victim.bin"
    victim.write_bytes(good)  # even a whole entry: a symlink is never an entry
    old = time.time() - 7 * 86400
    os.utime(victim, (old, old))
    stamp = victim.stat().st_mtime_ns
    entry.unlink()
    entry.symlink_to(victim)
    res, _ = setup.convert()
    assert victim.stat().st_mtime_ns == stamp, "utime did not follow the symlink"
    assert victim.read_bytes() == good
    assert_rebuilt_inside(setup, res, good, clean[2])
    assert not entry.is_symlink(), "the rebuilt entry replaced the link, not its target"


def test_kind_folder_that_is_a_symlink_is_not_read_or_written(setup, clean):
    user = setup.tmp / "user-meshes"
    (setup.cache / "meshes").rename(user)
    (setup.cache / "meshes").symlink_to(user)
    old = time.time() - 7 * 86400
    for p in user.iterdir():
        os.utime(p, (old, old))
    before = attack.snapshot(user)
    stamps = {p.name: p.stat().st_mtime_ns for p in user.iterdir()}
    res, _ = setup.convert()
    assert res.returncode == 0, res.stderr
    assert attack.snapshot(user) == before
    assert {p.name: p.stat().st_mtime_ns for p in user.iterdir()} == stamps


# -- the last line of defence: names that became paths ------------------------------------


@pytest.mark.parametrize(
    "rel", ["../victim.txt", "assets/../../victim.txt", "/abs/victim.txt", "assets/..\\x", ""]
)
def test_the_staging_writer_refuses_a_path_outside_its_folder(tmp_path, rel):
    from urdf2mjcf.errors import OutputError
    from urdf2mjcf.output import write_atomic

    victim = tmp_path / "victim.txt"
    victim.write_text("the user's file\n")
    out = tmp_path / "out" / "robot.xml"
    before = attack.snapshot(tmp_path)
    files = {"assets/ok.png": b"fine", rel: b"attacker bytes", "robot.xml": b"<mujoco/>"}
    with pytest.raises(OutputError, match="not inside"):
        write_atomic(out, files, lambda staged: None)
    assert attack.snapshot(tmp_path) == before, "nothing staged, nothing left behind"


@pytest.mark.parametrize("file", ["../x.png", "a/b.png", "..", ".", "x\x1b.png", ""])
def test_the_meshes_pass_refuses_a_texture_file_that_is_not_one_name(file):
    from urdf2mjcf.errors import MeshError
    from urdf2mjcf.ir import MaterialAsset, TextureAsset
    from urdf2mjcf.passes import meshes

    texture = TextureAsset(name="t", file=file, data=b"")
    material = MaterialAsset(name="m", rgba=(1.0, 1.0, 1.0, 1.0), texture="t")
    with pytest.raises(MeshError, match="not a plain file name"):
        meshes._Assets({}, {}).use(material, texture)
