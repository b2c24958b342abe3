"""Never delete or overwrite what we did not write (docs/cli.md, "Output folders and
files"): a folder is built into only when it is empty or holds our manifest from an
earlier run, and then only the files that manifest lists are replaced; --overwrite lets
us write into any folder, still keeping what we did not write. Run as a user runs the
commands."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
NO_ROBOT = str(ROOT / "recipes" / "imetro-no-robot.yaml")
WITH_ROBOT = str(ROOT / "recipes" / "imetro.yaml")
ENTRY = {
    "urdf2mjcf": "urdf2mjcf_main",
    "make-facility": "make_facility_main",
    "facility-demo": "facility_demo_main",
}
THESIS = "\\documentclass{article} my own words\n"
LINK = (
    '<link name="{n}"><inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)


def run(command: str, *args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    entry = ENTRY[command]
    code = f"from urdf2mjcf.cli import {entry}; {entry}()"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd, timeout=600
    )


def files(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()
    }


def refused(proc: subprocess.CompletedProcess, *needles: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert "--overwrite" in lines[0]
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


def user_folder(folder: Path) -> Path:
    """A folder of the user's: DIR/notes/thesis.tex."""
    (folder / "notes").mkdir(parents=True)
    (folder / "notes" / "thesis.tex").write_text(THESIS)
    return folder


def make_facility(out: Path, *args: str, recipe: str = NO_ROBOT) -> subprocess.CompletedProcess:
    return run(
        "make-facility", recipe, "--root", str(ROOT), "-o", str(out), "--no-components", *args
    )


# -- make-facility -o DIR ----------------------------------------------------------------


def test_make_facility_refuses_a_folder_it_did_not_build(tmp_path):
    out = user_folder(tmp_path / "DIR")
    before = files(out)
    refused(make_facility(out), str(out), "facility.json")
    assert files(out) == before, "the user's folder is unchanged"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["DIR"], "no staging folder left"


def test_make_facility_overwrite_writes_beside_the_users_files_and_keeps_them(tmp_path):
    out = user_folder(tmp_path / "DIR")
    proc = make_facility(out, "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert (out / "notes" / "thesis.tex").read_text() == THESIS
    manifest = json.loads((out / "facility.json").read_text())
    assert manifest["generator"] == "make-facility"
    assert "scene.xml" in manifest["files"] and not any("notes" in f for f in manifest["files"])
    assert set(files(out)) == {*manifest["files"], "facility.json", "notes/thesis.tex"}


def test_a_folder_we_built_is_replaced_and_only_our_files_go(tmp_path):
    out = tmp_path / "DIR"
    assert make_facility(out).returncode == 0
    first = json.loads((out / "facility.json").read_text())["files"]
    # the user keeps notes in our build folder, even inside assets/
    user_folder(out)
    (out / "assets" / "mine.txt").write_text("mine")

    # no --overwrite: the folder holds our manifest
    proc = make_facility(out, recipe=str(ROOT / "recipes" / "mira3d-floor.yaml"))
    assert proc.returncode == 0, proc.stderr
    second = json.loads((out / "facility.json").read_text())["files"]
    gone = set(first) - set(second)
    assert any(f.startswith("assets/") for f in gone), "the mockups' meshes are not on the floor"
    assert not any((out / f).exists() for f in gone), "files of the earlier build are removed"
    assert set(files(out)) == {*second, "facility.json", "notes/thesis.tex", "assets/mine.txt"}
    assert (out / "notes" / "thesis.tex").read_text() == THESIS
    assert (out / "assets" / "mine.txt").read_text() == "mine"


def test_a_users_file_where_the_new_build_writes_is_not_replaced(tmp_path):
    out = tmp_path / "DIR"
    assert make_facility(out).returncode == 0
    mine = out / "components" / "ctb" / "ctb.xml"  # the next build (with components) writes it
    mine.parent.mkdir(parents=True)
    mine.write_text("my own ctb")
    before = files(out)
    proc = run("make-facility", NO_ROBOT, "--root", str(ROOT), "-o", str(out))
    refused(proc, "components/ctb/ctb.xml")
    assert files(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["DIR"], "no staging folder left"


def test_a_manifest_listing_paths_outside_the_folder_is_not_ours(tmp_path):
    outside = tmp_path / "precious.txt"
    outside.write_text("keep")
    out = tmp_path / "DIR"
    assert make_facility(out).returncode == 0
    manifest = json.loads((out / "facility.json").read_text())
    manifest["files"].append("../precious.txt")
    (out / "facility.json").write_text(json.dumps(manifest))
    before = files(out)
    refused(make_facility(out))
    assert files(out) == before and outside.read_text() == "keep"


def test_sigterm_during_a_build_leaves_nothing_behind(tmp_path):
    """SIGTERM (as a job scheduler or `kill` sends) while make-facility builds: exit
    143 with one error line, and neither the output nor its hidden staging folder."""
    import signal
    import time

    entry = ENTRY["make-facility"]
    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"from urdf2mjcf.cli import {entry}; {entry}()",
            NO_ROBOT,
            "-o",
            str(tmp_path / "out"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".out-*")):  # the build is under way in its staging folder
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: make-facility terminated"), err
    assert list(tmp_path.iterdir()) == []


def test_an_empty_folder_is_built_into(tmp_path):
    out = tmp_path / "DIR"
    out.mkdir()
    assert make_facility(out).returncode == 0
    assert (out / "scene.xml").is_file()


# -- urdf2mjcf -o, --report --------------------------------------------------------------


@pytest.fixture
def urdf(tmp_path: Path) -> Path:
    src = tmp_path / "in" / "robot.urdf"
    src.parent.mkdir()
    src.write_text(f'<robot name="r">{LINK.format(n="a")}</robot>')
    return src


def test_urdf2mjcf_refuses_existing_files_and_overwrite_keeps_unrelated_ones(urdf, tmp_path):
    out = user_folder(tmp_path / "DIR")
    (out / "robot.xml").write_text("my robot")
    (out / "assets").mkdir()
    (out / "assets" / "mine.stl").write_text("my mesh")
    before = files(out)
    refused(run("urdf2mjcf", str(urdf), "-o", str(out / "robot.xml")), "robot.xml")
    assert files(out) == before

    proc = run("urdf2mjcf", str(urdf), "-o", str(out / "robot.xml"), "--overwrite")
    assert proc.returncode == 0, proc.stderr
    after = files(out)
    assert b"<mujoco" in after["robot.xml"] and "scene.xml" in after
    for kept in ("notes/thesis.tex", "assets/mine.stl"):
        assert after[kept] == before[kept]


def test_a_failed_conversion_leaves_an_existing_folder_as_it_was(tmp_path):
    # MuJoCo rejects it at the last stage, after the files were staged
    src = tmp_path / "unstable.urdf"
    src.write_text(
        f'<robot name="r">{LINK.format(n="a")}'
        '<mujoco><option gravity="0 0 -1e11"/></mujoco></robot>'
    )
    out = user_folder(tmp_path / "DIR")
    (out / "robot.xml").write_text("my robot")
    before = files(out)
    args = [str(src), "-o", str(out / "robot.xml"), "--floating-base", "--overwrite"]
    proc = run("urdf2mjcf", *args)
    assert proc.returncode == 2 and "MuJoCo warned" in proc.stderr, proc.stderr
    assert files(out) == before and sorted(p.name for p in out.iterdir()) == ["notes", "robot.xml"]
    # into a folder that did not exist: not even the folder is left
    proc = run("urdf2mjcf", str(src), "-o", str(tmp_path / "a" / "b" / "r.xml"), "--floating-base")
    assert proc.returncode == 2 and not (tmp_path / "a").exists()


def test_urdf2mjcf_report_is_refused_before_the_work(urdf, tmp_path):
    report = tmp_path / "report.json"
    report.write_text("my notes")
    out = tmp_path / "out" / "robot.xml"
    refused(run("urdf2mjcf", str(urdf), "-o", str(out), "--report", str(report)), "report.json")
    assert report.read_text() == "my notes" and not out.parent.exists()

    proc = run("urdf2mjcf", str(urdf), "-o", str(out), "--report", str(report), "--overwrite")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(report.read_text())
    assert data["generator"] == "urdf2mjcf" and data["robot"] == "r"


# -- facility-demo --report, --frames ----------------------------------------------------


@pytest.fixture(scope="module")
def facility(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "imetro"
    assert make_facility(out, recipe=WITH_ROBOT).returncode == 0
    return out


def short_demo(folder: Path, step: str) -> Path:
    """The demo file with one short step that takes a picture (the demo then fails its
    success check, exit 1, but writes its report and pictures)."""
    spec = yaml.safe_load((ROOT / "recipes" / "demo" / "imetro.yaml").read_text())
    spec["steps"] = [{"name": step, "kind": "wait", "seconds": 0.02, "snapshot": True}]
    spec["final_wait"] = 0.0
    path = folder / f"{step}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def demo(facility: Path, waypoints: Path, *args: str) -> subprocess.CompletedProcess:
    return run("facility-demo", str(facility), "--waypoints", str(waypoints), *args)


def test_facility_demo_refuses_a_report_and_a_frames_folder_it_did_not_write(facility, tmp_path):
    waypoints = short_demo(tmp_path, "first")
    report = tmp_path / "report.json"
    report.write_text("my notes")
    frames = user_folder(tmp_path / "frames")
    refused(demo(facility, waypoints, "--report", str(report)), "report.json")
    assert report.read_text() == "my notes"
    before = files(frames)
    refused(demo(facility, waypoints, "--frames", str(frames)), "frames", "frames.json")
    assert files(frames) == before


def test_facility_demo_replaces_its_own_report_and_frames(facility, tmp_path):
    report, frames = tmp_path / "report.json", tmp_path / "frames"
    first = demo(
        facility, short_demo(tmp_path, "first"), "--report", str(report), "--frames", str(frames)
    )
    assert first.returncode == 1, first.stderr  # the bag is not stowed: a failed demo
    assert json.loads(report.read_text())["steps"][0]["name"] == "first"
    assert {"first.png", "final.png", "frames.json"} <= set(files(frames))
    user_folder(frames)  # the user's notes among our pictures

    second = demo(
        facility, short_demo(tmp_path, "second"), "--report", str(report), "--frames", str(frames)
    )
    assert second.returncode == 1, second.stderr
    data = json.loads(report.read_text())
    assert data["generator"] == "facility-demo" and data["steps"][0]["name"] == "second"
    listed = json.loads((frames / "frames.json").read_text())["files"]
    assert set(files(frames)) == {*listed, "frames.json", "notes/thesis.tex"}
    assert "second.png" in listed and not (frames / "first.png").exists()


def test_facility_demo_overwrite_writes_into_the_users_folder_and_keeps_its_files(
    facility, tmp_path
):
    frames = user_folder(tmp_path / "frames")
    report = tmp_path / "report.json"
    report.write_text("my notes")
    args = ["--report", str(report), "--frames", str(frames), "--overwrite"]
    proc = demo(facility, short_demo(tmp_path, "first"), *args)
    assert proc.returncode == 1, proc.stderr
    assert json.loads(report.read_text())["generator"] == "facility-demo"
    assert (frames / "notes" / "thesis.tex").read_text() == THESIS
    assert (frames / "first.png").is_file()


def test_an_interrupt_the_instant_a_staging_folder_is_made_leaves_nothing(tmp_path, monkeypatch):
    """Where a SIGTERM sent on seeing the staging folder lands: just after the folder
    is made, before its maker has returned its name."""
    import os

    from urdf2mjcf import output

    real = os.mkdir

    def mkdir_then_interrupt(path, *args, **kwargs):
        real(path, *args, **kwargs)
        if Path(path).name.startswith((".out-", ".urdf2mjcf-")):
            raise KeyboardInterrupt

    monkeypatch.setattr(os, "mkdir", mkdir_then_interrupt)
    with pytest.raises(KeyboardInterrupt), output.staged_folder(tmp_path / "out"):
        pass
    with pytest.raises(KeyboardInterrupt):
        output.write_atomic(tmp_path / "new" / "robot.xml", {"robot.xml": b"<mujoco/>"}, print)
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []
