"""A built facility handed over by someone else is a stranger's input too: the
runtime refuses files MuJoCo would block on or read forever, and a FIFO at an output
path is never opened (issue 19, items 5 and 4)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from tests.security.attack import assert_one_error, run, snapshot
from urdf2mjcf.bundle import SCHEMA_VERSION

MANIFEST = {"schema_version": SCHEMA_VERSION, "generator": "make-facility", "components": {}}


def _bundle(tmp_path: Path, asset: str) -> Path:
    folder = tmp_path / "bundle"
    folder.mkdir()
    (folder / "facility.json").write_text(json.dumps(MANIFEST))
    (folder / "scene.xml").write_text(
        f'<mujoco><compiler meshdir="assets"/><asset>{asset}</asset><worldbody/></mujoco>\n'
    )
    (folder / "assets").mkdir()
    return folder


@pytest.mark.parametrize("command", ["facility-demo", "rover-drive"])
@pytest.mark.parametrize("kind", ["fifo", "dev_zero"])
def test_a_bundle_mesh_that_is_not_a_regular_file_is_refused(tmp_path, command, kind):
    folder = _bundle(tmp_path, '<mesh name="m" file="evil.stl"/>')
    target = folder / "assets" / "evil.stl"
    if kind == "fifo":
        os.mkfifo(target)
    else:
        target.symlink_to("/dev/zero")
    before = snapshot(tmp_path)
    res = run(command, str(folder), cwd=tmp_path, timeout=60)
    assert_one_error(res, "evil.stl", "not a regular file")
    assert snapshot(tmp_path) == before


def test_an_included_file_that_is_a_fifo_is_refused(tmp_path):
    folder = tmp_path / "bundle"
    folder.mkdir()
    (folder / "facility.json").write_text(json.dumps(MANIFEST))
    (folder / "scene.xml").write_text('<mujoco><include file="part.xml"/></mujoco>\n')
    (folder / "part.xml").write_text('<mujoco><asset><mesh file="/dev/zero"/></asset></mujoco>')
    res = run("rover-drive", str(folder), cwd=tmp_path, timeout=60)
    assert_one_error(res, "/dev/zero", "not a regular file")


def test_a_manifest_that_is_a_fifo_is_refused(tmp_path):
    folder = _bundle(tmp_path, "")
    (folder / "facility.json").unlink()
    os.mkfifo(folder / "facility.json")
    res = run("facility-demo", str(folder), cwd=tmp_path, timeout=60)
    assert_one_error(res, "facility.json")


def test_a_report_path_that_is_a_fifo_is_not_opened(tmp_path, data_dir):
    """An existing FIFO at --report is a file we did not write: refused without
    --overwrite, never opened to see whether it is a report of ours (it would block)."""
    fifo = tmp_path / "report.json"
    os.mkfifo(fifo)
    urdf = tmp_path / "r.urdf"
    urdf.write_text('<robot name="r"><link name="base"/></robot>')
    res = run(
        "urdf2mjcf", str(urdf), "-o", str(tmp_path / "out" / "r.xml"), "--report", str(fifo),
        cwd=tmp_path, timeout=60,
    )
    assert_one_error(res, "report.json", "--overwrite")
    assert not (tmp_path / "out").exists()
