"""The task-kind registry (``urdf2mjcf/runner/task_kinds.py``) is the one declaration:
no second literal default in the runtime, the command line's defaults and ranges, the
plan checks and the console's bounds are the registry's, the docs' table is generated."""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path
from typing import Any

import pytest

from urdf2mjcf.errors import CommandError, FacilityError
from urdf2mjcf.runner import task_kinds
from urdf2mjcf.runner.checks import Waypoints
from urdf2mjcf.runner.rover import rover_drive_command
from urdf2mjcf.runner.rover.console import Console
from urdf2mjcf.runner.rover.deliver_cli import TASKS as TASK_CHOICES
from urdf2mjcf.runner.rover.plan_file import check_shape
from urdf2mjcf.runner.rover.tasks import TASKS, Turn
from urdf2mjcf.runner.task_kinds import KINDS, STRAIGHT, TURN, WHEELS, family, keys_table
from urdf2mjcf.runner.waypoints import KINDS as STEP_KINDS
from urdf2mjcf.schema import Source

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "urdf2mjcf" / "runner"
ALIASES = {"rate": "rate_deg"}
"""A runtime attribute that holds a declared parameter in another unit."""
CLI = {"speed": STRAIGHT.param("speed"), "rate": TURN.param("rate_deg")}
"""rover-drive's options that are a plan key's, by option name."""


CLASSES = {"Straight": "straight", "Turn": "turn", "Hold": "hold", "ArmWave": "arm_wave"}
"""The runtime class of each plan kind."""


def _declared(cls: str) -> set[str]:
    """The fields that must not carry a literal default in class ``cls``: its kind's
    parameters (by their runtime names), and in any class a declared default's twin."""
    kind = KINDS.get(CLASSES.get(cls, ""))
    own = {p.name for p in kind.params} if kind else set()
    return own | {a for a, p in ALIASES.items() if p in own}


def _defaults() -> dict[str, set]:
    out: dict[str, set] = {}
    for k in KINDS.values():
        for p in k.params:
            if p.default is not None:
                out.setdefault(p.name, set()).add(p.default)
    return out


def _literal(node: ast.expr | None) -> Any:
    """The number a literal gives, else None."""
    sign = 1
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        node, sign = node.operand, -1
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
        return sign * node.value
    return None


def _second_defaults(runner: Path = RUNNER) -> list[str]:
    """Each literal default for a declared parameter outside the registry: a rover
    class's field, a click option's ``default=``, a demo step's ``step.get(KEY, literal)``."""
    defaults, found = _defaults(), []
    step_keys = {p.name for k in family("step").values() for p in k.params if not p.required}
    for path in sorted(runner.rglob("*.py")):
        if path.name == "task_kinds.py":
            continue
        where = path.relative_to(runner)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                for item in node.body:
                    if not (isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name)):
                        continue
                    field, value = item.target.id, _literal(item.value)
                    twin = value is not None and value in defaults.get(field, ())
                    if value is not None and (field in _declared(node.name) or twin):
                        found.append(f"{where}:{item.lineno} {node.name}.{item.target.id}")
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "option":
                flags = [a.value for a in node.args if isinstance(a, ast.Constant)]
                if any(f"--{name}" in flags for name in CLI):
                    for kw in node.keywords:
                        if kw.arg == "default" and _literal(kw.value) is not None:
                            found.append(f"{where}:{node.lineno} {flags[0]} default")
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr == "get"
                and isinstance(node.func.value, ast.Name)
                and node.func.value.id == "step"
                and len(node.args) == 2
                and isinstance(node.args[0], ast.Constant)
                and node.args[0].value in step_keys
                and isinstance(node.args[1], (ast.Constant, ast.UnaryOp))
            ):
                found.append(f"{where}:{node.lineno} step.get({node.args[0].value!r})")
    return found


def test_every_default_is_declared_once() -> None:
    assert _second_defaults() == []


def test_the_scan_finds_a_second_default(tmp_path: Path) -> None:
    rover = tmp_path / "runner" / "rover"
    rover.mkdir(parents=True)
    (rover / "bad.py").write_text(
        "import click\nclass Turn:\n    rate: float = 0.5\n"
        "@click.option('--speed', default=0.5)\ndef f(): pass\n"
        "def g(step): return step.get('steps', 8), step.get('camera', 'wrist')\n"
    )
    found = _second_defaults(tmp_path / "runner")
    assert [f.split(" ", 1)[1] for f in found] == [
        "Turn.rate",
        "--speed default",
        "step.get('steps')",
        "step.get('camera')",
    ]


def test_the_runtime_defaults_are_the_registrys() -> None:
    assert Turn(1.0).rate == pytest.approx(math.radians(30.0))
    assert TURN.default("rate_deg") == 30.0
    for kind, task in TASKS.items():
        for key, k in task.keys.items():
            assert k.param is KINDS[kind].param(key)
    assert tuple(TASK_CHOICES) == tuple(family("task")) == ("deliver",)


def test_the_cli_defaults_and_ranges_are_the_registrys() -> None:
    options = {p.name: p for p in rover_drive_command.params}
    for name, param in CLI.items():
        option = options[name]
        assert option.default == param.default
        assert (option.type.low, option.type.high) == (param.low, param.high)  # type: ignore[attr-defined]
        assert option.type.low_open == param.low_open  # type: ignore[attr-defined]


def _task(kind: str, **values: Any) -> dict:
    spec = {"kind": kind}
    for p in KINDS[kind].params:
        if p.required:
            spec[p.name] = p.high / 1000 if p.high else 1.0
    return {**spec, **values}


def _plan(spec: dict) -> dict:
    if KINDS[spec["kind"]].family == "arm":
        return {"tasks": [{"kind": "hold"}], "arm": spec}
    return {"tasks": [spec]}


@pytest.mark.parametrize(
    ("kind", "param"),
    [
        (k.name, p)
        for k in KINDS.values()
        if k.family in ("drive", "arm")
        for p in k.params
        if p.type is not bool
    ],
    ids=lambda x: x if isinstance(x, str) else x.name,
)
def test_plan_checks_refuse_what_the_registry_bounds(kind: str, param: Any) -> None:
    assert param.high is not None
    if param.name != "distance":  # 1000 m is refused for the plan's time, not its value
        check_shape(_plan(_task(kind, **{param.name: param.type(param.high)})), None)
    outside = int(param.high) + 1 if param.type is int else param.high * 1.5
    with pytest.raises(FacilityError, match=f"{param.name}: .*{param.high:g}"):
        check_shape(_plan(_task(kind, **{param.name: outside})), None)
    if param.low_open:
        with pytest.raises(FacilityError, match=f"{param.name}: .*out of range"):
            check_shape(_plan(_task(kind, **{param.name: param.low})), None)


@pytest.mark.parametrize(
    ("kind", "param"),
    [(k.name, p) for k in family("step").values() for p in k.params if p.type in (int, float)],
    ids=lambda x: x if isinstance(x, str) else x.name,
)
def test_step_checks_refuse_what_the_registry_bounds(kind: str, param: Any) -> None:
    w = Waypoints(None, Source("steps", error=FacilityError))
    assert STEP_KINDS[kind][0][param.name] is param.check  # the step reads its declaration
    assert param.low is not None and param.high is not None
    param.check(param.type(param.high), f"{kind}.{param.name}", w)
    outside = int(param.high) + 1 if param.type is int else param.high * 1.5
    with pytest.raises(FacilityError, match=f"{kind}.{param.name}"):
        param.check(outside, f"{kind}.{param.name}", w)
    below = param.low if param.low_open else param.low - 1
    with pytest.raises(FacilityError, match=f"{kind}.{param.name}"):
        param.check(param.type(below), f"{kind}.{param.name}", w)


class _Sim:
    """What the console's ``/command`` asks of its simulation."""

    rovers = {"rover": None}

    def driven(self, name: str) -> None:
        pass

    def command(self, name: str, wheels: Any, arm: Any) -> dict:
        return {"wheels": wheels, "arm": arm}


def test_the_console_refuses_what_the_registry_bounds() -> None:
    console = Console.__new__(Console)
    console.sim = _Sim()  # type: ignore[assignment]
    high = WHEELS.param("left").high
    assert high == task_kinds.NUMBER_MAX
    ok = console.post("/command", {"wheels": {"left": high, "right": -high}, "arm": {"j": 1}})
    assert ok == {"wheels": (high, -high), "arm": {"j": 1.0}}
    for body, where in (
        ({"wheels": {"left": 2 * high, "right": 0}}, "wheels.left"),
        ({"wheels": {"left": 0, "right": -2 * high}}, "wheels.right"),
        ({"arm": {"j": 2 * high}}, "arm.j"),
    ):
        pattern = f"^{re.escape(where)}: .* out of range .*{re.escape(f'{high:g}')}"
        with pytest.raises(CommandError, match=pattern):
            console.post("/command", body)


def test_the_docs_table_is_the_generated_one() -> None:
    text = (ROOT / "docs" / "mira3d.md").read_text()
    table = text.split("<!-- task-kinds begin -->\n", 1)[1].split("<!-- task-kinds end -->")[0]
    assert table == "\n".join(keys_table()) + "\n"


def test_the_demo_docs_step_table_is_the_generated_one() -> None:
    text = (ROOT / "docs" / "demo.md").read_text()
    table = text.split("<!-- step-kinds begin -->\n", 1)[1].split("<!-- step-kinds end -->")[0]
    assert table == "\n".join(keys_table(("step",))) + "\n"


@pytest.mark.parametrize(
    ("doc", "marker", "families"),
    [("ros2.md", "ros2-commands", ("ros2",)), ("mira3d.md", "command-kinds", ("command",))],
)
def test_the_docs_command_tables_are_the_generated_ones(doc, marker, families) -> None:
    text = (ROOT / "docs" / doc).read_text()
    table = text.split(f"<!-- {marker} begin -->\n", 1)[1].split(f"<!-- {marker} end -->")[0]
    assert table == "\n".join(keys_table(families)) + "\n"


def test_a_ros2_command_field_is_checked_as_declared() -> None:
    """A Twist's fields: finite numbers within the declared bounds, or the reason why not
    (the rovers' ROS 2 bridge drops such a message with it)."""
    from urdf2mjcf.runner.task_kinds import CMD_VEL

    speed = CMD_VEL.param("linear_x")
    assert speed.number(0.5) == 0.5 and speed.number(-3) == -3.0
    for bad, why in (
        (float("nan"), "is not finite"),
        (10**400, "is out of range"),
        (True, "is not a number"),
        ("0.5", "is not a number"),  # a field's text is no number
        (2e6, "2e+06 is out of range (from -1e+06 to 1e+06)"),
    ):
        assert why in speed.number(bad), bad
