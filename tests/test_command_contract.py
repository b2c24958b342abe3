"""One error contract for every command (urdf2mjcf, make-facility, facility-demo,
rover-drive), run as a user runs them: bad input of any kind is exactly one line on
stderr starting with 'error:', naming the file (and the element or key), exit code 2,
no traceback, and nothing on disk written or changed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from urdf2mjcf.facility.build import build_facility
from urdf2mjcf.facility.recipe import load_recipe

ROOT = Path(__file__).resolve().parents[1]
WAYPOINTS = ROOT / "recipes" / "demo" / "imetro.yaml"
ENTRY = {
    "urdf2mjcf": "urdf2mjcf_main",
    "make-facility": "make_facility_main",
    "facility-demo": "facility_demo_main",
    "rover-drive": "rover_drive_main",
}
PLAIN_MJCF = (
    '<mujoco model="plain"><worldbody><geom type="sphere" size="0.1"/></worldbody></mujoco>\n'
)
GARBAGE = bytes(range(256)) * 4  # NUL, 0x89, 0xff...: no text encoding reads it
IMETRO_XACRO = "facility/worlds/imetro_world/urdf/imetro_facility.urdf.xacro"


def run(command: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    entry = ENTRY[command]
    code = f"from urdf2mjcf.cli import {entry}; {entry}()"
    return subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=cwd, timeout=600
    )


def tree(*folders: Path) -> dict[str, bytes | None]:
    """Every file (bytes) and folder (None) under ``folders``."""
    out: dict[str, bytes | None] = {}
    for folder in folders:
        for p in folder.rglob("*"):
            out[str(p)] = p.read_bytes() if p.is_file() else None
    return out


def assert_one_error(proc: subprocess.CompletedProcess, *needles: str) -> str:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    line = lines[0]
    assert line.startswith("error: "), line
    assert "internal error" not in line, "bad input must not reach the last-resort guard"
    for needle in needles:
        assert needle in line, (needle, line)
    return line


@pytest.fixture(scope="module")
def facilities(tmp_path_factory) -> dict[str, Path]:
    """An iMETRO facility with its robot, one built without (recipes/imetro-no-robot), and
    a MIRA3D world with a rover."""
    base = tmp_path_factory.mktemp("facilities")
    out = {}
    for name, recipe in (
        ("imetro", "imetro.yaml"),
        ("norobot", "imetro-no-robot.yaml"),
        ("floor", "mira3d-floor.yaml"),
    ):
        report = build_facility(
            load_recipe(ROOT / "recipes" / recipe), base / name, root=ROOT, components=False
        )
        out[name] = report.output
    return out


@pytest.fixture
def work(tmp_path: Path) -> Path:
    """A folder of bad inputs; the commands run in it."""
    (tmp_path / "empty.xml").write_bytes(b"")
    (tmp_path / "garbage.xml").write_bytes(GARBAGE)
    (tmp_path / "plain").mkdir()
    (tmp_path / "plain" / "scene.xml").write_text(PLAIN_MJCF)
    for suffix in ("urdf", "yaml"):
        (tmp_path / f"empty.{suffix}").write_bytes(b"")
        (tmp_path / f"garbage.{suffix}").write_bytes(GARBAGE)
    return tmp_path


def check(command: str, args: list[str], needles: tuple[str, ...], work: Path, *also: Path):
    """Run; one error line with ``needles``; nothing under ``work`` or ``also`` changed."""
    before = tree(work, *also)
    line = assert_one_error(run(command, *args, cwd=work), *needles)
    assert tree(work, *also) == before, f"{command} changed the disk: {line}"


# -- urdf2mjcf ---------------------------------------------------------------------------

URDF_INPUTS = {
    "missing": ("missing.urdf", ("missing.urdf", "no such file")),
    "empty": ("empty.urdf", ("empty.urdf", "Document is empty")),
    "garbage": ("garbage.urdf", ("garbage.urdf",)),
    "mjcf_not_urdf": ("plain/scene.xml", ("scene.xml", "expected <robot>")),
    "folder": ("plain", ("plain", "directory")),
}


@pytest.mark.parametrize("case", sorted(URDF_INPUTS))
def test_urdf2mjcf_bad_source(case, work):
    source, needles = URDF_INPUTS[case]
    args = [source, "-o", "out/robot.xml", "--report", "out/report.json", "--no-ros-env"]
    check("urdf2mjcf", args, needles, work)


# -- make-facility -----------------------------------------------------------------------

RECIPES = {
    "missing": (None, "missing.yaml", ("missing.yaml", "cannot read recipe")),
    "empty": (None, "empty.yaml", ("empty.yaml", "name", "required")),
    "garbage": (None, "garbage.yaml", ("garbage.yaml", "not a text file")),
    "mjcf_scene": (None, "plain/scene.xml", ("scene.xml", "a recipe is a mapping")),
    "yaml_syntax": (
        "name: x\nxacro: [unclosed\n",
        "r.yaml",
        ("r.yaml", "line 3", "not valid YAML"),
    ),
    "unknown_key": (
        f"name: x\nxacro: {IMETRO_XACRO}\nflavour: 1\n",
        "r.yaml",
        ("r.yaml", "flavour"),
    ),
    "flags_wrong_type": (
        f"name: x\nxacro: {IMETRO_XACRO}\nflags: [robot, shelf]\n",
        "r.yaml",
        ("r.yaml", "flags", "mapping"),
    ),
    "placements_wrong_type": (
        f"name: x\nxacro: {IMETRO_XACRO}\nplacements: 5\n",
        "r.yaml",
        ("r.yaml", "placements"),
    ),
    "simulation_wrong_type": (
        f"name: x\nxacro: {IMETRO_XACRO}\nsimulation: fast\n",
        "r.yaml",
        ("r.yaml", "simulation"),
    ),
    "component_field_wrong_type": (
        f"name: x\nxacro: {IMETRO_XACRO}\ncomponents: {{robot: {{asset: 3, standalone: a}}}}\n",
        "r.yaml",
        ("r.yaml", "components.robot.asset"),
    ),
    "gravcomp_not_bool": (
        f"name: x\nxacro: {IMETRO_XACRO}\ngravcomp: sometimes\n",
        "r.yaml",
        ("r.yaml", "gravcomp"),
    ),
    "roles_file_garbage": (
        f"name: x\nxacro: {IMETRO_XACRO}\nflags: {{robot: imetro}}\n"
        "placements: {robot: {xyz: [0, 0, 0]}}\ncomponents: {robot: {asset: imetro_robot, "
        "standalone: facility/robots/imetro_robot/urdf/imetro_robot.urdf.xacro, flag: robot, "
        "roles: garbage.yaml}}\n",
        "r.yaml",
        ("garbage.yaml", "roles file", "not a text file"),
    ),
    "non_text_key": (f"1: x\nname: x\nxacro: {IMETRO_XACRO}\n", "r.yaml", ("r.yaml", "1")),
}


@pytest.mark.parametrize("case", sorted(RECIPES))
def test_make_facility_bad_recipe(case, work):
    text, name, needles = RECIPES[case]
    if text is not None:
        (work / name).write_text(text)
    check("make-facility", [name, "--root", str(ROOT), "-o", "out"], needles, work)


SETS = {
    # the recipe's flags are known: an unknown one says which are valid
    "unknown_flag": ("no_such_flag=true", ("--set no_such_flag", "hatch_4040", "robot")),
    "unknown_section": ("bogus.x=1", ("--set bogus.x", "unknown key 'bogus'")),
    "bool_flag_not_bool": ("hatch_4040=maybe", ("--set hatch_4040", "true or false")),
    "section_as_flag": ("jitter=3", ("--set jitter", "section")),
    "scalar_as_section": ("name.x=1", ("--set name.x", "not a section")),
    "bad_field_value": ("simulation.integrator=Magic", ("simulation.integrator", "Magic")),
    "unknown_field": ("jitter.wobble=1", ("jitter.wobble", "unknown key")),
}


@pytest.mark.parametrize("case", sorted(SETS))
def test_make_facility_bad_set(case, work):
    setting, needles = SETS[case]
    recipe = str(ROOT / "recipes" / "imetro.yaml")
    args = [recipe, "--root", str(ROOT), "-o", "out", "--set", setting]
    check("make-facility", args, ("imetro.yaml", *needles), work)


def test_make_facility_demo_without_a_robot_says_so_before_building(work):
    recipe = str(ROOT / "recipes" / "imetro-no-robot.yaml")
    check(
        "make-facility",
        [recipe, "--root", str(ROOT), "-o", "out", "--demo"],
        ("imetro-no-robot.yaml", "--demo", "no robot"),
        work,
    )


# -- facility-demo and rover-drive: the scene ---------------------------------------------

SCENES = {
    "missing": ("missing.xml", ("missing.xml", "does not exist")),
    "empty": ("empty.xml", ("empty.xml", "no facility.json")),
    "garbage": ("garbage.xml", ("garbage.xml", "no facility.json")),
    "mjcf_folder": ("plain", ("scene.xml", "no facility.json")),
    "mjcf_scene": ("plain/scene.xml", ("scene.xml", "no facility.json")),
}


@pytest.mark.parametrize("command", ["facility-demo", "rover-drive"])
@pytest.mark.parametrize("case", sorted(SCENES))
def test_runners_bad_scene(command, case, work):
    scene, needles = SCENES[case]
    check(command, [scene, "--report", "report.json"], needles, work)


def _broken_copy(facility: Path, work: Path, name: str, file: str, data: bytes) -> Path:
    folder = work / name
    folder.mkdir()
    for f in ("scene.xml", "facility.json"):
        (folder / f).write_bytes((facility / f).read_bytes())
    (folder / file).write_bytes(data)
    return folder


@pytest.mark.parametrize("command", ["facility-demo", "rover-drive"])
@pytest.mark.parametrize(
    "file, data, needles",
    [
        ("facility.json", b"{oops", ("facility.json", "not a manifest")),
        ("facility.json", GARBAGE, ("facility.json", "not a manifest")),
        ("facility.json", b"[1, 2]", ("facility.json", "components")),
        ("scene.xml", GARBAGE, ("scene.xml", "not well-formed XML")),
        ("scene.xml", b"", ("scene.xml", "not well-formed XML")),
    ],
)
def test_runners_broken_facility(command, file, data, needles, facilities, work):
    folder = _broken_copy(facilities["imetro"], work, "broken", file, data)
    check(command, [folder.name, "--report", "report.json"], needles, work)


def test_facility_demo_on_a_facility_without_a_robot(facilities, work):
    check(
        "facility-demo",
        [str(facilities["norobot"]), "--report", "r.json", "--frames", "frames"],
        ("norobot/facility.json", "components.robot.roles", "no robot"),
        work,
        facilities["norobot"],
    )


def test_facility_demo_on_roles_the_scene_lacks(facilities, work):
    folder = _broken_copy(facilities["imetro"], work, "mismatch", "scene.xml", PLAIN_MJCF.encode())
    check(
        "facility-demo",
        [folder.name],
        ("mismatch/facility.json", "components.robot.roles.joints", "no joint named"),
        work,
    )


@pytest.mark.parametrize("facility", ["imetro", "norobot"])
def test_rover_drive_on_a_scene_without_a_rover(facility, facilities, work):
    check(
        "rover-drive",
        [str(facilities[facility]), "--report", "r.json"],
        (f"{facility}/facility.json", "no rover"),
        work,
        facilities[facility],
    )


def test_rover_drive_names_a_rover_the_world_lacks(facilities, work):
    check(
        "rover-drive",
        [str(facilities["floor"]), "--rover", "nope", "--report", "r.json"],
        ("floor/facility.json", "--rover", "no rover 'nope'; rovers: rover"),
        work,
        facilities["floor"],
    )


# -- facility-demo: the waypoints file ----------------------------------------------------


def _spec() -> dict:
    return yaml.safe_load(WAYPOINTS.read_text())


def _edit(change):
    def edited() -> dict:
        spec = _spec()
        change(spec)
        return spec

    return edited


def _set_step(name: str, key: str, value=None, delete: bool = False):
    def change(spec: dict) -> None:
        step = next(s for s in spec["steps"] if s["name"] == name)
        if delete:
            del step[key]
        else:
            step[key] = value

    return _edit(change)


WAYPOINT_CASES = {
    "unknown_kind": (_set_step("demo_home", "kind", "teleport"), ("'demo_home'.kind", "teleport")),
    "missing_kind": (_set_step("init", "kind", delete=True), ("steps[1] 'init'.kind", "required")),
    "missing_position": (
        _set_step("pre_drop", "position", delete=True),
        ("'pre_drop'.position", "required"),
    ),
    "missing_bag": (_edit(lambda s: s.pop("bag")), ("bag", "required")),
    "q_wrong_type": (_set_step("init", "q", "high"), ("'init'.q", "numbers")),
    "q_wrong_length": (_set_step("init", "q", [0.0, 0.1]), ("'init'.q", "needs 8")),
    "speed_wrong_type": (_set_step("init", "speed", "fast"), ("'init'.speed", "fast")),
    "steps_wrong_type": (_edit(lambda s: s.update(steps=5)), ("steps", "list of steps")),
    "unknown_step_key": (_set_step("init", "velocity", 1), ("'init'.velocity", "unknown key")),
    "unknown_frame": (
        _set_step("under_handle", "frame", "nowhere"),
        ("'under_handle'.frame", "no body named 'nowhere'"),
    ),
    "unknown_joint": (
        _set_step("rail_to_0.5", "set", {"no_such_joint": 0.5}),
        ("'rail_to_0.5'.set.no_such_joint", "is not a joint of the robot"),
    ),
    "bad_gripper_action": (
        _set_step("close_gripper", "action", "wiggle"),
        ("'close_gripper'.action", "wiggle"),
    ),
    "unknown_camera": (
        _set_step("find_handle", "camera", "belly"),
        ("'find_handle'.camera", "belly"),
    ),
}


@pytest.mark.parametrize("case", sorted(WAYPOINT_CASES))
def test_facility_demo_bad_waypoints(case, facilities, work):
    make, needles = WAYPOINT_CASES[case]
    (work / "demo.yaml").write_text(yaml.safe_dump(make()))
    args = [str(facilities["imetro"]), "--waypoints", "demo.yaml", "--report", "r.json"]
    check("facility-demo", args + ["--frames", "frames"], ("demo.yaml", *needles), work)


@pytest.mark.parametrize(
    "name, data, needles",
    [
        ("empty.yaml", None, ("empty.yaml", "steps")),
        ("garbage.yaml", None, ("garbage.yaml", "not a text file")),
        ("syntax.yaml", b"steps: [\n", ("syntax.yaml", "line", "not valid YAML")),
        ("list.yaml", b"- a\n- b\n", ("list.yaml", "mapping")),
    ],
)
def test_facility_demo_unreadable_waypoints(name, data, needles, facilities, work):
    if data is not None:
        (work / name).write_bytes(data)
    args = [str(facilities["imetro"]), "--waypoints", name, "--report", "r.json"]
    check("facility-demo", args, needles, work)


def test_facility_demo_trials_check_the_recipe_first(facilities, work):
    (work / "r.yaml").write_text(f"name: x\nxacro: {IMETRO_XACRO}\nflavour: 1\n")
    args = [str(facilities["imetro"]), "--trials", "2", "--recipe", "r.yaml"]
    check("facility-demo", args, ("r.yaml", "flavour"), work)


# -- usage errors and the last-resort guard ----------------------------------------------


@pytest.mark.parametrize("command", sorted(ENTRY))
def test_unknown_option_is_one_usage_line(command, work):
    # a conversion's options are `urdf2mjcf convert`'s (`urdf2mjcf SOURCE` is short for it)
    helps = {"urdf2mjcf": "urdf2mjcf convert --help"}
    check(
        command,
        ["--no-such-option"],
        ("--no-such-option", helps.get(command, f"{command} --help")),
        work,
    )


BUGGY = """
import click
from urdf2mjcf.command_runner import run_command

@click.command("buggy")
def buggy():
    raise KeyError("missing")  # a bug, not bad input

run_command(buggy)
"""


def test_an_unexpected_exception_is_one_line_and_debug_shows_the_traceback():
    quiet = subprocess.run([sys.executable, "-c", BUGGY], capture_output=True, text=True)
    assert quiet.returncode == 1
    assert quiet.stderr.splitlines() == [
        "error: internal error in buggy: KeyError: 'missing'; run with --debug for the traceback"
    ]
    loud = subprocess.run([sys.executable, "-c", BUGGY, "--debug"], capture_output=True, text=True)
    assert loud.returncode == 1
    assert "Traceback" in loud.stderr and "in buggy" in loud.stderr
    assert loud.stderr.splitlines()[-1] == "error: internal error in buggy: KeyError: 'missing'"


WRAPPED_SIGTERM = """
import os, signal, sys, time
from pathlib import Path
import click
from urdf2mjcf.command_runner import run_command
from urdf2mjcf.output import staged_folder

@click.command("stage")
def stage():
    with staged_folder(Path(sys.argv[1])) as folder:
        (folder / "half.xml").write_text("<mujoco/>")
        try:  # as pybind11 does when a module's init is interrupted
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(30)
        except BaseException as exc:
            raise ImportError("initialization failed") from exc

run_command(stage, args=[])
"""


def test_sigterm_that_a_native_import_wraps_is_still_a_termination(tmp_path):
    """SIGTERM landing while a native module is imported reaches us as the module's
    ImportError: still exit 143, one line, the staged output gone."""
    proc = subprocess.run(
        [sys.executable, "-c", WRAPPED_SIGTERM, str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr.splitlines() == [
        "error: stage terminated (SIGTERM); its unfinished output removed"
    ]
    assert list(tmp_path.iterdir()) == []


SWALLOWED_SIGTERM = """
import os, signal, time
import click
from urdf2mjcf.command_runner import run_command

@click.command("swallow")
def swallow():
    try:  # as a __del__ or a C callback does: the exception is printed and dropped
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(30)
    except BaseException:
        pass

run_command(swallow, args=[])
"""


def test_sigterm_whose_exception_was_swallowed_still_exits_143():
    proc = subprocess.run(
        [sys.executable, "-c", SWALLOWED_SIGTERM], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr.splitlines() == [
        "error: swallow terminated (SIGTERM) as it finished; its output is complete"
    ]
