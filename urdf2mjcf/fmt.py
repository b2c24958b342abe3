"""The one float formatter used for everything we write.

Python's ``repr`` gives the shortest text that round-trips a double, so link
frames survive the trip through XML exactly (MuJoCo's own writer keeps 6
significant digits).
"""

from __future__ import annotations

from collections.abc import Iterable


def fmt_float(x: float) -> str:
    x = float(x)
    if x != x or x in (float("inf"), float("-inf")):
        raise ValueError(f"non-finite number {x!r} cannot be written to MJCF")
    if x == 0.0:
        return "0"  # also folds -0.0
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def fmt_vec(values: Iterable[float]) -> str:
    return " ".join(fmt_float(v) for v in values)
