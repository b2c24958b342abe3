"""The converter's options are declared once (``urdf2mjcf.options.OPTIONS``): the API's
defaults are the pass configs' own, every command takes its flags from there, and the
docs list exactly what is declared."""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from urdf2mjcf import api, options
from urdf2mjcf.certify.tolerances import Tolerances
from urdf2mjcf.cli_common import converter_keywords, converter_options

ROOT = Path(__file__).resolve().parents[1]
CLI_DOC = ROOT / "docs" / "cli.md"


def test_the_declared_defaults_are_the_pass_configs_own():
    """``make_options()`` with no keyword is ``ConvertOptions()``: every pass config as it
    declares its own defaults (but the cache folder the certificate finds by itself, and
    the environment's say on running xacro code)."""
    made = options.make_options()
    plain = options.ConvertOptions()
    made = dataclasses.replace(
        made,
        certify=dataclasses.replace(made.certify, cache_root=None),
        xacro=dataclasses.replace(made.xacro, trust=plain.xacro.trust),
    )
    assert made == plain


def test_an_unknown_keyword_is_refused_as_by_any_function():
    with pytest.raises(TypeError, match="unexpected keyword argument 'densty'"):
        api.make_options(densty=500.0)


def _command():
    @click.command()
    @converter_options()
    def command(**values):
        click.echo(repr(sorted(converter_keywords(values).items())))

    return command


def _given(*argv: str) -> dict:
    result = CliRunner().invoke(_command(), list(argv))
    assert result.exit_code == 0, result.output
    return dict(ast.literal_eval(result.output))


def test_a_command_hands_on_only_what_was_given_as_the_api_keywords():
    assert _given() == {}
    given = _given(
        "--no-scene", "--density", "500", "--package", "arm=/ws/arm", "--link-density",
        "base=2700", "--tolerance", "mass_relative=0.01", "--trust-xacro", "-j", "3", "--no-ros-env",
        "--collision-shape", "hull", "--link-collision", "tool=primitive",
    )  # fmt: skip
    assert given == {
        "scene": False,
        "density": 500.0,
        "packages": (("arm", "/ws/arm"),),
        "link_density": (("base", 2700.0),),
        "tolerances": (("mass_relative", 0.01),),
        "trust_xacro": True,
        "workers": 3,
        "use_environment": False,
        "collision_shape": "hull",
        "link_collision": (("tool", "primitive"),),
    }
    made = api.make_options(**given)
    assert made.xacro.packages == {"arm": Path("/ws/arm")}
    assert made.xacro.trust and not made.xacro.use_environment
    assert made.inertia.density == 500.0 and made.inertia.link_density == {"base": 2700.0}
    assert made.certify.tolerances == Tolerances(mass_relative=0.01)
    assert made.collision.link_shapes == {"tool": "primitive"}
    assert made.collision.workers == 3 and not made.scene


def test_an_option_out_of_its_declared_range_is_a_usage_error():
    result = CliRunner().invoke(_command(), ["--density", "0"])
    assert result.exit_code == 2 and "--density" in result.output
    result = CliRunner().invoke(_command(), ["--package", "arm"])
    assert result.exit_code == 2 and "is not NAME=DIR" in result.output


def _declared_flags(path: Path) -> set[str]:
    """The flags ``path`` declares: the strings in its ``click.option(...)`` and
    ``click.Option([...])`` calls' positional arguments."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") in ("option", "Option"):
            for arg in node.args:
                found |= {
                    c.value
                    for c in ast.walk(arg)
                    if isinstance(c, ast.Constant) and isinstance(c.value, str)
                }
    return found


# Flags other commands declare with a meaning of their own (a folder of results, not
# a conversion's files).
OWN_MEANING = {"--overwrite"}


def test_no_other_module_declares_a_converter_flag():
    flags = {f for o in options.OPTIONS for f in o.flags if f.startswith("--")} - OWN_MEANING
    found = []
    for path in sorted((ROOT / "urdf2mjcf").rglob("*.py")):
        if path.name == "options.py" and path.parent.name == "urdf2mjcf":
            continue
        found += [f"{path.relative_to(ROOT)}: {f}" for f in _declared_flags(path) & flags]
    assert found == [], "declare a converter option in urdf2mjcf/options.py only"


def _keyword_table() -> str:
    rows = ["| keyword | flag | default | what |", "|---|---|---|---|"]
    for o in options.OPTIONS:
        flag = f"`{o.flags[-1]}`" if o.flags else "(API only)"
        rows.append(f"| `{o.keyword}` | {flag} | `{o.default!r}` | {o.help} |")
    return "\n".join(rows)


def test_the_docs_list_every_keyword_as_declared(update_golden):
    text = CLI_DOC.read_text()
    begin, end = "<!-- options:begin -->\n", "\n<!-- options:end -->"
    written = text[text.index(begin) + len(begin) : text.index(end)]
    if update_golden:
        CLI_DOC.write_text(text.replace(written, _keyword_table()))
        return
    assert written == _keyword_table(), "docs/cli.md: regenerate with pytest --update-golden"


def test_the_docs_option_table_has_a_row_for_each_flag_with_its_default():
    """docs/cli.md's table of ``urdf2mjcf convert``'s options: a row for every flag; a
    default the row states is the declared one."""
    rows = {
        m.group(1): m.group(0)
        for m in re.finditer(r"^\| `(?:-\w, )?(--[\w-]+)[^`]*` \|.*$", CLI_DOC.read_text(), re.M)
    }
    for o in options.OPTIONS:
        if not o.flags:
            continue
        assert o.flags[-1] in rows, f"docs/cli.md: no row for {o.flags[-1]}"
        stated = re.search(r"\(default `?([\w.]+)`?", rows[o.flags[-1]])
        if stated and isinstance(o.default, (int, float, str)) and o.value != "switch":
            assert float(stated.group(1)) == float(o.default) if not isinstance(
                o.default, str
            ) else stated.group(1) == o.default, o.flags[-1]
