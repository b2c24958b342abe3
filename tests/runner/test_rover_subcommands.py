"""``rover-drive``'s sub-commands (drive, plan, deliver, console): each takes only its own
options, and the spelling from before sub-commands does the same run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from urdf2mjcf.envs import build as env_build
from urdf2mjcf.runner.rover.cli import SUBCOMMANDS, rover_drive_group

ROOT = Path(__file__).resolve().parents[2]
DRIVE = ["--distance", "0.3", "--turn", "20", "--settle", "0.3"]


@pytest.fixture(scope="session")
def floor(_session_cache: Path) -> Path:
    return env_build.facility_folder("mira3d-floor", root=ROOT)[0]


def _report(args: list[str], report: Path) -> dict:
    result = CliRunner().invoke(rover_drive_group, [*args, "--report", str(report)])
    assert result.exit_code == 0, result.output
    data = json.loads(report.read_text())
    data.pop("scene")
    return data


def test_drive_and_the_old_spelling_give_the_same_report(floor, tmp_path):
    new = _report(["drive", str(floor), *DRIVE], tmp_path / "new.json")
    old = _report([str(floor), *DRIVE], tmp_path / "old.json")
    assert new == old and new["tasks"]


def test_plan_takes_its_file_as_an_argument_as_the_old_plan_option_does(floor, tmp_path):
    plan = tmp_path / "plan.yaml"
    plan.write_text("tasks:\n  - {kind: straight, distance: 0.2}\n")
    new = _report(["plan", str(floor), str(plan), "--settle", "0.3"], tmp_path / "new.json")
    old = _report([str(floor), "--plan", str(plan), "--settle", "0.3"], tmp_path / "old.json")
    assert new == old and len(new["tasks"]) == 1


@pytest.mark.parametrize(
    ("command", "option"),
    [("console", "--distance"), ("deliver", "--rover"), ("plan", "--turn"), ("drive", "--port")],
)
def test_a_sub_command_has_only_its_own_options(floor, tmp_path, command, option):
    args = [command, str(floor), *(["plan.yaml"] if command == "plan" else []), option, "1"]
    result = CliRunner().invoke(rover_drive_group, args)
    assert result.exit_code == 2 and f"No such option '{option}'" in result.output


def test_the_old_spelling_keeps_its_option_checks(floor):
    result = CliRunner().invoke(rover_drive_group, [str(floor), "--console", "--distance", "1"])
    assert result.exit_code == 2 and "--console runs no drive" in result.output


def test_help_lists_the_declared_sub_commands():
    result = CliRunner().invoke(rover_drive_group, ["--help"])
    listed = [line.split()[0] for line in result.output.split("Commands:")[1].splitlines() if line]
    assert sorted(listed) == sorted(SUBCOMMANDS)
