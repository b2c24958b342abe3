"""`urdf2mjcf cache info|clear`, run as a user runs them (a subprocess of the
console script's entry point), checked against the files on disk; and the
conversion command still takes SOURCE first, a file named 'cache' included."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import urdf2mjcf

DATA = Path(__file__).parent / "data"
MESHES = DATA / "meshes"

URDF = """<robot name="small">
  <link name="base">
    <visual><geometry><mesh filename="meshes/colored_box.dae"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/u_shape.stl"/></geometry></collision>
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>
</robot>
"""
KINDS = {
    "coacd": ".npz",
    "hull_gap": ".json",
    "hulls": ".npz",
    "primitive_fits": ".json",
    "meshes": ".bin",
    "certificate": ".json",  # geometric figures of certificates
}


def urdf2mjcf_cli(*args: str, cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    code = "from urdf2mjcf.cli import urdf2mjcf_main; urdf2mjcf_main()"
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, **(env or {})},
        timeout=600,
    )


def make_robot(folder: Path, name: str = "robot.urdf") -> Path:
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    for mesh in ("colored_box.dae", "u_shape.stl"):
        shutil.copy(MESHES / mesh, folder / "meshes" / mesh)
    urdf = folder / name
    urdf.write_text(URDF)
    return urdf


def on_disk(root: Path) -> dict[str, tuple[int, int]]:
    """(entries, bytes) per kind, counted from the folder itself."""
    out = {}
    for kind, suffix in KINDS.items():
        files = [p for p in (root / kind).glob(f"*{suffix}")] if (root / kind).is_dir() else []
        out[kind] = (len(files), sum(p.stat().st_size for p in files))
    return out


def parse_info(stdout: str) -> tuple[Path, dict[str, tuple[int, float]]]:
    where = re.search(r"^cache: (.+?)( \(not created yet\))?$", stdout, re.M)
    assert where, stdout
    kinds = {
        m.group(1): (int(m.group(2)), float(m.group(3)))
        for m in re.finditer(r"\((\w+)/\): (\d+) entries, ([\d.]+) MB", stdout)
    }
    return Path(where.group(1)), kinds


@pytest.fixture(scope="module")
def filled(tmp_path_factory) -> Path:
    """A cache holding one conversion's meshes, hull gaps and a decomposition."""
    tmp = tmp_path_factory.mktemp("filled")
    root = tmp / "cache"
    report = urdf2mjcf.convert(
        make_robot(tmp / "robot"), tmp / "out" / "robot.xml", use_environment=False, cache_dir=root
    )
    assert report.decomposed, "the U shape is concave: one CoACD entry"
    return root


def test_info_counts_what_is_on_disk(filled, tmp_path):
    proc = urdf2mjcf_cli("cache", "info", "--cache-dir", str(filled), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    where, kinds = parse_info(proc.stdout)
    assert where == filled
    disk = on_disk(filled)
    assert set(kinds) == set(disk)
    for kind, (count, size) in disk.items():
        assert kinds[kind][0] == count
        assert kinds[kind][1] == pytest.approx(size / 2**20, abs=0.051)
    assert disk["meshes"][0] == 2 and disk["coacd"][0] == 1 and disk["hull_gap"][0] == 1
    total = re.search(r"^total: (\d+) entries, .* \(limit 2048\.0 MB\)$", proc.stdout, re.M)
    assert total and int(total.group(1)) == sum(c for c, _ in disk.values())


def test_info_follows_the_environment(filled, tmp_path):
    proc = urdf2mjcf_cli(
        "cache", "info", cwd=tmp_path, env={"URDF2MJCF_CACHE": str(filled),
                                            "URDF2MJCF_CACHE_MAX_MB": "0"}
    )
    assert proc.returncode == 0, proc.stderr
    assert parse_info(proc.stdout)[0] == filled
    assert "(limit none)" in proc.stdout
    empty = tmp_path / "nothing-here"
    proc = urdf2mjcf_cli("cache", "info", "--cache-dir", str(empty), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "(not created yet)" in proc.stdout and "total: 0 entries" in proc.stdout
    assert not empty.exists()


def test_clear_deletes_entries_and_nothing_else(tmp_path):
    root = tmp_path / "cache"
    urdf2mjcf.convert(
        make_robot(tmp_path / "robot"), tmp_path / "out" / "robot.xml", cache_dir=root
    )
    before = on_disk(root)
    (root / "README.txt").write_text("mine")  # a user's files in the cache folder stay
    (root / "meshes" / "notes.txt").write_text("mine too")
    proc = urdf2mjcf_cli("cache", "clear", "--cache-dir", str(root), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    count = sum(c for c, _ in before.values())
    size = sum(s for _, s in before.values())
    assert f"removed {count} entries, {size / 2**20:.1f} MB" in proc.stdout
    assert on_disk(root) == {k: (0, 0) for k in KINDS}
    assert (root / "README.txt").read_text() == "mine"
    assert (root / "meshes" / "notes.txt").read_text() == "mine too"
    assert not (root / "coacd").exists()  # emptied folders of ours go
    proc = urdf2mjcf_cli("cache", "info", "--cache-dir", str(root), cwd=tmp_path)
    assert "total: 0 entries" in proc.stdout


def test_conversion_still_takes_source_first_even_a_file_named_cache(tmp_path):
    make_robot(tmp_path, name="cache")  # a URDF file called 'cache', given as ./cache
    proc = urdf2mjcf_cli(
        "./cache", "-o", "out/robot.xml", "--cache-dir", str(tmp_path / "c"), cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out" / "robot.xml").is_file()
    assert on_disk(tmp_path / "c")["meshes"][0] == 2  # the conversion used the named cache


@pytest.mark.parametrize(
    "args, needle",
    [
        (("cache", "bogus"), "No such command 'bogus'"),
        (("cache", "info", "--cache-dir", str(DATA / "golden" / "joints.urdf")), "is a file"),
    ],
)
def test_cache_command_errors_are_one_line(args, needle, tmp_path):
    proc = urdf2mjcf_cli(*args, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], proc.stderr


# -- the marker: we delete only what we wrote ---------------------------------------------

TAG_FIRST_LINE = "Signature: 8a477f597d28d172789f06886806bc55"


def test_the_first_write_marks_the_cache_with_a_cachedir_tag(filled):
    lines = (filled / "CACHEDIR.TAG").read_text().splitlines()
    assert lines[0] == TAG_FIRST_LINE  # the Cache Directory Tagging spec: backup tools skip it
    assert lines[1].startswith("#") and "urdf2mjcf" in lines[1]


def test_an_older_versions_cache_is_marked_when_written_and_cleared_after(tmp_path):
    root = tmp_path / "cache"
    urdf = make_robot(tmp_path / "robot")
    urdf2mjcf.convert(urdf, tmp_path / "a" / "robot.xml", use_environment=False, cache_dir=root)
    (root / "CACHEDIR.TAG").unlink()  # as an older version left it: entries, no marker
    proc = urdf2mjcf_cli("cache", "clear", "--cache-dir", str(root), cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "CACHEDIR.TAG" in proc.stderr, proc.stderr
    assert "delete the folder yourself" in proc.stderr and TAG_FIRST_LINE in proc.stderr
    assert on_disk(root)["meshes"][0] == 2, "nothing deleted"
    info = urdf2mjcf_cli("cache", "info", "--cache-dir", str(root), cwd=tmp_path)
    assert info.returncode == 0 and "not a cache of ours" in info.stdout
    # its kind folders hold only entries named as ours: the next write marks it
    (tmp_path / "robot" / "meshes" / "u_shape.stl").write_bytes(
        (MESHES / "box.stl").read_bytes()
    )
    urdf2mjcf.convert(urdf, tmp_path / "b" / "robot.xml", use_environment=False, cache_dir=root)
    assert (root / "CACHEDIR.TAG").read_text().startswith(TAG_FIRST_LINE)
    proc = urdf2mjcf_cli("cache", "clear", "--cache-dir", str(root), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert on_disk(root) == {k: (0, 0) for k in KINDS}


def test_a_folder_of_other_files_is_used_and_marked_but_one_with_foreign_entries_is_not(
    tmp_path,
):
    urdf = make_robot(tmp_path / "robot")
    other = tmp_path / "other"  # files, but none of our kind folders: used and marked
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    urdf2mjcf.convert(urdf, tmp_path / "a" / "robot.xml", use_environment=False, cache_dir=other)
    assert (other / "CACHEDIR.TAG").is_file() and (other / "notes.txt").read_text() == "mine"
    mixed = tmp_path / "mixed"  # a 'meshes' folder with files we did not name: not marked
    (mixed / "meshes").mkdir(parents=True)
    (mixed / "meshes" / "arm.stl").write_bytes((MESHES / "box.stl").read_bytes())
    urdf2mjcf.convert(urdf, tmp_path / "b" / "robot.xml", use_environment=False, cache_dir=mixed)
    assert not (mixed / "CACHEDIR.TAG").exists()
    assert (mixed / "meshes" / "arm.stl").read_bytes() == (MESHES / "box.stl").read_bytes()
    assert on_disk(mixed)["meshes"][0] == 2, "still used as a cache (never evicted from)"
