"""Fuzzing the URDF reader: any document is a model or a ConversionError.

Hypothesis builds URDF documents as a stranger might write them -- random trees
of links and joints whose attributes are NaN, huge, empty, unicode, lists of
the wrong length or missing, unknown elements nested a few levels deep -- and
runs them through the real first two passes (``xacro.run`` reads the file as a
plain URDF, ``parse.run`` builds the robot), as :func:`urdf2mjcf.api.build` chains
them. Anything but a :class:`~urdf2mjcf.ir.Model` or a
:class:`~urdf2mjcf.errors.ConversionError` (a ValueError, KeyError, RecursionError,
...) is a bug: the command would report it as an internal error.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lxml import etree

from urdf2mjcf.errors import ConversionError
from urdf2mjcf.ir import Model
from urdf2mjcf.passes import parse, xacro

SPECIAL = [
    "nan",
    "NaN",
    "inf",
    "-inf",
    "Infinity",
    "1e300",
    "-1e300",
    "1e-300",
    "1e999",
    "-0",
    "0",
    "1",
    "-1",
    "",
    " ",
    "0 0 0",
    "1 2 3",
    "1 2",
    "1 2 3 4 5 6 7",
    "nan 0 0",
    "0 inf 0",
    "1e300 1e300 1e300",
    "1,2,3",
    "0x10",
    "1_000",
    "abc",
    "é中文",
    "\u202e",
    "9" * 400,
]

# XML 1.0 text: no control characters, no surrogates
xml_text = st.text(
    alphabet=st.characters(blacklist_categories=("Cs", "Cc"), max_codepoint=0x2FFFF), max_size=24
)
numbers = st.floats(allow_nan=True, allow_infinity=True).map(repr)
number_lists = st.lists(
    st.one_of(numbers, st.sampled_from(["0", "1", "-1"])), min_size=0, max_size=5
).map(" ".join)
values = st.one_of(st.sampled_from(SPECIAL), numbers, number_lists, xml_text)
maybe = st.one_of(st.none(), values)
"""An attribute value, or None: the attribute left out."""


def good(n: int) -> st.SearchStrategy[str]:
    """``n`` plain numbers, as a careful author writes them."""
    return st.lists(st.floats(-10, 10).map(lambda x: f"{x:.3g}"), min_size=n, max_size=n).map(
        " ".join
    )


def field(n: int) -> st.SearchStrategy[str | None]:
    """An attribute of ``n`` numbers: mostly right (so that documents get past the first
    attribute to the deeper checks), sometimes anything, sometimes missing."""
    return st.one_of(good(n), good(n), good(n), good(n), good(n), good(n), maybe)


ATTR_WIDTH = {"xyz": 3, "rpy": 3, "size": 3, "normal": 3, "scale": 3, "rgba": 4}

JOINT_TYPES = ["revolute", "continuous", "prismatic", "fixed", "floating", "planar"]
SHAPES = ["box", "cylinder", "sphere", "capsule", "plane", "mesh", "heightmap"]
SHAPE_ATTRS = ["size", "radius", "length", "normal", "scale", "filename"]


def _set(el: etree._Element, attrs: dict[str, str | None]) -> etree._Element:
    for key, value in attrs.items():
        if value is not None:
            el.set(key, value)
    return el


@st.composite
def garbage(draw: st.DrawFn, depth: int = 0) -> etree._Element:
    """Unknown elements nested at most four deep (the reader ignores or refuses them)."""
    el = etree.Element(draw(st.sampled_from(["foo", "origin", "link", "joint", "mujoco", "x"])))
    _set(el, {"name": draw(maybe), "xyz": draw(maybe), "value": draw(maybe)})
    if depth < 4:
        for child in draw(st.lists(garbage(depth + 1), max_size=2)):
            el.append(child)
    return el


@st.composite
def origin(draw: st.DrawFn) -> etree._Element:
    return _set(etree.Element("origin"), {"xyz": draw(field(3)), "rpy": draw(field(3))})


@st.composite
def geometry_holder(draw: st.DrawFn, tag: str) -> etree._Element:
    holder = etree.Element(tag)
    if draw(st.booleans()):
        holder.append(draw(origin()))
    if draw(st.integers(0, 9)) != 1:  # now and then no <geometry> at all
        geometry = etree.SubElement(holder, "geometry")
        if draw(st.integers(0, 9)):
            shape = etree.SubElement(geometry, draw(st.sampled_from(SHAPES)))
            attrs = st.lists(st.sampled_from(SHAPE_ATTRS), min_size=1, max_size=4, unique=True)
            for attr in draw(attrs):
                value = draw(field(ATTR_WIDTH.get(attr, 1)))
                if attr == "filename" and value is not None:
                    value = "missing_" + str(abs(hash(value)) % 1000) + ".stl"
                _set(shape, {attr: value})
    if tag == "visual" and draw(st.booleans()):
        material = _set(etree.SubElement(holder, "material"), {"name": draw(maybe)})
        if draw(st.booleans()):
            _set(etree.SubElement(material, "color"), {"rgba": draw(field(4))})
    return holder


@st.composite
def link(draw: st.DrawFn, name: str | None) -> etree._Element:
    el = _set(etree.Element("link"), {"name": name})
    if draw(st.booleans()):
        inertial = etree.SubElement(el, "inertial")
        if draw(st.booleans()):
            inertial.append(draw(origin()))
        if draw(st.integers(0, 9)) != 1:  # now and then no <mass>
            _set(etree.SubElement(inertial, "mass"), {"value": draw(field(1))})
        if draw(st.booleans()):
            names = ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"]
            _set(etree.SubElement(inertial, "inertia"), {k: draw(field(1)) for k in names})
    for tag in draw(st.lists(st.sampled_from(["visual", "collision"]), max_size=3)):
        el.append(draw(geometry_holder(tag)))
    return el


@st.composite
def joint(draw: st.DrawFn, names: list[str], i: int) -> etree._Element:
    jtype = draw(st.one_of(*[st.sampled_from(JOINT_TYPES)] * 4, xml_text, st.none()))
    jname = draw(st.one_of(st.just(f"j{i}"), st.just("j0"), xml_text))
    el = _set(etree.Element("joint"), {"name": jname, "type": jtype})
    pick = st.one_of(st.sampled_from(names), xml_text, st.none()) if names else xml_text
    if draw(st.integers(0, 9)):
        _set(etree.SubElement(el, "parent"), {"link": draw(pick)})
    if draw(st.integers(0, 9)):
        _set(etree.SubElement(el, "child"), {"link": draw(pick)})
    if draw(st.booleans()):
        el.append(draw(origin()))
    if draw(st.booleans()):
        _set(etree.SubElement(el, "axis"), {"xyz": draw(field(3))})
    if draw(st.booleans()):
        limit = etree.SubElement(el, "limit")
        _set(limit, {k: draw(field(1)) for k in ("lower", "upper", "effort", "velocity")})
    if draw(st.booleans()):
        dynamics = etree.SubElement(el, "dynamics")
        _set(dynamics, {"damping": draw(field(1)), "friction": draw(field(1))})
    if draw(st.integers(0, 4)) == 0:
        mimic = etree.SubElement(el, "mimic")
        _set(mimic, {"joint": draw(pick), "multiplier": draw(field(1)), "offset": draw(field(1))})
    return el


@st.composite
def urdf_documents(draw: st.DrawFn) -> bytes:
    """A robot of up to 6 links; joints mostly form a chain, sometimes anything."""
    robot = _set(etree.Element("robot"), {"name": draw(st.one_of(st.just("r"), xml_text))})
    count = draw(st.integers(0, 6))
    names = [draw(st.one_of(st.just(f"l{i}"), st.just("l0"), xml_text)) for i in range(count)]
    for name in names:
        robot.append(draw(link(name)))
    for i in range(1, count):
        if draw(st.integers(0, 4)):  # the chain's joint, its fields fuzzed
            el = draw(joint(names, i))
            for tag, value in (("parent", names[i - 1]), ("child", names[i])):
                found = el.find(tag)
                if found is not None and draw(st.integers(0, 3)):
                    found.set("link", value)
            robot.append(el)
    for i in range(draw(st.integers(0, 2))):  # stray joints
        robot.append(draw(joint(names, 100 + i)))
    if draw(st.booleans()):
        material = _set(etree.SubElement(robot, "material"), {"name": draw(maybe)})
        _set(etree.SubElement(material, "color"), {"rgba": draw(field(4))})
    for extra in draw(st.lists(garbage(), max_size=2)):
        robot.append(extra)
    return etree.tostring(robot)


def parse_document(data: bytes) -> Model | ConversionError:
    """The first two passes on ``data``, as :func:`urdf2mjcf.api.build` runs them."""
    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "robot.urdf"
        source.write_bytes(data)
        cfg = xacro.XacroConfig(use_environment=False)
        try:
            doc = xacro.run(source, cfg)
            return parse.run(doc, parse.ParseConfig())
        except ConversionError as exc:
            return exc


def _finite_model(model: Model) -> None:
    """What parse let through is finite: later passes never see NaN or inf."""
    for ln in model.robot.links:
        if ln.inertial is not None:
            numbers = [ln.inertial.mass, *ln.inertial.inertia, *ln.inertial.origin.xyz]
            assert all(math.isfinite(x) for x in numbers), ln
    for j in model.robot.joints:
        numbers = [*j.origin.xyz, *j.origin.rpy, *j.axis]
        if j.limit is not None:
            numbers += [x for x in (j.limit.lower, j.limit.upper) if x is not None]
        assert all(math.isfinite(x) for x in numbers), j


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(urdf_documents())
def test_any_urdf_is_a_model_or_a_conversion_error(data: bytes) -> None:
    result = parse_document(data)
    if isinstance(result, Model):
        _finite_model(result)
    else:
        assert isinstance(result, ConversionError)
        assert str(result).strip()


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=300) | xml_text.map(str.encode))
def test_any_bytes_are_a_model_or_a_conversion_error(data: bytes) -> None:
    assert isinstance(parse_document(b"<robot " + data), Model | ConversionError)
    assert isinstance(parse_document(data), Model | ConversionError)


def test_deep_nesting_is_an_error_or_a_model_not_a_crash() -> None:
    depth = 100_000
    data = b"<robot name='r'>" + b"<x>" * depth + b"</x>" * depth + b"</robot>"
    assert isinstance(parse_document(data), Model | ConversionError)
