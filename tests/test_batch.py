"""``urdf2mjcf batch``: many robots into one tree with one summary, on the local process
pool or Ray. Each robot's files are byte for byte what the one-robot converter writes and
MuJoCo compiles them; a failing robot is a line of the summary; bad input is one error
line, exit 2, nothing written; concurrent workers sharing one cache never corrupt it."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import threading
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf import api
from urdf2mjcf.batch import SUMMARY, run_batch
from urdf2mjcf.cache import read_entry, write_entry
from urdf2mjcf.passes.collision.decompositions import DecompositionCache

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "data" / "golden"
SIM_ARM = ROOT / "tests" / "data" / "sim_robot" / "urdf" / "sim_arm.urdf.xacro"
SMALL = [GOLDEN / "joints.urdf", GOLDEN / "mimic.urdf", SIM_ARM]
BAD_URDF = (
    '<robot name="bad"><link name="a"/><joint name="j" type="revolute">'
    '<parent link="a"/><child link="missing"/><axis xyz="0 0 1"/>'
    '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>\n'
)


def batch(*args: str, hide_ray: bool = False) -> subprocess.CompletedProcess:
    """``urdf2mjcf batch ARGS`` as a user runs it (optionally where Ray is not installed)."""
    code = "from urdf2mjcf.cli import urdf2mjcf_main; urdf2mjcf_main()"
    if hide_ray:
        code = "import sys; sys.modules['ray'] = None; " + code
    return subprocess.run(
        [sys.executable, "-c", code, "batch", *args],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )


def tree(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != SUMMARY
    }


def refused(proc: subprocess.CompletedProcess, *needles: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


# -- what a batch writes ------------------------------------------------------------------


def test_each_robot_is_what_the_one_robot_converter_writes(tmp_path):
    out = tmp_path / "out"
    cache = tmp_path / "cache"
    proc = batch(*map(str, SMALL), "-o", str(out), "--workers", "2", "--cache-dir", str(cache))
    assert proc.returncode == 0, proc.stderr
    progress = [line for line in proc.stderr.splitlines() if line.startswith("[")]
    assert len(progress) == 3 and all(" ok " in line for line in progress), proc.stderr
    assert "converted 3/3 robots" in proc.stdout

    summary = json.loads((out / SUMMARY).read_text())
    assert summary["generator"] == "urdf2mjcf batch" and summary["converted"] == 3
    assert [r["output"] for r in summary["robots"]] == [
        "joints/joints.xml",
        "mimic/mimic.xml",
        "sim_arm/sim_arm.xml",
    ]
    assert sorted(summary["files"]) == sorted([*tree(out), SUMMARY])
    for source, entry in zip(SMALL, summary["robots"], strict=True):
        name = entry["output"].split("/")[0]
        ref = tmp_path / "ref" / name / f"{name}.xml"
        api.convert(source, ref, cache_dir=cache)  # the one-robot converter, defaults
        assert tree(out / name) == tree(ref.parent), name
        model = mujoco.MjModel.from_xml_path(str(out / name / "scene.xml"))
        assert model.nbody - 1 == entry["bodies"]


def test_a_folder_gives_its_urdfs_in_its_layout(tmp_path):
    src = tmp_path / "robots"
    (src / "pkg" / "urdf").mkdir(parents=True)
    shutil.copy(GOLDEN / "joints.urdf", src / "pkg" / "urdf" / "arm.urdf")
    shutil.copy(GOLDEN / "mimic.urdf", src / "hand.urdf")
    (src / "pkg" / "urdf" / "macros.xacro").write_text("<robot/>")  # a macro library: skipped
    (src / "hand.urdf.xacro").write_text("<robot/>")  # the source of hand.urdf: left out
    out = tmp_path / "out"
    summary = run_batch([src], out, workers=1)
    assert [r["output"] for r in summary["robots"]] == ["hand/hand.xml", "pkg/urdf/arm/arm.xml"]
    assert summary["skipped"] == [
        {"source": str(src / "hand.urdf.xacro"), "reason": "hand.urdf beside it"}
    ]
    assert (out / "pkg" / "urdf" / "arm" / "scene.xml").is_file()


def test_a_failing_robot_is_a_line_of_the_summary_not_the_end_of_the_batch(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    shutil.copy(GOLDEN / "joints.urdf", src / "good.urdf")
    (src / "bad.urdf").write_text(BAD_URDF)
    out = tmp_path / "out"
    proc = batch(str(src), "-o", str(out), "--workers", "2")
    assert proc.returncode == 1, proc.stderr
    assert f"failed: {src / 'bad.urdf'}: " in proc.stdout and "missing" in proc.stdout
    assert "converted 1/2 robots" in proc.stdout
    summary = json.loads((out / SUMMARY).read_text())
    bad, good = summary["robots"]
    assert not bad["ok"] and str(src / "bad.urdf") in bad["error"] and "missing" in bad["error"]
    assert good["ok"] and (out / "good" / "good.xml").is_file()
    assert not (out / "bad").exists(), "nothing of the failed robot"


def test_quiet_leaves_only_the_failed_robots(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    shutil.copy(GOLDEN / "joints.urdf", src / "good.urdf")
    (src / "bad.urdf").write_text(BAD_URDF)
    proc = batch(str(src), "-o", str(tmp_path / "out"), "--workers", "1", "-q")
    assert proc.returncode == 1, proc.stderr
    (line,) = proc.stdout.splitlines()
    assert line.startswith(f"failed: {src / 'bad.urdf'}: ")
    assert proc.stderr == "", "no progress lines"
    assert json.loads((tmp_path / "out" / SUMMARY).read_text())["converted"] == 1


def test_quiet_means_the_same_in_every_command():
    from urdf2mjcf.batch import batch_command
    from urdf2mjcf.certify.command import verify_command
    from urdf2mjcf.cli import make_facility_command, urdf2mjcf_command

    helps = {
        command.name: [p.help for p in command.params if "-q" in getattr(p, "opts", ())]
        for command in (urdf2mjcf_command, batch_command, verify_command, make_facility_command)
    }
    assert len({tuple(h) for h in helps.values()}) == 1 and all(len(h) == 1 for h in helps.values())


# -- bad input: one line, exit 2, nothing written -----------------------------------------


def test_a_path_that_does_not_exist_is_refused_before_anything_runs(tmp_path):
    out = tmp_path / "out"
    refused(
        batch(str(GOLDEN / "joints.urdf"), str(tmp_path / "nope.urdf"), "-o", str(out)),
        "nope.urdf",
        "does not exist",
    )
    assert list(tmp_path.iterdir()) == []


def test_a_folder_without_robots_and_two_robots_on_one_output_are_refused(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    refused(batch(str(empty), "-o", str(tmp_path / "out")), "no robot description")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    shutil.copy(GOLDEN / "joints.urdf", tmp_path / "a" / "arm.urdf")
    shutil.copy(GOLDEN / "mimic.urdf", tmp_path / "b" / "arm.urdf")
    proc = batch(
        str(tmp_path / "a" / "arm.urdf"),
        str(tmp_path / "b" / "arm.urdf"),
        "-o",
        str(tmp_path / "out"),
    )
    refused(proc, "arm/arm.xml", str(tmp_path / "a" / "arm.urdf"))
    assert not (tmp_path / "out").exists()


def test_a_folder_we_did_not_write_is_refused_and_overwrite_keeps_its_files(tmp_path):
    out = tmp_path / "out"
    (out / "joints").mkdir(parents=True)
    (out / "notes.txt").write_text("mine")
    (out / "joints" / "joints.xml").write_text("my own model")
    refused(batch(str(GOLDEN / "joints.urdf"), "-o", str(out)), str(out), "--overwrite")
    assert tree(out) == {"notes.txt": b"mine", "joints/joints.xml": b"my own model"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"], "no staging folder left"

    proc = batch(str(GOLDEN / "joints.urdf"), "-o", str(out), "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "joints" / "joints.xml").read_bytes() != b"my own model"  # --overwrite

    # A later batch into its own folder replaces what it wrote, keeps the rest.
    (out / "notes.txt").write_text("still mine")
    proc = batch(str(GOLDEN / "mimic.urdf"), "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    assert not (out / "joints").exists(), "the earlier batch's robot is gone"
    assert (out / "mimic" / "mimic.xml").is_file() and (
        out / "notes.txt"
    ).read_text() == "still mine"


def test_executor_options_are_checked_before_anything_runs(tmp_path):
    out = tmp_path / "out"
    refused(
        batch(str(GOLDEN / "joints.urdf"), "-o", str(out), "--address", "auto"),
        "--address needs --executor ray",
    )
    proc = batch(str(GOLDEN / "joints.urdf"), "-o", str(out), "--executor", "ray", hide_ray=True)
    refused(proc, "--executor ray needs Ray", "pip install 'mjcf-forge[ray]'")
    assert not out.exists()


# -- workers sharing one cache ------------------------------------------------------------

PAYLOAD_MB = 4


def _hammer(args: tuple[str, int]) -> int:
    """Write the same entry again and again: 4 MB whose last 32 bytes hash the rest."""
    folder, writer = args
    for i in range(30):
        body = np.random.default_rng(1000 * writer + i).bytes(PAYLOAD_MB * 2**20)
        write_entry(Path(folder), "same.bin", body + hashlib.sha256(body).digest())
    return writer


def test_concurrent_writers_of_one_entry_leave_only_whole_files(tmp_path, monkeypatch):
    monkeypatch.setenv("URDF2MJCF_CACHE_MAX_MB", "0")
    folder = tmp_path / "meshes"
    seen = torn = 0
    stop = threading.Event()

    def read() -> None:
        nonlocal seen, torn
        while not stop.is_set():
            data = read_entry(folder / "same.bin")
            if data is not None:
                seen += 1
                torn += hashlib.sha256(data[:-32]).digest() != data[-32:]

    reader = threading.Thread(target=read)
    reader.start()
    try:
        with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:
            assert sorted(pool.map(_hammer, [(str(folder), 1), (str(folder), 2)])) == [1, 2]
    finally:
        stop.set()
        reader.join()
    assert seen > 0 and torn == 0, (seen, torn)
    assert os.listdir(folder) == ["same.bin"], "no temporary file left"


def test_two_workers_filling_one_cache_agree_and_leave_it_whole(tmp_path):
    # Two copies of one robot: both workers decompose the same meshes at the same time
    # and write the same cache entries.
    src = tmp_path / "src" / "golden"
    shutil.copytree(GOLDEN.parent / "meshes", tmp_path / "src" / "meshes")
    src.mkdir()
    for name in ("left", "right"):
        shutil.copy(GOLDEN / "nonconvex.urdf", src / f"{name}.urdf")
    cache = tmp_path / "cache"
    summary = run_batch([src], tmp_path / "out", {"cache_dir": cache}, workers=2)
    assert summary["converted"] == 2
    left = (tmp_path / "out" / "left" / "left.xml").read_bytes()
    assert left == (tmp_path / "out" / "right" / "right.xml").read_bytes()
    entries = sorted((cache / "coacd").glob("*.npz"))
    assert entries and all(DecompositionCache(cache).load(p.stem) for p in entries)
    assert not list(cache.rglob("*.tmp")), "no temporary file left"
    # A warm batch reads those entries and writes the same bytes.
    again = run_batch([src], tmp_path / "again", {"cache_dir": cache}, workers=2)
    assert again["converted"] == 2
    assert tree(tmp_path / "again") == tree(tmp_path / "out")


# -- Ray: same bytes as the local pool ----------------------------------------------------


def test_ray_writes_the_same_tree_as_the_local_pool(tmp_path):
    ray = pytest.importorskip("ray")
    local = run_batch(SMALL, tmp_path / "local", workers=2)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = run_batch(SMALL, tmp_path / "ray", executor="ray")
    finally:
        ray.shutdown()
    assert remote["converted"] == local["converted"] == 3
    assert tree(tmp_path / "ray") == tree(tmp_path / "local")
    strip = ("wall_time",)
    assert [{k: v for k, v in r.items() if k not in strip} for r in remote["robots"]] == [
        {k: v for k, v in r.items() if k not in strip} for r in local["robots"]
    ]
