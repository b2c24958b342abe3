"""Every YAML file a user gives is read one way (issue 34, item 2): recipes, component
tables, waypoints files, task plans, actuator configs, name maps, the calibration
files a description reads with ``xacro.load_yaml``.

Through the real commands, in a fresh process each: a key given twice is one error
line naming the file and both lines; YAML 1.1's readings of ``1:30``, ``0x10``,
``0o17``, ``1_000`` (90, 16, 15, 1000) are refused with what to write, never read
as numbers; ``.inf``, ``.nan``, a 5,000-digit number and ``1e400`` where a number is
expected are one error line as any bad number is; nothing is written.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from urdf2mjcf.runner import waypoints

from .attack import ROOT, assert_one_error, run, snapshot

TIMEOUT = 60
MOON = ROOT / "recipes" / "mira3d-moon.yaml"
IMETRO = ROOT / "recipes" / "imetro.yaml"
DEMO = ROOT / "recipes" / "demo" / "imetro.yaml"

YAML11 = [
    ("1:30", "is the number 90 to YAML 1.1"),
    ("0x10", "is 16 in base 16"),
    ("0o17", "is 15 in base 8"),
    ("1_000", "is the number 1000 to YAML 1.1"),
]
"""A plain scalar YAML 1.1 reads as a number and YAML 1.2 as text: refused, saying so."""
BAD_NUMBERS = [
    (".inf", "not finite"),
    (".nan", "not finite"),
    ("9" * 5000, "(5,000 characters; at most 100)"),
    ("1e400", "1e400"),
]
"""Where a number is expected: one error line as any bad number."""
CASES = YAML11 + BAD_NUMBERS


def _edited(source: Path, tmp_path: Path, name: str, pattern: str, replacement: str) -> Path:
    text = source.read_text().replace("components: components/", "components: recipes/components/")
    text, n = re.subn(pattern, replacement, text, count=1, flags=re.M)
    assert n == 1, pattern
    path = tmp_path / name
    path.write_text(text)
    return path


def _refused(tmp_path: Path, command: str, *args: str, needles: tuple[str, ...]) -> str:
    before = snapshot(tmp_path)
    res = run(command, *args, cwd=tmp_path, timeout=TIMEOUT)
    line = assert_one_error(res, *needles)
    assert len(line) < 600, line  # a 5,000-digit number is not printed whole
    assert snapshot(tmp_path) == before, "a refused input wrote something"
    return line


def _line_of(path: Path, pattern: str) -> int:
    lines = path.read_text().splitlines()
    return next(i for i, line in enumerate(lines, 1) if re.search(pattern, line))


# -- recipes and component tables (make-facility) -----------------------------------------


def _make_facility(tmp_path: Path, recipe: Path, needles: tuple[str, ...]) -> str:
    return _refused(
        tmp_path,
        "make-facility",
        str(recipe),
        "--root",
        str(ROOT),
        "-o",
        str(tmp_path / "out"),
        "--no-components",
        needles=needles,
    )


def test_a_recipe_key_given_twice_names_both_lines(tmp_path):
    recipe = _edited(
        MOON, tmp_path, "r.yaml", r"^  timestep: 0.002$", "  timestep: 0.002\n  timestep: 0.004"
    )
    first = _line_of(recipe, r"^  timestep: 0.002$")
    line = _make_facility(tmp_path, recipe, ("r.yaml", "duplicate key"))
    assert f"lines {first} and {first + 1}" in line and "simulation.timestep" in line


@pytest.mark.parametrize(("value", "needle"), CASES)
def test_a_recipe_number_is_read_one_way(tmp_path, value, needle):
    recipe = _edited(MOON, tmp_path, "r.yaml", r"^  timestep: 0.002$", f"  timestep: {value}")
    _make_facility(tmp_path, recipe, ("r.yaml", needle))


@pytest.mark.parametrize(("value", "needle"), YAML11)
def test_a_recipe_flag_is_not_read_as_a_number(tmp_path, value, needle):
    recipe = _edited(
        MOON, tmp_path, "r.yaml", r"^  terrain_size_x: 1000$", f"  terrain_size_x: {value}"
    )
    _make_facility(tmp_path, recipe, ("r.yaml", needle))


def test_a_set_value_is_read_one_way(tmp_path):
    _refused(
        tmp_path,
        "make-facility",
        str(MOON),
        "--root",
        str(ROOT),
        "-o",
        str(tmp_path / "out"),
        "--no-components",
        "--set",
        "terrain_size_x=0x10",
        needles=("terrain_size_x", "is 16 in base 16"),
    )


def test_a_component_table_key_given_twice_names_both_lines(tmp_path):
    table_src = ROOT / "recipes" / "components" / "imetro.yaml"
    lines = table_src.read_text().splitlines()
    top = next(i for i, line in enumerate(lines) if re.match(r"^[^\s#][^:#]*:", line))
    table = tmp_path / "table.yaml"
    table.write_text("\n".join(lines + [lines[top]]) + "\n")
    recipe = _edited(
        IMETRO,
        tmp_path,
        "r.yaml",
        r"^components: recipes/components/imetro.yaml.*$",
        f"components: {table}",
    )
    line = _make_facility(tmp_path, recipe, ("table.yaml", "duplicate key"))
    assert f"lines {top + 1} and {len(lines) + 1}" in line


# -- waypoints files (facility-demo) ---------------------------------------------------------


def _demo(tmp_path: Path, text: str, needles: tuple[str, ...]) -> str:
    path = tmp_path / "demo.yaml"
    path.write_text(text)
    return _refused(
        tmp_path,
        "facility-demo",
        str(tmp_path),
        "--waypoints",
        str(path),
        needles=("demo.yaml", *needles),
    )


def test_a_waypoints_key_given_twice_names_both_lines(tmp_path):
    text = re.sub(
        r"^final_wait: 1.5$",
        "final_wait: 1.5\nfinal_wait: 2.5",
        DEMO.read_text(),
        count=1,
        flags=re.M,
    )
    first = next(i for i, line in enumerate(text.splitlines(), 1) if line == "final_wait: 1.5")
    line = _demo(tmp_path, text, ("duplicate key",))
    assert f"lines {first} and {first + 1}" in line


@pytest.mark.parametrize(("value", "needle"), CASES)
def test_a_waypoints_number_is_read_one_way(tmp_path, value, needle):
    text, n = re.subn(
        r"^final_wait: 1.5$", f"final_wait: {value}", DEMO.read_text(), count=1, flags=re.M
    )
    assert n == 1
    _demo(tmp_path, text, (needle,))


def test_a_waypoints_files_total_time_is_bounded(tmp_path):
    # each wait within DURATION_MAX, together past SECONDS_MAX
    text = DEMO.read_text().rstrip() + "\n"
    text = re.sub(
        r"^final_wait: 1.5$", f"final_wait: {waypoints.DURATION_MAX:g}", text, count=1, flags=re.M
    )
    text = re.sub(r"seconds: 1.5", f"seconds: {waypoints.DURATION_MAX:g}", text, count=1)
    line = _demo(tmp_path, text, (f"at most {waypoints.SECONDS_MAX:g} s simulated",))
    assert "'close'" in line


# -- task plans (rover-drive --plan) -------------------------------------------------------


def _plan(tmp_path: Path, text: str, needles: tuple[str, ...]) -> str:
    path = tmp_path / "plan.yaml"
    path.write_text(text)
    return _refused(
        tmp_path, "rover-drive", str(tmp_path), "--plan", str(path), needles=("plan.yaml", *needles)
    )


def test_a_plan_key_given_twice_names_both_lines(tmp_path):
    line = _plan(
        tmp_path, "tasks:\n  - kind: hold\n    duration: 1\n    duration: 2\n", ("duplicate key",)
    )
    assert "lines 3 and 4" in line and "tasks.0.duration" in line


@pytest.mark.parametrize(("value", "needle"), CASES)
def test_a_plan_number_is_read_one_way(tmp_path, value, needle):
    _plan(tmp_path, f"tasks:\n  - {{kind: hold, duration: {value}}}\n", (needle,))


# -- actuator configs and name maps (urdf2mjcf) --------------------------------------------

URDF = (
    '<robot name="r"><link name="base"/><link name="arm"><inertial><mass value="1"/>'
    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>'
    '<limit lower="-1" upper="1" effort="10" velocity="1"/></joint></robot>\n'
)


def _convert(tmp_path: Path, config: str, needles: tuple[str, ...]) -> str:
    (tmp_path / "r.urdf").write_text(URDF)
    (tmp_path / "actuators.yaml").write_text(config)
    return _refused(
        tmp_path,
        "urdf2mjcf",
        str(tmp_path / "r.urdf"),
        "-o",
        str(tmp_path / "out" / "r.xml"),
        "--no-validate",
        "--actuator-config",
        str(tmp_path / "actuators.yaml"),
        needles=("actuators.yaml", *needles),
    )


def test_an_actuator_config_key_given_twice_names_both_lines(tmp_path):
    line = _convert(tmp_path, "joints:\n  j: {kp: 10}\n  j: {kp: 20}\n", ("duplicate key",))
    assert "lines 2 and 3" in line


@pytest.mark.parametrize(("value", "needle"), CASES)
def test_an_actuator_config_number_is_read_one_way(tmp_path, value, needle):
    _convert(tmp_path, f"joints:\n  j: {{kp: {value}}}\n", (needle,))


def test_a_name_map_is_read_one_way(tmp_path):
    (tmp_path / "r.urdf").write_text(URDF)
    (tmp_path / "m.xml").write_text("<mujoco/>\n")
    for text, needle in [
        ("links:\n  base: a\n  base: b\n", "lines 2 and 3"),
        ("joints:\n  j: 0x10\n", "is 16 in base 16"),
        ("joints:\n  j: 1:30\n", "is the number 90"),
    ]:
        (tmp_path / "map.yaml").write_text(text)
        _refused(
            tmp_path,
            "urdf2mjcf",
            "verify",
            str(tmp_path / "r.urdf"),
            str(tmp_path / "m.xml"),
            "--name-map",
            str(tmp_path / "map.yaml"),
            needles=("map.yaml", needle),
        )


# -- a calibration file a description reads (xacro.load_yaml) --------------------------------


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("shoulder: {x: 0.1}\nshoulder: {x: 0.2}\n", "duplicate key on lines 1 and 2"),
        ("shoulder: {x: 1:30}\n", "is the number 90 to YAML 1.1"),
        ("shoulder: {x: 0x10}\n", "is 16 in base 16"),
    ],
)
def test_a_calibration_file_is_read_one_way(tmp_path, text, needle):
    (tmp_path / "package.xml").write_text("<package><name>pkg</name></package>\n")
    (tmp_path / "calibration.yaml").write_text(text)
    (tmp_path / "r.urdf.xacro").write_text(
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
        '  <xacro:property name="c" value="${xacro.load_yaml(\'calibration.yaml\')}"/>\n'
        '  <link name="base_${c.shoulder.x}"/>\n</robot>\n'
    )
    _refused(
        tmp_path,
        "urdf2mjcf",
        str(tmp_path / "r.urdf.xacro"),
        "-o",
        str(tmp_path / "out" / "r.xml"),
        "--no-validate",
        needles=("calibration.yaml", needle),
    )
