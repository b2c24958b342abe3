"""Checked values from recipe files: one error shape (file and key) for every field,
and the documented ranges of the facility's numbers.

A recipe, a ``--set`` and a waypoints file are written by strangers: every number
in them is finite and within the range below, or the build (or the demo) stops
with one error naming the file, the key and its line, before anything runs.
The ranges are wide enough for every recipe in ``recipes/`` and every real
facility we know, and narrow enough that no value can make a build or a run
loop for hours, allocate without bound or overflow (docs/security.md).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..limits import ANGLE_MAX, LENGTH_MAX, SEED_MAX, TIMESTEP_RANGE  # noqa: F401
from ..schema import Source
from ..untrusted import BadNumber, read_number, shown

JITTER_POSITION_MAX = 10.0
"""m: largest +- position range of a component's jitter."""
JITTER_YAW_MAX = math.pi
"""rad: largest +- yaw range of a component's jitter (a half turn: any heading)."""
ITERATIONS_MAX = 10_000
"""``simulation.iterations`` (MuJoCo's default 100): solver iterations per step."""
IMPRATIO_MAX = 1_000.0
"""``simulation.impratio`` (> 0; our recipes use 10)."""
FLAG_MAX = 1e9
"""Magnitude of any numeric flag (a xacro argument) without its own range."""
FLAG_RANGES: tuple[tuple[str, tuple[float, float, bool]], ...] = (
    # (name pattern, (low, high, low_open)): a flag's range follows from what its name says
    # it is, whatever the component (the builder knows none by name); first match wins
    (r"gravity", (0.0, 1_000.0, False)),  # m/s^2 (or auto: the world's own)
    (r".*_(stiffness|damping|friction|mass)", (0.0, 1e6, False)),  # physical, >= 0; 0: rigid
    (r".*_size(_[xyz])?", (0.0, 100_000.0, True)),  # m, an extent
    (r".*_base", (0.0, 10_000.0, True)),  # m, a heightfield's base thickness
    (r".*_z_(min|max)", (-10_000.0, 10_000.0, False)),  # m, an elevation
    (r".*_[xyz]", (-LENGTH_MAX, LENGTH_MAX, False)),  # m, a position
)
"""Numeric flags whose name gives them a range (any other numeric flag: |x| <= FLAG_MAX)."""


def flag_range(name: str) -> tuple[float, float, bool]:
    """The range of the numeric flag ``name``: (low, high, low_open)."""
    import re

    for pattern, bounds in FLAG_RANGES:
        if re.fullmatch(pattern, name):
            return bounds
    return (-FLAG_MAX, FLAG_MAX, False)


def fail(path: Path | Source | None, key: str, message: str) -> InputError:
    """The error naming the file and the key (and its line, given the file's Source)."""
    if isinstance(path, Source):
        return path.fail(key, message)  # type: ignore[return-value]
    return InputError(message, file=path or "recipe", element=key)


def number(
    value: Any,
    path: Path | Source | None,
    key: str,
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
) -> float:
    """A finite float in [low, high] (``(low, high]`` with ``low_open``), or an
    InputError naming the file and the key (:func:`urdf2mjcf.untrusted.read_number`:
    text only in decimal, at most ``NUMBER_TEXT_MAX`` characters)."""
    if not isinstance(value, (int, float, str)):
        raise fail(path, key, f"'{shown(value)}' is not a number")
    try:
        return read_number(value, low=low, high=high, low_open=low_open)
    except BadNumber as exc:
        raise fail(path, key, str(exc)) from None


def whole(value: Any, path: Path | Source | None, key: str, *, low: int, high: int) -> int:
    """An integer (not a bool, not a float, not text) in [low, high], or an InputError."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise fail(path, key, f"'{shown(value)}' is not a whole number from {low} to {high}")
    return value
