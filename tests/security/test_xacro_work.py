"""The xacro guard bounds work and total memory, loops inside builtins included (issue 34).

Each hostile description is run through the real ``urdf2mjcf`` command in a fresh
process, as an attacker's victim would: it must end with exit 2 and one ``error:``
line naming the file and the bound it passed, within a bounded time, writing nothing.
Stock xacro runs each of these for minutes or until memory runs out.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

import pytest

from tests.security.attack import assert_one_error, run
from urdf2mjcf.passes import xacro_install

HEAD = '<?xml version="1.0"?>\n<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
BASE = '  <link name="base"/>\n'
TAIL = "</robot>\n"
SECONDS = 60
"""Wall time a refusal may take, even on a loaded machine (each takes 1 to 4 s here)."""
WORK = "work past the bound of"
MEMORY = "memory past the bound of"
ITEMS = "over the bound of 1,000,000 items"


def _refused(tmp_path: Path, body: str, *needles: str) -> str:
    source = tmp_path / "bomb.urdf.xacro"
    source.write_text(HEAD + BASE + body + TAIL)
    out = tmp_path / "out"
    res = run(
        "urdf2mjcf",
        str(source),
        "-o",
        str(out / "robot.xml"),
        "--no-validate",
        cwd=tmp_path,
        timeout=SECONDS,
        env={"URDF2MJCF_TRUST_XACRO": ""},
    )
    line = assert_one_error(res, "bomb.urdf.xacro")
    assert any(n in line for n in needles), line
    assert res.seconds < SECONDS
    assert not out.exists(), "output written for a refused description"
    return line


def _link(expression: str) -> str:
    return f"  <link name={quoteattr('l${' + expression + '}')}/>\n"


@pytest.mark.parametrize(
    ("expression", "needles"),
    [
        # the issue's: a loop inside a builtin, over a range too long to make
        ("python.sum(python.range(10**12))", (ITEMS,)),
        ("len(list(map(str, range(10**10))))", (ITEMS,)),
        # the same loops over ranges each within the item bound, many times
        ("python.sum([python.sum(python.range(10**6)) for i in python.range(10**6)])", (WORK,)),
        ("python.sum(python.map(python.sum, [python.range(10**6)] * 10**6))", (WORK,)),
        ("len(list(map(str, range(10**6))))", (WORK,)),
        ("len([len(python.sorted(range(10**6))) for i in range(1000)])", (WORK,)),
        ("len([max(range(10**6)) for i in range(1000)])", (WORK,)),
        ("len([min(range(10**6)) for i in range(1000)])", (WORK,)),
        ("len([python.any(python.map(python.bool, [0] * 10**6)) for i in range(1000)])", (WORK,)),
        ("len([python.all([1] * 10**6) for i in range(1000)])", (WORK, MEMORY)),
        ("len([''.join(map(str, range(10**6))) for i in range(1000)])", (WORK,)),
        # one string past the text bound; a thousand strings each just under it
        (
            "len('x' * 10**9)",
            ("1 character repeated 1,000,000,000 times, over the bound of 10,000,000 characters",),
        ),
        ("len(['x' * 10**7 for i in range(1000)])", (MEMORY,)),
        ("len([[i * j for i in range(10**5)] for j in range(10**5)])", (WORK,)),
    ],
)
def test_an_expression_past_the_budget_is_one_error_with_its_reason(tmp_path, expression, needles):
    line = _refused(tmp_path, _link(expression), *needles)
    assert "line 4" in line


def test_attributes_each_within_bounds_are_refused_together(tmp_path):
    # 2,000 sorts of 100,000 items, each cheap alone: the budget is the expansion's
    body = "".join(_link(f"len(python.sorted(range({10**5 + i})))") for i in range(2000))
    _refused(tmp_path, body, WORK)


def test_a_property_repeated_into_many_attributes_is_refused_by_memory(tmp_path):
    body = '  <xacro:property name="big" value="${\'x\' * 9000000}"/>\n'
    body += "".join(f'  <link name="l{i}${{big}}"/>\n' for i in range(100))
    _refused(tmp_path, body, MEMORY)


def test_a_macro_that_calls_itself_twice_is_refused_by_work(tmp_path):
    # 2**41 calls; minidom's insertion into a parent of thousands of children is
    # what took the time (13 s for 2**14 before it was charged)
    body = (
        '  <xacro:macro name="m" params="n"><link name="a${n}"/>'
        '<xacro:if value="${n > 0}"><xacro:m n="${n-1}"/><xacro:m n="${n-1}"/></xacro:if>'
        '</xacro:macro>\n  <xacro:m n="40"/>\n'
    )
    line = _refused(tmp_path, body, WORK, "more than 20,000 macro calls")
    assert "macro 'm'" in line or "line 4" in line


def test_a_macro_that_calls_itself_without_end_is_refused_by_depth(tmp_path):
    body = (
        '  <xacro:macro name="m" params="n"><xacro:m n="${n+1}"/></xacro:macro>\n'
        '  <xacro:m n="0"/>\n'
    )
    line = _refused(tmp_path, body, f"nested more than {xacro_install.MAX_MACRO_DEPTH} deep")
    assert "macro 'm'" in line
    assert "recursion" not in line  # Python's own message is no reason a user can act on


def test_a_macro_walking_a_list_as_deep_as_the_bound_converts(tmp_path):
    # the facility's idiom (one call per item of a list) within the depth bound
    n = xacro_install.MAX_MACRO_DEPTH - 1
    source = tmp_path / "chain.urdf.xacro"
    source.write_text(
        HEAD + BASE + '  <xacro:macro name="m" params="n"><xacro:if value="${n > 0}">'
        '<link name="a${n}"/><joint name="j${n}" type="fixed"><parent link="base"/>'
        '<child link="a${n}"/></joint><xacro:m n="${n-1}"/></xacro:if></xacro:macro>\n'
        f'  <xacro:m n="{n}"/>\n' + TAIL
    )
    res = run(
        "urdf2mjcf",
        str(source),
        "-o",
        str(tmp_path / "out" / "robot.xml"),
        "--no-validate",
        cwd=tmp_path,
        timeout=SECONDS,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    assert f'name="a{n}"' in (tmp_path / "out" / "robot.xml").read_text()
