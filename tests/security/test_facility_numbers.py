"""Every number a recipe, a ``--set``, a waypoints file or the facility commands'
options give is finite and in its documented range: a bad one is one ``error:``
line naming where it came from, exit 2, nothing written, within a time bound and
the memory rlimit (issue 19, items 5 and 6).

Each probe runs the real command in a fresh process (``attack.run``) and is
refused before any build or simulation starts, so each takes a second or two;
the ones that hung or crashed before (``rocks.count=1000000000``, ``timestep:
1e-300``, ``--settle 1e9``, 1e300 in a placement, ``--seed -1`` with trials, an
alias bomb) are quoted as the issue found them.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from .attack import ROOT, assert_one_error, run, snapshot

TIMEOUT = 60
"""s: each probe is refused before any build; a hang fails the test."""

MOON = ROOT / "recipes" / "mira3d-moon.yaml"
IMETRO = ROOT / "recipes" / "imetro.yaml"


def _recipe(tmp_path: Path, source: Path, *edits: tuple[str, str]) -> Path:
    """A copy of one of our recipes in ``tmp_path`` with ``edits`` (regex, replacement)
    applied; its component table named from the facility root (``--root``)."""
    text = source.read_text()
    text = text.replace("components: components/", "components: recipes/components/")
    for pattern, replacement in edits:
        text, n = re.subn(pattern, replacement, text, count=1, flags=re.M)
        assert n == 1, pattern
    path = tmp_path / "attack.yaml"
    path.write_text(text)
    return path


def _refused(tmp_path: Path, recipe: Path, *args: str, needles: tuple[str, ...]) -> str:
    """make-facility with ``recipe`` and ``args``: one error line holding ``needles``,
    exit 2, within TIMEOUT and the memory limit, nothing written anywhere."""
    out = tmp_path / "out"
    before = snapshot(tmp_path)
    res = run(
        "make-facility",
        str(recipe),
        "--root",
        str(ROOT),
        "-o",
        str(out),
        "--no-components",
        *args,
        cwd=tmp_path,
        timeout=TIMEOUT,
    )
    line = assert_one_error(res, *needles)
    assert not out.exists()
    assert snapshot(tmp_path) == before
    return line


# -- the recipe's simulation options -------------------------------------------------------


@pytest.mark.parametrize(
    "value, needle",
    [
        ("1e-300", "1e-300 is out of range"),  # hung validation (1/timestep steps)
        ("1.0e300", "1e+300 is out of range"),
        ("0", "0 is out of range"),
        ("-0.002", "is out of range"),
        (".nan", "not finite"),
        (".inf", "not finite"),
        ("fast", "not a number"),
    ],
)
def test_a_timestep_out_of_range_is_refused_with_its_line(tmp_path, value, needle):
    recipe = _recipe(tmp_path, MOON, (r"^  timestep: 0\.002$", f"  timestep: {value}"))
    line = _refused(tmp_path, recipe, needles=("attack.yaml", "simulation.timestep", needle))
    assert "(line " in line


@pytest.mark.parametrize(
    "value, needle",
    [("7.5", "not a whole number"), ("0", "not a whole number"), ("1000000000", "1 to 10000")],
)
def test_iterations_is_a_whole_number_in_range(tmp_path, value, needle):
    recipe = _recipe(
        tmp_path, MOON, (r"^  impratio: 10$", f"  impratio: 10\n  iterations: {value}")
    )
    _refused(tmp_path, recipe, needles=("simulation.iterations", needle))


def test_an_impratio_of_zero_or_huge_is_refused(tmp_path):
    recipe = _recipe(tmp_path, MOON, (r"^  impratio: 10$", "  impratio: 0"))
    _refused(tmp_path, recipe, needles=("simulation.impratio", "out of range"))
    _refused(tmp_path, MOON, "--set", "simulation.impratio=1e9", needles=("simulation.impratio",))


@pytest.mark.parametrize(
    "sets, needles",
    [
        # the probes: a bare `timestep` is not a flag of the recipe
        (("timestep=1e-300",), ("--set timestep", "unknown")),
        (("simulation.timestep=1e-300",), ("simulation.timestep", "out of range")),
        (("rocks.count=1000000000",), ("rocks.count", "0 to 10000")),
        (("rocks.count=-1",), ("rocks.count",)),
        (("rocks.seed=-1",), ("rocks.seed",)),
        (("rocks.size=[0, 1]",), ("rocks.size", "out of range")),
        (("rocks.area=[-1e300, 1e300, 0, 1]",), ("rocks.area", "out of range")),
        (("rocks.clearance=-1",), ("rocks.clearance",)),
        (("rocks.variants=0",), ("rocks.variants",)),
        (("terrain_size_x=-5",), ("flags.terrain_size_x", "out of range")),
        (("terrain_z_max=nan",), ("flags.terrain_z_max", "not finite")),
        (("gravity=-9.81",), ("flags.gravity", "out of range")),
        (("gravity=inf",), ("flags.gravity", "not finite")),
        (("jitter.default.position=1e300",), ("jitter.default.position", "out of range")),
        (("jitter.default.yaw=-0.1",), ("jitter.default.yaw", "out of range")),
        (("noise.exposure.gain=2",), ("noise.exposure.gain", "out of range")),
        (("noise.depth.baseline=0",), ("noise.depth.baseline", "out of range")),
        (("noise.rgb.read_std=nan",), ("noise.rgb.read_std", "not finite")),
    ],
)
def test_set_values_are_checked_before_the_build(tmp_path, sets, needles):
    args = [a for s in sets for a in ("--set", s)]
    line = _refused(tmp_path, MOON, *args, needles=needles)
    assert "(line " not in line  # a --set value is not in the file


@pytest.mark.parametrize(
    "pattern, replacement, needles",
    [
        (r"xyz: \[30, 0, 0\]", "xyz: [1.0e300, 0, 0]", ("placements.rover.xyz.0", "out of range")),
        (r"xyz: \[30, 0, 0\]", "xyz: [.nan, 0, 0]", ("placements.rover.xyz.0", "not finite")),
        (r"xyz: \[30, 0, 0\]", "xyz: [30, -.inf, 0]", ("placements.rover.xyz.1", "not finite")),
        (r"xyz: \[30, 0, 0\], yaw: 0", "xyz: [30, 0, 0], yaw: 1.0e300", ("placements.rover.yaw",)),
        (r"^  count: 30$", "  count: 1000000000", ("rocks.count", "0 to 10000")),
        (r"^  count: 30$", "  count: 30.5", ("rocks.count", "whole number")),
        (r"^  seed: 3$", "  seed: 100000000000000000000", ("rocks.seed", "4294967295")),
        (r"^  size: \[0.2, 0.9\]$", "  size: [0.2, .inf]", ("rocks.size", "not finite")),
        (r"^    - \[24, 45, -3.5, 3.5\]$", "    - [24, 45, .nan, 3.5]", ("rocks.keepout",)),
        (r"^  clearance: 3.0$", "  clearance: -1", ("rocks.clearance", "out of range")),
        (r"^  terrain_size_x: 1000$", "  terrain_size_x: 0", ("flags.terrain_size_x",)),
        (r"^  depth: \{subpixel: 0.2165", "  depth: {subpixel: 1.0e300", ("noise.depth.subpixel",)),
    ],
)
def test_recipe_numbers_are_checked_with_their_line(tmp_path, pattern, replacement, needles):
    recipe = _recipe(tmp_path, MOON, (pattern, replacement))
    line = _refused(tmp_path, recipe, needles=("attack.yaml", *needles))
    assert "(line " in line


@pytest.mark.parametrize(
    "pattern, replacement, needles",
    [
        (
            r"^  strap_stiffness: 0 ",
            "  strap_stiffness: -5 ",
            ("flags.strap_stiffness", "out of range"),
        ),
        (r"^  strap_stiffness: 0 ", "  strap_stiffness: .nan ", ("flags.strap_stiffness",)),
        (r"^  strap_stiffness: 0 ", "  strap_stiffness: '-5' ", ("flags.strap_stiffness",)),
        (
            r"ctb: \{position: 0.05, yaw: 0.2618\}",
            "ctb: {position: 1.0e300, yaw: 0.2618}",
            ("jitter.ctb.position", "out of range"),
        ),
        (
            r"ctb: \{position: 0.05, yaw: 0.2618\}",
            "ctb: {position: 0.05, yaw: .nan}",
            ("jitter.ctb.yaw", "not finite"),
        ),
        (
            r"default: \{position: 0.02, yaw: 0.0349\}",
            "default: {position: .inf, yaw: 0.0349}",
            ("jitter.default.position", "not finite"),
        ),
        # a flag must not smuggle a value past its own section's checks
        (
            r"^  floor_beams: false ",
            "  timestep: 1.0e-300\n  floor_beams: false ",
            ("flags.timestep",),
        ),
        (r"^  floor_beams: false ", "  ctb_x: 1.0e300\n  floor_beams: false ", ("flags.ctb_x",)),
    ],
)
def test_imetro_recipe_numbers_are_checked(tmp_path, pattern, replacement, needles):
    recipe = _recipe(tmp_path, IMETRO, (pattern, replacement))
    _refused(tmp_path, recipe, "--seed", "1", needles=("attack.yaml", *needles))


def test_strap_stiffness_from_the_command_line_is_checked(tmp_path):
    _refused(tmp_path, IMETRO, "--set", "strap_stiffness=-5", needles=("flags.strap_stiffness",))


def test_an_option_a_world_ignores_is_refused_not_dropped(tmp_path):
    """A world xacro that does not pass a recipe's ``simulation:`` option to ``<option>``
    would build with MuJoCo's default: the manifest's check refuses it, naming the key."""
    import mujoco

    from urdf2mjcf.errors import InputError
    from urdf2mjcf.facility.manifest import check_simulation
    from urdf2mjcf.facility.recipe import load_recipe

    recipe = load_recipe(IMETRO, {"simulation.iterations": "7"}, ROOT)
    options = {k: v for k, v in recipe.simulation.items() if k != "iterations"}
    attrs = " ".join(f'{k}="{v}"' for k, v in options.items())
    ignoring = mujoco.MjModel.from_xml_string(f"<mujoco><option {attrs}/><worldbody/></mujoco>")
    with pytest.raises(InputError, match="does not set option 'iterations'") as err:
        check_simulation(ignoring, recipe)
    assert err.value.element == "simulation.iterations"


@pytest.mark.parametrize("recipe", ["imetro.yaml", "mira3d-floor.yaml"])
def test_an_iterations_option_is_in_the_built_model(tmp_path, recipe):
    """Both worlds pass ``iterations`` to ``<option>`` (it was silently ignored in the
    iMETRO world): the built model has it."""
    import mujoco

    out = tmp_path / "out"
    res = run(
        "make-facility",
        str(IMETRO.with_name(recipe)),
        "--root",
        str(ROOT),
        "-o",
        str(out),
        "--no-components",
        "--set",
        "simulation.iterations=7",
        cwd=tmp_path,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert mujoco.MjModel.from_xml_path(str(out / "scene.xml")).opt.iterations == 7


# -- command-line options --------------------------------------------------------------------


@pytest.mark.parametrize(
    "args, needle",
    [
        (("--seed", "-1"), "--seed"),
        (("--seed", "4294967296"), "--seed"),
        (("--seed", "nan"), "--seed"),
        (("-j", "-1"), "--jobs"),
        (("-j", "100000000"), "--jobs"),
    ],
)
def test_make_facility_options_are_checked(tmp_path, args, needle):
    _refused(tmp_path, MOON, *args, needles=(needle,))


@pytest.mark.parametrize(
    "args, needle",
    [
        (("--trials", "2", "--seed", "-1"), "--seed"),  # was reported as two failed demos
        (("--trials", "0"), "--trials"),
        (("--trials", "-3"), "--trials"),
        (("--trials", "1000000000"), "--trials"),
        (("--trials", "2", "--seed", "4294967295"), "--seed"),  # the last seed is over
        (("--trials", "2", "--workers", "0"), "--workers"),
        (("--trials", "nan"), "--trials"),
    ],
)
def test_facility_demo_options_are_checked_before_anything_runs(tmp_path, args, needle):
    report = tmp_path / "r.json"
    before = snapshot(tmp_path)
    res = run(
        "facility-demo",
        str(tmp_path),
        *args,
        "--report",
        str(report),
        cwd=tmp_path,
        timeout=TIMEOUT,
    )
    assert_one_error(res, needle)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "args, needle",
    [
        (("--settle", "1e9"), "--settle"),  # hung: 5e11 steps
        (("--settle", "nan"), "--settle"),
        (("--settle", "-1"), "--settle"),
        (("--distance", "inf"), "--distance"),
        (("--distance", "1e300"), "--distance"),
        (("--speed", "0"), "--speed"),
        (("--speed", "nan"), "--speed"),
        (("--turn", "1e9"), "--turn"),
        (("--rate", "-30"), "--rate"),
    ],
)
def test_rover_drive_options_are_refused_before_the_bundle_loads(tmp_path, args, needle):
    """SCENE is an empty folder: the option is refused before it is even looked at."""
    report = tmp_path / "r.json"
    before = snapshot(tmp_path)
    res = run(
        "rover-drive", str(tmp_path), *args, "--report", str(report), cwd=tmp_path, timeout=TIMEOUT
    )
    assert_one_error(res, needle)
    assert snapshot(tmp_path) == before


# -- waypoints files -------------------------------------------------------------------------

DEMO = ROOT / "recipes" / "demo" / "imetro.yaml"


@pytest.mark.parametrize(
    "pattern, replacement, needles",
    [
        (r"^final_wait: 1.5$", "final_wait: 1.0e+9", ("final_wait", "out of range")),
        (r"^final_wait: 1.5$", "final_wait: .nan", ("final_wait", "not finite")),
        (r"step_time: 1.2 ", "step_time: 1.0e+300 ", ("step_time", "out of range")),
        (r"steps: 8$", "steps: 1000000000", ("open_lid'.steps", "whole number")),
        (r"perception: \{size: \[480, 640\]\}", "perception: {size: [480, 1.0e+9]}", ("size[1]",)),
        (r"position: \[0.61, 0.197, -0.0285\]", "position: [.inf, 0, 0]", ("position[0]",)),
        (r"z: \[0, 0, -1\]", "z: [0, 0, 0]", ("hover'.z", "all zeros")),
        (r"x: \[1, 0, 0\]", "x: [0, 0, -2]", ("hover'.x", "parallel")),
        (r"seconds: 1.5", "seconds: 1.0e+300", ("close'.seconds", "out of range")),
        (r"speed: 0.5", "speed: 0", ("pre_drop'.speed", "out of range")),
        (r"trainer: \{xyz: \[-2.0992", "trainer: {xyz: [1.0e+300", ("nominal.trainer.xyz[0]",)),
        (
            r"orientation_xyzw: \[0.725, 0.688, 0.032, -0.004\]",
            "orientation_xyzw: [0, 0, 0, 0]",
            ("orientation_xyzw", "all zeros"),
        ),
        (r"min_tags: 2", "min_tags: -2", ("min_tags",)),
    ],
)
def test_waypoints_numbers_are_checked_before_the_facility_loads(
    tmp_path, pattern, replacement, needles
):
    text, n = re.subn(pattern, replacement, DEMO.read_text(), count=1, flags=re.M)
    assert n == 1, pattern
    waypoints = tmp_path / "demo.yaml"
    waypoints.write_text(text)
    before = snapshot(tmp_path)
    res = run(
        "facility-demo", str(tmp_path), "--waypoints", str(waypoints), cwd=tmp_path, timeout=TIMEOUT
    )
    line = assert_one_error(res, "demo.yaml", *needles)
    assert "(line " in line
    assert snapshot(tmp_path) == before


# -- YAML alias bombs, end to end ------------------------------------------------------------

BOMB = "\n".join(
    [
        'a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]',
        *(
            f"{n}: &{n} [" + ", ".join([f"*{p}"] * 9) + "]"
            for p, n in zip("abcdefgh", "bcdefghi", strict=True)
        ),
    ]
)
"""Nine levels of nine aliases: 9**9 (387 million) strings from 700 bytes."""


def test_an_alias_bomb_in_a_recipe_is_refused(tmp_path):
    recipe = tmp_path / "attack.yaml"
    recipe.write_text(MOON.read_text() + "\n" + BOMB.replace("\n", "\n") + "\n")
    _refused(tmp_path, recipe, needles=("attack.yaml", "not valid YAML", "aliases"))


def test_an_alias_bomb_in_a_component_table_is_refused(tmp_path):
    table = tmp_path / "table.yaml"
    table.write_text(BOMB + "\n")
    recipe = _recipe(
        tmp_path,
        IMETRO,
        (r"^components: recipes/components/imetro.yaml.*$", f"components: {table}"),
    )
    _refused(tmp_path, recipe, needles=("table.yaml", "not valid YAML", "aliases"))


def test_an_alias_bomb_in_a_waypoints_file_is_refused(tmp_path):
    waypoints = tmp_path / "demo.yaml"
    waypoints.write_text(DEMO.read_text() + "\nbomb:\n  " + BOMB.replace("\n", "\n  ") + "\n")
    before = snapshot(tmp_path)
    res = run(
        "facility-demo", str(tmp_path), "--waypoints", str(waypoints), cwd=tmp_path, timeout=TIMEOUT
    )
    assert_one_error(res, "demo.yaml", "not valid YAML", "aliases")
    assert snapshot(tmp_path) == before


def test_an_alias_in_a_set_value_is_not_expanded(tmp_path):
    value = "[&a [1, 1, 1, 1, 1, 1, 1, 1, 1], [*a, *a, *a, *a, *a, *a, *a, *a, *a]]"
    _refused(tmp_path, MOON, "--set", f"rocks.keepout={value}", needles=("rocks.keepout",))
