"""A built facility is a self-contained bundle: make-facility copies in the recipe it was
built from and the demo it was built for, facility.json names them and its schema
version, and the runtime replays the bundle moved anywhere, without the repository's
recipes; a bundle of another schema version is one error line."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from urdf2mjcf import bundle
from urdf2mjcf.errors import InputError
from urdf2mjcf.facility.build import build_facility, recipe_text
from urdf2mjcf.facility.recipe import load_recipe, parse_recipe

ROOT = Path(__file__).resolve().parents[1]
RECIPES = ROOT / "recipes"
DEMO = RECIPES / "demo" / "imetro.yaml"
# The runtime must not look for a facility root: in these subprocesses every way of
# finding one fails loudly (an AssertionError is no bad input: exit 1, not 0 or 2).
NO_ROOT = """
from urdf2mjcf import headless

headless.configure()  # before mujoco is imported, as the command does
import urdf2mjcf.facility.root as root

def nowhere(*args, **kwargs):
    raise AssertionError("the runtime looked for the facility root")

root.find_root = root.installed_data = nowhere
from urdf2mjcf.cli import {entry}
{entry}()
"""
ENTRY = {"facility-demo": "facility_demo_main", "rover-drive": "rover_drive_main"}


def run(command: str, *args: str, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    code = NO_ROOT.format(entry=ENTRY[command])
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd,
        timeout=timeout,
    )  # fmt: skip


def _same(a, b) -> bool:
    """Two recipes alike but for the file they were read from."""
    return dataclasses.replace(a, path=None) == dataclasses.replace(b, path=None)


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """The default facility without its components: what the demo tests build."""
    out = tmp_path_factory.mktemp("bundle") / "imetro"
    build_facility(load_recipe(RECIPES / "imetro.yaml"), out, root=ROOT, components=False)
    return out


def test_the_bundle_holds_its_recipe_and_its_demo_and_the_manifest_names_them(built):
    manifest = json.loads((built / "facility.json").read_text())
    assert manifest["schema_version"] == bundle.SCHEMA_VERSION == 1
    assert manifest["bundle"] == {"recipe": "recipe.yaml", "demo": "demo.yaml"}
    assert {"recipe.yaml", "demo.yaml"} <= set(manifest["files"])  # ours: a rebuild replaces them
    assert (built / "demo.yaml").read_bytes() == DEMO.read_bytes()
    copy = load_recipe(built / "recipe.yaml")  # no root: its component table is inline
    assert _same(copy, load_recipe(RECIPES / "imetro.yaml", root=ROOT))


@pytest.mark.parametrize("name", sorted(p.stem for p in RECIPES.glob("*.yaml")))
def test_the_recipe_copy_reads_back_to_the_recipe_it_was_built_from(name):
    recipe = load_recipe(RECIPES / f"{name}.yaml", root=ROOT)
    text = recipe_text(recipe)
    back = parse_recipe(yaml.safe_load(text), None, ROOT)
    assert _same(back, recipe)
    assert recipe_text(back) == text  # the same recipe, the same bytes


def test_the_recipe_copy_is_the_recipe_as_built_with_its_set_edits():
    recipe = load_recipe(RECIPES / "imetro.yaml", {"hatch_4040": "true"}, root=ROOT)
    back = parse_recipe(yaml.safe_load(recipe_text(recipe)), None, ROOT)
    assert back.flags["hatch_4040"] is True and _same(back, recipe)


def test_a_recipe_that_places_no_robot_gets_no_demo_and_the_manifest_says_so(tmp_path):
    out = build_facility(
        load_recipe(RECIPES / "mira3d-floor.yaml"), tmp_path / "floor", root=ROOT, components=False
    ).output
    manifest = json.loads((out / "facility.json").read_text())
    assert manifest["bundle"] == {"recipe": "recipe.yaml", "demo": None}
    assert not (out / "demo.yaml").exists() and "demo.yaml" not in manifest["files"]


def _portable(built: Path, tmp_path: Path) -> tuple[Path, Path]:
    """The bundle moved into an empty folder, and another empty folder to run in."""
    moved = tmp_path / "elsewhere" / "imetro"
    moved.parent.mkdir()
    shutil.copytree(built, tmp_path / "copy")
    shutil.move(tmp_path / "copy", moved)
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    return moved, cwd


@pytest.mark.slow
def test_a_moved_bundle_replays_its_demo_without_the_repository(built, tmp_path, gl_context):
    moved, cwd = _portable(built, tmp_path)
    report = cwd / "report.json"
    res = run("facility-demo", str(moved), "--report", str(report), cwd=cwd, timeout=1200)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "SUCCESS" in res.stdout and "open_lid" in res.stdout
    data = json.loads(report.read_text())
    assert data["ok"] and all(s["ok"] for s in data["steps"])


def test_a_bundles_demo_is_the_one_replayed(built, tmp_path, gl_context):
    """Without --waypoints the bundle's own demo.yaml runs, not the repository's: a
    copy cut to its first step runs that step alone (and so fails the verdict)."""
    moved, cwd = _portable(built, tmp_path)
    spec = yaml.safe_load((moved / "demo.yaml").read_text())
    first, second = (s["name"] for s in spec["steps"][:2])
    spec["steps"] = spec["steps"][:1]
    (moved / "demo.yaml").write_text(yaml.safe_dump(spec))
    res = run("facility-demo", str(moved), cwd=cwd)
    assert res.returncode == 1, res.stdout + res.stderr
    lines = res.stdout.splitlines()
    assert any(line.startswith(f"{first:<22} ok") for line in lines), res.stdout
    assert not any(line.startswith(f"{second:<22} ") for line in lines), res.stdout
    assert "FAILED" in res.stdout


def test_a_bundle_without_a_demo_asks_for_one(built, tmp_path):
    moved, cwd = _portable(built, tmp_path)
    manifest = json.loads((moved / "facility.json").read_text())
    manifest["bundle"]["demo"] = None
    (moved / "facility.json").write_text(json.dumps(manifest))
    (moved / "demo.yaml").unlink()
    res = run("facility-demo", str(moved), "--report", "r.json", cwd=cwd)
    assert res.returncode == 2, res.stderr
    (line,) = res.stderr.splitlines()
    assert line.startswith("error: ") and "facility.json: bundle.demo" in line
    assert "--waypoints" in line
    assert list(cwd.iterdir()) == []


def test_trials_rebuild_the_bundles_recipe_copy_by_default(built, tmp_path, monkeypatch):
    from urdf2mjcf.runner import cli

    moved, cwd = _portable(built, tmp_path)
    seen = []

    def trials(run, seed, n, frames):  # what would run, without running it
        seen.append(run)
        return {}, True

    monkeypatch.setattr(cli, "_trials", trials)
    monkeypatch.chdir(cwd)
    res = CliRunner().invoke(cli.facility_demo_command, [str(moved), "--trials", "2"])
    assert res.exit_code == 0, res.output
    (run_,) = seen
    assert run_.recipe == moved / "recipe.yaml" and run_.waypoints == moved / "demo.yaml"


def test_trials_of_a_recipe_naming_its_own_files_ask_for_the_original(built, tmp_path):
    """A recipe's own xacro beside it is not in the bundle: refused before any trial."""
    from urdf2mjcf.runner.trials import check_recipe

    assert check_recipe(built / "recipe.yaml") == ROOT  # ours: under the facility root
    copy = tmp_path / "recipe.yaml"
    copy.write_text("name: my-lab\nxacro: my_lab.urdf.xacro\n")
    with pytest.raises(InputError, match=r"recipe.yaml: xacro: 'my_lab.urdf.xacro' .*--recipe"):
        check_recipe(copy)


@pytest.mark.parametrize("command", ["facility-demo", "rover-drive"])
@pytest.mark.parametrize("version", [None, 2, "1"])
def test_a_bundle_of_another_schema_version_is_one_error_line(built, tmp_path, command, version):
    moved, cwd = _portable(built, tmp_path)
    manifest = json.loads((moved / "facility.json").read_text())
    if version is None:
        del manifest["schema_version"]  # an older make-facility's bundle
    else:
        manifest["schema_version"] = version
    (moved / "facility.json").write_text(json.dumps(manifest))
    res = run(command, str(moved), "--report", "r.json", cwd=cwd)
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr
    (line,) = res.stderr.splitlines()
    assert line.startswith("error: ")
    assert "facility.json: schema_version:" in line and "rebuild it with make-facility" in line
    assert ("missing" in line) == (version is None)
    assert list(cwd.iterdir()) == []  # nothing written
