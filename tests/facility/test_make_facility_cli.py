"""make-facility as a user runs it: flags, seeds, and the error contract."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _run(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    code = "from urdf2mjcf.cli import make_facility_main; make_facility_main()"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd, timeout=600
    )


def test_flags_and_seed_from_the_command_line(tmp_path):
    out = tmp_path / "x"
    proc = _run(
        "--set",
        "hatch_4040=true",
        "--set",
        "robot=none",
        "--seed",
        "3",
        "-o",
        str(out),
        "--no-components",
    )
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads((out / "facility.json").read_text())
    assert manifest["seed"] == 3 and manifest["flags"]["hatch_4040"] is True
    joints = {j["name"] for j in manifest["joints"]}
    assert "hatch_4040_door_joint" in joints and "rail" not in joints
    assert "ctb" in manifest["offsets"]


def test_bad_recipe_is_one_error_line_exit_2_and_nothing_written(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "name: bad\nxacro: facility/worlds/imetro_world/urdf/imetro_facility.urdf.xacro\nflavour: 1\n"
    )
    out = tmp_path / "out"
    proc = _run(str(bad), "-o", str(out), "--root", str(ROOT))
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert (
        len(lines) == 1
        and lines[0].startswith("error: ")
        and "bad.yaml" in lines[0]
        and "flavour" in lines[0]
    )
    assert not out.exists()


def test_a_root_without_the_facility_data_is_one_error_line(tmp_path):
    # Without --root the installed data is the last resort (tests/test_wheel_install.py).
    proc = _run("--root", str(tmp_path), cwd=tmp_path)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"error: {tmp_path}: no facility root")


def test_a_failed_build_keeps_the_previous_output(tmp_path):
    out = tmp_path / "keep"
    assert _run("-o", str(out), "--no-components").returncode == 0
    before = (out / "scene.xml").read_bytes()
    proc = _run("-o", str(out), "--set", "simulation.integrator=Magic")
    assert proc.returncode == 2 and "integrator" in proc.stderr
    assert (out / "scene.xml").read_bytes() == before
