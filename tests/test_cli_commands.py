"""``urdf2mjcf``'s sub-commands: declared once (``cli.COMMANDS``), listed by ``--help`` and
docs/cli.md from that declaration, and the short spelling of a conversion kept."""

from __future__ import annotations

import re
from pathlib import Path

from click.testing import CliRunner

from urdf2mjcf import cli

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "cli.md"

URDF = """<robot name="two">
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
    ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="arm"><inertial><origin xyz="0 0 0.1"/><mass value="0.5"/><inertia ixx="0.002"
    iyy="0.002" izz="0.0005" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.02" length="0.2"/></geometry>
    </collision></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.05"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="5" velocity="2"/>
  </joint>
</robot>
"""


def _table() -> str:
    """The docs' table of sub-commands, made from the declaration (each one's first line)."""
    rows = ["| sub-command | what it does |", "|---|---|"]
    for name in cli.COMMANDS:
        command = cli.urdf2mjcf_group.get_command(None, name)  # type: ignore[arg-type]
        assert command is not None
        doc = " ".join((command.help or "").split("\n\n")[0].split())
        rows.append(f"| `urdf2mjcf {name}` | {doc} |")
    return "\n".join(rows)


def test_the_docs_list_every_sub_command_as_declared(update_golden):
    text = DOC.read_text()
    begin, end = "<!-- subcommands:begin -->\n", "\n<!-- subcommands:end -->"
    written = text[text.index(begin) + len(begin) : text.index(end)]
    if update_golden:
        DOC.write_text(text.replace(written, _table()))
        return
    assert written == _table(), "docs/cli.md: regenerate with pytest --update-golden"


def test_help_lists_exactly_the_declared_sub_commands():
    result = CliRunner().invoke(cli.urdf2mjcf_group, ["--help"])
    assert result.exit_code == 0
    listed = re.findall(r"^  (\w+)  ", result.output.split("Commands:")[1], re.M)
    assert listed == list(cli.COMMANDS)


def test_the_short_spelling_converts_as_convert_does(tmp_path):
    source = tmp_path / "two.urdf"
    source.write_text(URDF)
    runner = CliRunner()
    short = runner.invoke(cli.urdf2mjcf_group, [str(source), "-o", str(tmp_path / "a/robot.xml")])
    named = runner.invoke(
        cli.urdf2mjcf_group, ["convert", str(source), "-o", str(tmp_path / "b/robot.xml")]
    )
    assert short.exit_code == 0, short.output
    assert named.exit_code == 0, named.output
    for name in ("robot.xml", "scene.xml"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_a_source_named_like_a_sub_command_is_given_as_a_path(tmp_path, monkeypatch):
    (tmp_path / "batch").write_text(URDF)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli.urdf2mjcf_group, ["./batch", "-o", "out/robot.xml"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "robot.xml").is_file()
