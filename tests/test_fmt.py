"""The array formatter writes what the one float formatter writes, number by number
(the reference: :func:`fmt_float` called on each), and an OBJ keeps every vertex
exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from urdf2mjcf.assets import obj_bytes
from urdf2mjcf.fmt import fmt_float, fmt_floats
from urdf2mjcf.ir import MeshData

EDGES = [0.0, -0.0, 1.0, -3.0, 0.5, 1e15, -1e15, 999999999999999.0, 1e15 + 2, 1e300, 5e-324]


@given(
    arrays(
        np.float64, st.integers(0, 40), elements=st.floats(allow_nan=False, allow_infinity=False)
    )
)
def test_each_text_is_fmt_floats_text(a):
    assert fmt_floats(a) == [fmt_float(x) for x in a]


def test_the_edges_integers_zeros_and_tiny_numbers():
    assert fmt_floats(EDGES) == [fmt_float(x) for x in EDGES]
    assert fmt_floats([[-0.0, 2.0], [2.5, 1e15]]) == ["0", "2", "2.5", "1000000000000000.0"]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_number_is_refused_as_by_fmt_float(bad):
    with pytest.raises(ValueError, match="non-finite number .* cannot be written to MJCF"):
        fmt_floats([1.0, bad])


def test_an_obj_reads_back_to_the_same_vertices_and_uv():
    rng = np.random.default_rng(0)
    vertices = rng.normal(size=(50, 3))
    vertices[0] = (0.0, -0.0, 7.0)
    uv = rng.random((50, 2))
    faces = rng.integers(0, 50, size=(30, 3))
    text = obj_bytes(MeshData(vertices=vertices, faces=faces, uv=uv)).decode()
    rows = [line.split() for line in text.splitlines()]
    v = np.array([[float(x) for x in r[1:]] for r in rows if r[0] == "v"])
    t = np.array([[float(x) for x in r[1:]] for r in rows if r[0] == "vt"])
    f = np.array([[int(x.split("/")[0]) - 1 for x in r[1:]] for r in rows if r[0] == "f"])
    assert np.array_equal(v, vertices) and np.array_equal(t, uv) and np.array_equal(f, faces)
    assert rows[1] == ["v", "0", "0", "7"]
