"""Property-based fuzzing of the xacro expression check (issue 19, item 1).

Arbitrary text, and generated expressions of allowed and forbidden shapes,
through the checker: either compiled code or a refusal (an XacroError once
xacro's file and line are added), never another exception or a hang. Allowed
arithmetic evaluates, through the guarded ``safe_eval`` xacro calls, to what
Python's ``eval`` gives.
"""

from __future__ import annotations

from pathlib import Path
from types import CodeType

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from urdf2mjcf.errors import XacroError
from urdf2mjcf.passes import xacro_guard, xacro_install
from urdf2mjcf.passes.xacro import _LOCK

pytestmark = pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")

SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _checked(text: str) -> CodeType | None:
    try:
        return xacro_guard.check(text)
    except xacro_guard.Refused as exc:
        assert exc.reason  # a message to show, never empty
        return None


@SETTINGS
@given(st.text(max_size=300))
def test_arbitrary_text_is_compiled_or_refused(text):
    _checked(text)


@SETTINGS
@given(st.text(alphabet="()[]{}.,:;'\"_ab01+-*/%<>=!~^|&@ \\\n\tλ", max_size=120))
def test_punctuation_soup_is_compiled_or_refused(text):
    _checked(text)


NAMES = st.sampled_from(["x", "python", "math", "xacro", "_p", "__class__", "gi_frame", "pi"])
ATTRS = st.sampled_from(["real", "keys", "vars", "type", "__class__", "_module", "gi_frame"])


def _shapes(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    return st.one_of(
        st.builds("{}.{}".format, inner, ATTRS),
        st.builds("{}[{}]".format, inner, inner),
        st.builds("{}[{}:{}]".format, inner, inner, inner),
        st.builds("{}({})".format, inner, inner),
        st.builds("({} if {} else {})".format, inner, inner, inner),
        st.builds("[{} for x in {}]".format, inner, inner),
        st.builds("(lambda: {})".format, inner),
        st.builds("({} := {})".format, NAMES, inner),
        st.builds("f'{{{}}}'".format, inner),
        st.builds("{}['__{}']".format, inner, ATTRS),
        st.builds("({} + {})".format, inner, inner),
    )


EXPRESSIONS = st.recursive(
    st.one_of(NAMES, st.integers(-5, 5).map(str), st.just("'a'")), _shapes, max_leaves=12
)


@SETTINGS
@given(EXPRESSIONS)
def test_generated_shapes_are_compiled_or_refused(text):
    code = _checked(text)
    forbidden = ("lambda", ":=", "__", "._")
    if any(f in text for f in forbidden):
        assert code is None, text


def _arithmetic(inner: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    ops = st.sampled_from(["+", "-", "*", "/", "//", "%", "<", "==", "and", "or"])
    return st.one_of(
        st.builds("({} {} {})".format, inner, ops, inner),
        st.builds("(-{})".format, inner),
        st.builds("({} if {} else {})".format, inner, inner, inner),
        st.builds("python.abs({})".format, inner),
        st.builds("max({}, {})".format, inner, inner),
        st.builds("round({}, 3)".format, inner),
        st.builds("[{}, {}][1]".format, inner, inner),
        st.builds("sqrt(python.abs({}))".format, inner),
        st.builds("({} ** 2)".format, inner),
    )


ARITHMETIC = st.recursive(
    st.one_of(st.integers(-1000, 1000).map(str), st.floats(-1e3, 1e3).map(repr), st.just("pi")),
    _arithmetic,
    max_leaves=10,
)


def _python(text: str):
    import math

    python = type("python", (), {"abs": abs})
    env = {"__builtins__": {}, "python": python, "max": max, "round": round, **vars(math)}
    try:
        return ("ok", eval(text, env))
    except Exception as exc:  # the same failure both ways (ZeroDivisionError, ...)
        return ("raised", type(exc))


def _guarded(text: str):
    import xacro

    with _LOCK, xacro_install.installed(lambda: [], Path("fuzz.xacro")):
        symbols = xacro.Table(xacro._global_symbols)
        try:
            return ("ok", xacro.safe_eval(text, symbols))
        except XacroError:
            raise
        except Exception as exc:
            return ("raised", type(exc))


@SETTINGS
@given(ARITHMETIC)
def test_allowed_arithmetic_evaluates_as_python_does(text):
    expected = _python(text)
    got = _guarded(text)
    if expected[0] == "ok" and isinstance(expected[1], float) and expected[1] != expected[1]:
        assert got[0] == "ok" and got[1] != got[1]  # NaN
    else:
        assert got == expected, text


@pytest.mark.parametrize(
    "text",
    [
        "python.vars(python.int)",
        "python['type']",
        "[g for g in [(x for x in [1])]][0].gi_frame",
        "'\\x7b0.real\\x7d'.format(1)",
        "math.update({})",
        "open",
    ],
)
def test_guarded_eval_refuses_with_an_xacro_error(text):
    import xacro

    with pytest.raises(XacroError, match="is not allowed in a description"):
        with _LOCK, xacro_install.installed(lambda: [], Path("fuzz.xacro")):
            xacro.init_stacks(None)
            xacro.safe_eval(text, xacro.Table(xacro._global_symbols))
