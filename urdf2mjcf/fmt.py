"""The one float formatter used for everything we write (the one writer of MJCF text is
:func:`urdf2mjcf.mjcf.document.mjcf_bytes`).

Python's ``repr`` gives the shortest text that round-trips a double, so link
frames survive the trip through XML exactly (MuJoCo's own writer keeps 6
significant digits).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from lxml import etree


def fmt_float(x: float) -> str:
    x = float(x)
    if x != x or x in (float("inf"), float("-inf")):
        raise ValueError(f"non-finite number {x!r} cannot be written to MJCF")
    if x == 0.0:
        return "0"  # also folds -0.0
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def fmt_floats(values: object) -> list[str]:
    """:func:`fmt_float` of every number of an array (row-major), the same texts without
    a Python call per number: a textured mesh's OBJ holds millions."""
    flat = np.asarray(values, dtype=np.float64).ravel()
    bad = np.flatnonzero(~np.isfinite(flat))
    if len(bad):
        fmt_float(flat[bad[0]])  # raises, naming the number
    out = list(map(repr, flat.tolist()))
    whole = np.flatnonzero((flat == np.trunc(flat)) & (np.abs(flat) < 1e15))
    for i, v in zip(whole.tolist(), flat[whole].astype(np.int64).tolist(), strict=True):
        out[i] = str(v)  # 0 for -0.0 too
    return out


def fmt_vec(values: Iterable[float]) -> str:
    return " ".join(fmt_float(v) for v in values)


def set_attrs(el: etree._Element, **attrs: object) -> etree._Element:
    """Set MJCF attributes on ``el`` with the one formatter; None values are skipped."""
    for key, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, str):
            el.set(key, value)
        elif isinstance(value, (int, float)):
            el.set(key, fmt_float(value))
        else:
            el.set(key, fmt_vec(value))  # type: ignore[arg-type]
    return el
