"""Output only where asked, all or nothing (issue 19, item 4), through the real commands.

A recipe's name is one plain folder name; a symlink at an output path, even one to
nothing, is a file there (refused without --overwrite); every output of a run is
installed together or not at all; a run killed at any point, even by SIGKILL, leaves
nothing a later run mistakes for a user's folder, and the later run undoes it."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.security.attack import ROOT, assert_one_error, run, snapshot

NO_ROBOT = ROOT / "recipes" / "imetro-no-robot.yaml"
THESIS = "my own words\n"
URDF = (
    '<robot name="r"><link name="a"><inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    "</robot>"
)


def listing(*folders: Path) -> list[str]:
    """Every path under ``folders`` (symlinks not followed), hidden ones included."""
    out = []
    for folder in folders:
        for top, dirs, names in os.walk(folder):
            out += [os.path.join(top, n) for n in dirs + names]
    return sorted(out)


@pytest.fixture
def urdf(tmp_path: Path) -> Path:
    path = tmp_path / "robot.urdf"
    path.write_text(URDF)
    return path


# -- a recipe's name -----------------------------------------------------------------------


@pytest.fixture
def own_root(tmp_path: Path) -> Path:
    """A facility root of our own (the checkout's data by symlink), so that a build that
    escaped build/ would show here, not in the checkout."""
    root = tmp_path / "root"
    (root / "recipes").mkdir(parents=True)
    for name in ("facility", "meshes"):
        (root / name).symlink_to(ROOT / name)
    (root / "recipes" / "components").symlink_to(ROOT / "recipes" / "components")
    return root


@pytest.mark.parametrize("name", ["../../x", "/abs/x", ".", "..", "a/b", "x\x1b[31m"])
def test_a_recipe_name_that_is_not_one_plain_name_builds_nothing(own_root, tmp_path, name):
    recipe = own_root / "recipes" / "evil.yaml"
    text = NO_ROBOT.read_text().replace("name: imetro-no-robot", f"name: {json.dumps(name)}")
    recipe.write_text(text)
    before = listing(tmp_path), listing(ROOT / "build") if (ROOT / "build").is_dir() else []
    res = run("make-facility", str(recipe), "--root", str(own_root), cwd=tmp_path, timeout=120)
    line = assert_one_error(res, str(recipe), "name:", "plain name")
    assert "\x1b" not in line
    after = listing(tmp_path), listing(ROOT / "build") if (ROOT / "build").is_dir() else []
    assert after == before
    assert not Path("/abs/x").exists() and not (tmp_path.parent / "x").exists()


def test_a_name_set_on_the_command_line_is_checked_too(own_root, tmp_path):
    res = run(
        "make-facility",
        str(NO_ROBOT),
        "--root",
        str(own_root),
        "--set",
        "name=../../x",
        cwd=tmp_path,
        timeout=120,
    )
    assert_one_error(res, "name")
    assert not (own_root / "build").exists() and not (tmp_path.parent / "x").exists()


# -- a symlink to nothing at an output path ------------------------------------------------


def test_a_dangling_symlink_at_the_mjcf_output_is_refused(urdf, tmp_path):
    out = tmp_path / "out.xml"
    out.symlink_to(tmp_path / "elsewhere" / "victim.xml")
    res = run("urdf2mjcf", str(urdf), "-o", str(out), "--no-validate", cwd=tmp_path)
    assert_one_error(res, "out.xml", "--overwrite")
    assert out.is_symlink() and os.readlink(out) == str(tmp_path / "elsewhere" / "victim.xml")
    assert not (tmp_path / "elsewhere").exists() and not (tmp_path / "scene.xml").exists()

    res = run("urdf2mjcf", str(urdf), "-o", str(out), "--overwrite", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert not out.is_symlink() and "<mujoco" in out.read_text()  # the link itself replaced
    assert not (tmp_path / "elsewhere").exists()


def test_a_dangling_symlink_at_the_report_is_refused(urdf, tmp_path):
    report = tmp_path / "report.json"
    report.symlink_to(tmp_path / "victim.json")
    out = tmp_path / "o" / "robot.xml"
    res = run("urdf2mjcf", str(urdf), "-o", str(out), "--report", str(report), cwd=tmp_path)
    assert_one_error(res, "report.json", "--overwrite")
    assert report.is_symlink() and not (tmp_path / "victim.json").exists()
    assert not out.parent.exists()

    args = ["-o", str(out), "--report", str(report), "--overwrite"]
    res = run("urdf2mjcf", str(urdf), *args, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert json.loads(report.read_text())["generator"] == "urdf2mjcf"
    assert not report.is_symlink() and not (tmp_path / "victim.json").exists()


def test_a_dangling_symlink_at_a_facility_output_is_refused(tmp_path):
    out = tmp_path / "fac"
    out.symlink_to(tmp_path / "victim")
    res = run("make-facility", str(NO_ROBOT), "--root", str(ROOT), "-o", str(out), cwd=tmp_path)
    assert_one_error(res, "fac", "--overwrite")
    assert out.is_symlink() and listing(tmp_path) == [str(out)]


# -- all or nothing -------------------------------------------------------------------------


def _read_only(folder: Path) -> bool:
    """Make ``folder`` one we cannot write in (root ignores modes: immutable then);
    False when this machine lets us do neither."""
    folder.chmod(0o555)
    probe = folder / ".probe"
    try:
        probe.write_text("")
    except OSError:
        return True
    probe.unlink()
    done = subprocess.run(["chattr", "+i", str(folder)], capture_output=True, check=False)
    return done.returncode == 0 if shutil.which("chattr") else False


def _writable(folder: Path) -> None:
    if shutil.which("chattr"):
        subprocess.run(["chattr", "-i", str(folder)], capture_output=True, check=False)
    folder.chmod(0o755)


def test_a_report_in_a_read_only_folder_leaves_no_mjcf(urdf, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    if not _read_only(ro):
        pytest.skip("cannot make a folder read-only here (root, and no chattr)")
    try:
        out = tmp_path / "out" / "robot.xml"
        res = run(
            "urdf2mjcf", str(urdf), "-o", str(out), "--report", str(ro / "r.json"), cwd=tmp_path
        )
        assert_one_error(res, "r.json")
        assert not (tmp_path / "out").exists()
        assert listing(tmp_path) == sorted([str(urdf), str(ro)])
    finally:
        _writable(ro)


def test_a_report_whose_folder_is_a_file_leaves_no_mjcf(urdf, tmp_path):
    (tmp_path / "afile").write_text("mine")
    out = tmp_path / "robot.xml"
    res = run(
        "urdf2mjcf",
        str(urdf),
        "-o",
        str(out),
        "--report",
        str(tmp_path / "afile" / "r.json"),
        cwd=tmp_path,
    )
    assert_one_error(res, "afile")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "robot.urdf"]


def test_a_report_that_cannot_be_renamed_into_place_undoes_the_mjcf(tmp_path):
    """The last step of a run failing undoes the others, the files they replaced back."""
    from urdf2mjcf import output

    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "robot.xml").write_text("old robot")
    (folder / "notes.txt").write_text(THESIS)
    with pytest.raises(FileNotFoundError):
        with output.reserved_file(tmp_path / "r.json") as slot, output.together() as batch:
            files = {"robot.xml": b"<mujoco/>", "assets/a.stl": b"solid"}
            output.write_atomic(folder / "robot.xml", files, lambda staged: None)
            assert (folder / "robot.xml").read_text() == "old robot"  # not yet installed
            slot.write(b"{}")
            slot.tmp.unlink()  # its rename will fail
            batch.last(slot.commit)
    assert sorted(p.name for p in folder.iterdir()) == ["notes.txt", "robot.xml"]
    assert (folder / "robot.xml").read_text() == "old robot"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


# -- -o through a symlink to another file system -------------------------------------------


@pytest.fixture
def other_device(tmp_path: Path) -> Path:
    shm = Path("/dev/shm")
    if not shm.is_dir() or shm.stat().st_dev == tmp_path.stat().st_dev:
        pytest.skip("no /dev/shm on another file system than the test's folder")
    folder = Path(tempfile_dir(shm))
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def tempfile_dir(parent: Path) -> str:
    import tempfile

    return tempfile.mkdtemp(prefix="urdf2mjcf-test-", dir=parent)


def test_a_facility_through_a_symlink_to_another_file_system(tmp_path, other_device):
    link = tmp_path / "link"
    link.symlink_to(other_device)
    (other_device / "notes.txt").write_text(THESIS)
    args = ["--root", str(ROOT), "-o", str(link), "--no-components", "--overwrite"]
    for _ in range(2):  # built, then replaced: both through the link
        res = run("make-facility", str(NO_ROBOT), *args, cwd=tmp_path, timeout=300)
        assert res.returncode == 0, res.stderr
        assert link.is_symlink() and (other_device / "facility.json").is_file()
        assert listing(tmp_path) == [str(link)]
        assert not [p for p in other_device.parent.glob(f".{link.name}-*")]
    assert (other_device / "notes.txt").read_text() == THESIS

    # A failure there (a file of the user's where we would write) leaves nothing.
    (other_device / "facility.json").unlink()
    (other_device / "scene.xml").write_text("the user's scene")
    before = snapshot(other_device)
    res = run(
        "make-facility",
        str(NO_ROBOT),
        "--root",
        str(ROOT),
        "-o",
        str(link),
        "--no-components",
        cwd=tmp_path,
        timeout=300,
    )
    assert_one_error(res, "--overwrite")
    assert snapshot(other_device) == before
    assert listing(tmp_path) == [str(link)]
    assert not [p for p in other_device.parent.glob(f".{link.name}-*")]


def test_a_conversion_into_a_symlinked_folder_on_another_file_system(urdf, tmp_path, other_device):
    link = tmp_path / "link"
    link.symlink_to(other_device)
    res = run("urdf2mjcf", str(urdf), "-o", str(link / "robot.xml"), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in other_device.iterdir()) == ["robot.xml", "scene.xml"]


# -- killed at any point (SIGKILL) -----------------------------------------------------------

CHILD = textwrap.dedent(
    """
    import json, os, signal, sys
    from pathlib import Path
    from urdf2mjcf import output

    out, kill_at, tag = Path(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    calls = 0
    real_replace, real_unlink = os.replace, os.unlink

    def counted(real):
        def call(*args, **kwargs):
            global calls
            calls += 1
            if calls == kill_at:
                os.kill(os.getpid(), signal.SIGKILL)
            return real(*args, **kwargs)
        return call

    previous = output.check_folder(out, False, "facility.json", "make-facility")
    with output.staged_folder(out) as stage:
        files = [f"scene-{tag}.xml", f"assets/{tag}.stl", "assets/shared.stl"]
        for rel in files:
            (stage / rel).parent.mkdir(parents=True, exist_ok=True)
            (stage / rel).write_text(tag)
        manifest = {"generator": "make-facility", "files": [*files, "facility.json"]}
        (stage / "facility.json").write_text(json.dumps(manifest))
        os.replace, os.unlink = counted(real_replace), counted(real_unlink)
        output.install_folder(stage, out, previous, overwrite=False, last="facility.json")
        os.replace, os.unlink = real_replace, real_unlink
    print(calls)
    """
)


def install(out: Path, tag: str, kill_at: int = 0) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", CHILD, str(out), str(kill_at), tag],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )


def build_files(out: Path, tag: str) -> dict[str, str]:
    return {
        f"scene-{tag}.xml": tag,
        f"assets/{tag}.stl": tag,
        "assets/shared.stl": tag,
        "notes/thesis.tex": THESIS,
    }


def contents(out: Path) -> dict[str, str]:
    return {
        p.relative_to(out).as_posix(): p.read_text()
        for p in out.rglob("*")
        if p.is_file() and p.name != "facility.json"
    }


def test_a_kill_at_any_point_of_an_install_is_undone_by_the_next_run(tmp_path):
    """SIGKILL at every rename and unlink of install_folder (the real function, in a child
    process): the next run finds the earlier build (never a folder it would refuse as the
    user's), the user's files intact, and completes; nothing hidden is left beside it."""
    probe = tmp_path / "probe"
    assert install(probe, "old").returncode == 0
    (probe / "notes").mkdir()
    (probe / "notes" / "thesis.tex").write_text(THESIS)
    done = install(probe, "new")
    assert done.returncode == 0, done.stderr
    total = int(done.stdout)
    assert total >= 8  # journal, trash, placements, cleanup: each a point to die at

    for kill_at in range(1, total + 1):
        case = tmp_path / f"k{kill_at}"
        case.mkdir()
        out = case / "out"
        assert install(out, "old").returncode == 0
        (out / "notes").mkdir()
        (out / "notes" / "thesis.tex").write_text(THESIS)
        killed = install(out, "new", kill_at)
        assert killed.returncode == -9, (kill_at, killed.stderr)

        again = install(out, "new")  # the next run
        assert again.returncode == 0, (kill_at, again.stderr)
        assert contents(out) == build_files(out, "new"), kill_at
        assert [p.name for p in case.iterdir()] == ["out"], kill_at


def test_a_killed_facility_build_is_completed_by_the_next_make_facility(tmp_path):
    """The same through make-facility: killed in its install, the next build succeeds."""
    out = tmp_path / "out"
    assert install(out, "old").returncode == 0
    (out / "notes").mkdir()
    (out / "notes" / "thesis.tex").write_text(THESIS)
    assert install(out, "new", kill_at=4).returncode == -9
    assert any(p.name.startswith(".out-old-") for p in tmp_path.iterdir())  # it was cut short
    res = run(
        "make-facility",
        str(NO_ROBOT),
        "--root",
        str(ROOT),
        "-o",
        str(out),
        "--no-components",
        cwd=tmp_path,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    assert (out / "notes" / "thesis.tex").read_text() == THESIS
    assert not (out / "scene-old.xml").exists() and not (out / "scene-new.xml").exists()
    assert (out / "scene.xml").is_file()
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_stale_staging_of_a_dead_run_goes_and_a_users_look_alike_stays(urdf, tmp_path):
    out = tmp_path / "robot.xml"
    stale = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    dead = int(stale.stdout)
    ours = tmp_path / ".urdf2mjcf-0123456789ab"
    ours.mkdir()
    (ours / "robot.xml").write_text("half")
    marker = {"pid": dead, "start": None, "host": socket.gethostname(), "kind": "staging"}
    (ours / ".urdf2mjcf-staging").write_text(json.dumps(marker))
    theirs = tmp_path / ".urdf2mjcf-abcdef012345"
    theirs.mkdir()
    (theirs / "diary.txt").write_text(THESIS)
    res = run("urdf2mjcf", str(urdf), "-o", str(out), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert not ours.exists()
    assert (theirs / "diary.txt").read_text() == THESIS
