"""A description cannot run code or read files outside its packages (issue 19, item 1).

Each probe runs the real ``urdf2mjcf`` command in a fresh process with a time
and memory bound, as an attacker's victim would, and checks: no marker file,
no leaked content, one ``error:`` line naming the file, the line and the
expression, exit 2, nothing written. ``--trust-xacro`` and
``URDF2MJCF_TRUST_XACRO=1`` do run the code: that proves the checks are what
stops it.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from tests.security.attack import assert_one_error, run

HEAD = '<?xml version="1.0"?>\n<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
TAIL = "</robot>\n"
BASE = '  <link name="base"/>\n'

# The issue's payload: stock xacro's ${} sandbox escaped through object's subclasses.
SUBCLASSES = (
    "${[c for c in python.vars(python.type)['__subclasses__'](python.type.mro(python.int)[-1])"
    " if 'catch_warnings' in python.repr(c)][0]()._module.sys.modules['os'].system('touch MARKER')}"
)
# $(eval ...) ends at the first ')' in xacro's lexer, so a working payload spells the
# parentheses as ${'\x28'} and ${'\x29'}; the issue's literal spelling is tried too.
L, R = "${'\\x28'}", "${'\\x29'}"
EVAL_EXEC = f"$(eval exec{L}\"import os; os.system{L}'touch MARKER'{R}\", {{}}{R})"
EVAL_EXEC_LITERAL = "$(eval exec(\"import os; os.system('touch MARKER')\"))"
EVAL_OPEN = f"$(eval open{L}'/etc/hostname'{R}.read{L}{R})"
HOSTNAME = Path("/etc/hostname").read_text().strip() if Path("/etc/hostname").is_file() else ""


def _write(folder: Path, name: str, body: str) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEAD + body + TAIL)
    return path


def _convert(tmp_path: Path, source: Path, *extra: str, env: dict[str, str] | None = None):
    out = tmp_path / "out"
    res = run(
        "urdf2mjcf",
        str(source),
        "-o",
        str(out / "robot.xml"),
        "--no-validate",
        *extra,
        cwd=tmp_path,
        timeout=90,
        env=env,
    )
    return res, out


def _refused(tmp_path: Path, source: Path, *needles: str, name: str | None = None) -> str:
    env = {"URDF2MJCF_TRUST_XACRO": ""}  # the probe's outcome must not depend on the caller
    res, out = _convert(tmp_path, source, env=env)
    line = assert_one_error(res, name or source.name, *needles)
    assert not (tmp_path / "MARKER").exists(), "the description ran a command"
    assert not out.exists(), "output written for a refused description"
    if HOSTNAME:
        assert HOSTNAME not in res.stderr.replace(str(tmp_path), "")
    return line


@pytest.mark.parametrize("name", ["robot.urdf.xacro", "robot.urdf"])
def test_subclasses_escape_is_refused(tmp_path, name):
    src = _write(
        tmp_path,
        name,
        f'  <xacro:property name="x" value="{SUBCLASSES}"/>\n{BASE}  <link name="l${{x}}"/>\n',
    )
    line = _refused(tmp_path, src, "line 3", "${[c for c in python.vars(python.type)")
    assert "is not allowed in a description" in line and "--trust-xacro" in line


@pytest.mark.parametrize("name", ["robot.urdf.xacro", "robot.urdf"])
def test_eval_exec_is_refused(tmp_path, name):
    src = _write(
        tmp_path,
        name,
        f'  <xacro:property name="p" value="1"/>\n{BASE}'
        f'  <link name="{EVAL_EXEC.replace(chr(34), "&quot;")}"/>\n',
    )
    _refused(tmp_path, src, "line 5", "$(eval exec(", "'exec' is not allowed")


def test_eval_exec_as_the_issue_spells_it_is_an_error(tmp_path):
    src = _write(
        tmp_path,
        "robot.xacro",
        f'{BASE}  <link name="{EVAL_EXEC_LITERAL.replace(chr(34), "&quot;")}"/>\n',
    )
    _refused(tmp_path, src, "line 4", "$(eval exec(")


@pytest.mark.parametrize("name", ["robot.urdf.xacro", "robot.urdf"])
def test_eval_open_into_a_link_name_is_refused(tmp_path, name):
    src = _write(
        tmp_path,
        name,
        f'  <xacro:property name="p" value="1"/>\n{BASE}'
        f'  <joint name="j" type="fixed"><parent link="base"/>'
        f'<child link="{EVAL_OPEN}"/></joint>\n  <link name="{EVAL_OPEN}"/>\n',
    )
    _refused(tmp_path, src, "line 5", "$(eval open(", "'open' is not allowed")


@pytest.mark.parametrize(
    ("expression", "needle"),
    [
        ("${[g for g in [(x for x in [1])]][0].gi_frame}", "gi_frame"),
        ("${'\\x7b0.gi_frame.f_globals\\x7d'.format((x for x in [1]))}", "format"),
        ("${python['type'](1)}", "python['type']"),
        ("${python.vars(python.int)}", "python.vars"),
        ("${python.type.mro(python.int)}", "python.type"),
        ("${xacro.root}", "xacro.root"),
        ("${math.update(dict(a=1))}", "math.update"),
        ("${getattr(1, 'real')}", "'getattr' is not allowed"),
        ("${(lambda: 1)()}", "'lambda' is not allowed"),
        ("${[y := 1]}", "':=' is not allowed"),
        ("${python.str.join(',', 'ab')}", "str.join"),
    ],
)
def test_sandbox_walks_are_refused(tmp_path, expression, needle):
    src = _write(tmp_path, "robot.urdf.xacro", f'{BASE}  <link name="l{expression}"/>\n')
    _refused(tmp_path, src, "line 4", expression[:20], needle)


def test_load_yaml_of_etc_passwd_is_refused(tmp_path):
    src = _write(
        tmp_path / "pkg" / "urdf",
        "robot.urdf.xacro",
        '  <xacro:property name="d" value="${xacro.load_yaml(\'/etc/passwd\')}"/>\n'
        f'{BASE}  <link name="${{d}}"/>\n',
    )
    (tmp_path / "pkg" / "package.xml").write_text("<package><name>pkg</name></package>")
    line = _refused(tmp_path, src, "line 3", "load_yaml", "/etc/passwd", "outside")
    assert "root:" not in line


def test_load_yaml_outside_the_package_is_refused(tmp_path):
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "keys.yaml").write_text("key: hunter2\n")
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "package.xml").write_text("<package><name>pkg</name></package>")
    src = _write(
        tmp_path / "pkg" / "urdf",
        "robot.urdf.xacro",
        f"{BASE}  <link name=\"${{xacro.load_yaml('../../secret/keys.yaml').key}}\"/>\n",
    )
    res, out = _convert(tmp_path, src)
    line = assert_one_error(res, "robot.urdf.xacro", "line 4", "outside")
    assert "hunter2" not in res.stderr and not out.exists()
    assert "load_yaml" in line


def test_load_yaml_inside_the_package_works(tmp_path):
    (tmp_path / "pkg" / "config").mkdir(parents=True)
    (tmp_path / "pkg" / "package.xml").write_text("<package><name>pkg</name></package>")
    (tmp_path / "pkg" / "config" / "dims.yaml").write_text("name: arm\nangle: !degrees 180\n")
    src = _write(
        tmp_path / "pkg" / "urdf",
        "robot.urdf.xacro",
        '  <xacro:property name="d" value="${xacro.load_yaml(\'../config/dims.yaml\')}"/>\n'
        f'{BASE}  <link name="${{d.name}}_${{int(d.angle * 1000)}}"/>\n'
        '  <joint name="j" type="fixed"><parent link="base"/><child link="arm_3141"/>'
        "</joint>\n",
    )
    res, out = _convert(tmp_path, src)
    assert res.returncode == 0, res.stderr
    assert 'name="arm_3141"' in (out / "robot.xml").read_text()


def test_yaml_alias_bomb_through_load_yaml_is_refused(tmp_path):
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 10)]
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "package.xml").write_text("<package><name>pkg</name></package>")
    (tmp_path / "pkg" / "bomb.yaml").write_text("\n".join(lines) + "\n")
    src = _write(
        tmp_path / "pkg",
        "robot.urdf.xacro",
        f"{BASE}  <link name=\"${{len(str(xacro.load_yaml('bomb.yaml')))}}\"/>\n",
    )
    _refused(tmp_path, src, "line 4", "load_yaml", "expands to more than")


def test_include_of_a_fifo_does_not_hang(tmp_path):
    os.mkfifo(tmp_path / "parts.xacro")
    src = _write(tmp_path, "robot.urdf.xacro", f'{BASE}  <xacro:include filename="parts.xacro"/>\n')
    _refused(tmp_path, src, "line 4: xacro:include", "parts.xacro", "FIFO")


def test_include_of_a_socket_is_refused(tmp_path):
    sock = socket.socket(socket.AF_UNIX)
    try:
        sock.bind(str(tmp_path / "s.xacro"))
        src = _write(tmp_path, "robot.urdf.xacro", f'{BASE}  <xacro:include filename="s.xacro"/>\n')
        _refused(tmp_path, src, "line 4: xacro:include", "s.xacro", "socket")
    finally:
        sock.close()


def test_include_of_dev_zero_is_refused_before_reading(tmp_path):
    src = _write(tmp_path, "robot.urdf.xacro", f'{BASE}  <xacro:include filename="/dev/zero"/>\n')
    _refused(tmp_path, src, "line 4: xacro:include", "/dev/zero", "device")


def test_include_of_etc_passwd_is_malformed_xml(tmp_path):
    src = _write(tmp_path, "robot.urdf.xacro", f'{BASE}  <xacro:include filename="/etc/passwd"/>\n')
    line = _refused(tmp_path, src, "malformed XML", name="/etc/passwd")
    assert "root:x" not in line


def test_source_that_is_a_fifo_is_refused(tmp_path):
    os.mkfifo(tmp_path / "robot.urdf.xacro")
    _refused(tmp_path, tmp_path / "robot.urdf.xacro", "FIFO")


# -- the opt-out is real -----------------------------------------------------------------


def test_trust_xacro_runs_the_code(tmp_path):
    src = _write(
        tmp_path,
        "robot.urdf.xacro",
        f'{BASE}  <link name="{EVAL_EXEC.replace(chr(34), "&quot;")}"/>\n'
        '  <joint name="j" type="fixed"><parent link="base"/><child link="None"/>'
        "</joint>\n",
    )
    res, out = _convert(tmp_path, src, "--trust-xacro")
    assert (tmp_path / "MARKER").exists(), res.stderr
    assert res.returncode == 0, res.stderr


def test_trust_from_the_environment_runs_the_code(tmp_path):
    src = _write(
        tmp_path,
        "robot.urdf.xacro",
        f'  <xacro:property name="x" value="{SUBCLASSES}"/>'
        f'\n{BASE}  <link name="l${{x}}"/>\n'
        '  <joint name="j" type="fixed"><parent link="base"/><child link="l0"/></joint>\n',
    )
    res, _ = _convert(tmp_path, src, env={"URDF2MJCF_TRUST_XACRO": "1"})
    assert (tmp_path / "MARKER").exists(), res.stderr


def test_trust_variable_must_be_a_flag(tmp_path):
    src = _write(tmp_path, "robot.urdf.xacro", BASE)
    res, out = _convert(tmp_path, src, env={"URDF2MJCF_TRUST_XACRO": "maybe"})
    assert_one_error(res, "URDF2MJCF_TRUST_XACRO", "maybe")
    assert not out.exists()


# -- nothing an expression or a description does may hang or exhaust memory ------------


@pytest.mark.parametrize(
    ("expression", "needle"),
    [
        ("'a'*10**10", "repeated"),
        ("[0]*10**10", "repeated"),
        ("9**9**9", "a power of"),
        ("1 &lt;&lt; 10**10", "a shift by"),  # << written as XML needs it
        ("python.sum(python.range(10**12))", "a range of"),
        ("len([x for x in python.range(10**6) for y in python.range(10**6)])", "steps"),
        ("'%0999999999d' % 1", "format field"),
        ("'a'.ljust(10**10)", "characters"),
        ("('a'*1000).replace('a', 'b'*100000)", "characters"),
        ("math.factorial(10**7)", "factorial"),
    ],
)
def test_costly_expressions_are_refused_quickly(tmp_path, expression, needle):
    src = _write(tmp_path, "robot.urdf.xacro", f'  <link name="l${{{expression}}}"/>\n')
    res, out = _convert(tmp_path, src)
    assert_one_error(res, "robot.urdf.xacro", "line 3", needle)
    assert res.seconds < 60
    assert not out.exists()


def test_properties_doubling_each_other_are_refused(tmp_path):
    """xacro's billion laughs: each property twice the one before, 2**40 characters."""
    body = '  <xacro:property name="p0" value="aaaaaaaaaaaaaaaa"/>\n'
    body += "".join(
        f'  <xacro:property name="p{i}" value="${{p{i - 1}}}${{p{i - 1}}}"/>\n'
        for i in range(1, 40)
    )
    src = _write(tmp_path, "robot.urdf.xacro", body + '  <link name="${p39}"/>\n')
    res, out = _convert(tmp_path, src)
    assert_one_error(res, "robot.urdf.xacro", "10,000,000 characters")
    assert not out.exists()


def test_macros_calling_each_other_twice_are_refused(tmp_path):
    """2**39 links from 40 macros, each calling the one before twice."""
    body = '  <xacro:macro name="m0"><link name="x"/></xacro:macro>\n'
    body += "".join(
        f'  <xacro:macro name="m{i}"><xacro:m{i - 1}/><xacro:m{i - 1}/></xacro:macro>\n'
        for i in range(1, 40)
    )
    src = _write(tmp_path, "robot.urdf.xacro", body + "  <xacro:m39/>\n")
    res, out = _convert(tmp_path, src)
    assert_one_error(res, "robot.urdf.xacro", "macro calls")
    assert not out.exists()
