"""Seeded scatter of rocks for worlds that take a ``rocks`` xacro argument.

A recipe's ``rocks:`` section says how many rocks, where and how big::

    rocks:
      count: 24                 # rocks to place (0: none)
      seed: 3                   # the generator's seed; make-facility --seed N replaces it
      area: [-30, 30, -30, 30]  # x0, x1, y0, y1 (m): the rocks' centres lie in it
      size: [0.2, 0.8]          # m, smallest and largest rock (its scale: ~0.9 x size across)
      clearance: 2.5            # m: no rock centre nearer than this to a placement
      keepout:                  # [x0, x1, y0, y1] rectangles kept free (drive lanes)
        - [0, 25, -2, 2]
      variants: 5               # rock meshes to draw from (rock_0 ... rock_<n-1>)
      z: 0.0                    # m: the ground height where the rocks lie

Rocks are drawn one after the other from ``numpy.random.default_rng(seed)``:
each draw is a position, a size, a yaw and a mesh variant, kept when the rock
is inside the area, outside every keep-out rectangle, at least ``clearance``
from every placement and not overlapping an earlier rock (centres at least
the sum of their sizes apart, half-size each). The same recipe and seed give
the same rocks. The world receives them as one xacro argument,
``rocks:="variant x y z yaw size; ..."``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..schema import Source
from .values import fail, number

ROCK_KEYS = ("count", "seed", "area", "size", "clearance", "keepout", "variants", "z")
DEFAULTS: dict[str, Any] = {
    "count": 0,
    "seed": 0,
    "area": [-20.0, 20.0, -20.0, 20.0],
    "size": [0.2, 0.8],
    "clearance": 2.5,
    "keepout": [],
    "variants": 5,
    "z": 0.0,
}
SINK = 0.08
"""The rock's centre sits SINK x size above the ground: about a third of it is buried."""
TRIES_PER_ROCK = 2000


@dataclass(frozen=True)
class Rock:
    variant: int
    x: float
    y: float
    z: float
    yaw: float
    size: float


def _fail(path: Path | Source | None, key: str, message: str) -> InputError:
    return fail(path, f"rocks.{key}", message)


def _numbers(value: Any, n: int, path: Path | Source | None, key: str) -> list[float]:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise _fail(path, key, f"needs {n} numbers")
    return [number(v, path, f"rocks.{key}") for v in value]


def parse_rocks(data: Any, path: Path | Source | None) -> dict[str, Any]:
    """A recipe's ``rocks:`` section, checked and completed with the defaults."""
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise fail(path, "rocks", "a mapping of rock settings")
    unknown = set(data) - set(ROCK_KEYS)
    if unknown:
        raise _fail(path, ", ".join(sorted(unknown)), f"unknown key; valid: {', '.join(ROCK_KEYS)}")
    spec = {**DEFAULTS, **data}
    for key in ("count", "seed", "variants"):
        value = spec[key]
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise _fail(path, key, f"'{value}' is not a whole number >= 0")
    if spec["variants"] < 1:
        raise _fail(path, "variants", "needs at least one rock mesh")
    area = _numbers(spec["area"], 4, path, "area")
    if not (area[0] < area[1] and area[2] < area[3]):
        raise _fail(path, "area", "needs x0 < x1 and y0 < y1")
    size = _numbers(spec["size"], 2, path, "size")
    if not 0 < size[0] <= size[1]:
        raise _fail(path, "size", "needs 0 < smallest <= largest")
    clearance = _numbers([spec["clearance"]], 1, path, "clearance")[0]
    if clearance < 0:
        raise _fail(path, "clearance", "must be >= 0")
    if not isinstance(spec["keepout"], (list, tuple)):
        raise _fail(path, "keepout", "a list of [x0, x1, y0, y1] rectangles")
    keepout = [_numbers(r, 4, path, "keepout") for r in spec["keepout"]]
    z = _numbers([spec["z"]], 1, path, "z")[0]
    return {
        "count": spec["count"],
        "seed": spec["seed"],
        "area": area,
        "size": size,
        "clearance": clearance,
        "keepout": keepout,
        "variants": spec["variants"],
        "z": z,
    }


def scatter(
    spec: Mapping[str, Any],
    seed: int,
    placements: Iterable[tuple[float, float]] = (),
    path: Path | None = None,
) -> list[Rock]:
    """The rocks of ``spec`` (from :func:`parse_rocks`), drawn with ``seed``."""
    count = int(spec.get("count", 0))
    if count == 0:
        return []
    rng = np.random.default_rng(seed)
    x0, x1, y0, y1 = spec["area"]
    smin, smax = spec["size"]
    clear = spec["clearance"]
    keep = [tuple(r) for r in spec["keepout"]]
    avoid = [(float(x), float(y)) for x, y in placements]
    rocks: list[Rock] = []
    for _ in range(TRIES_PER_ROCK * count):
        # always four draws per try, so one setting never shifts another's numbers
        u = [float(v) for v in rng.random(4)]
        x, y = x0 + u[0] * (x1 - x0), y0 + u[1] * (y1 - y0)
        size = smin + u[2] * (smax - smin)
        yaw = u[3] * 2 * math.pi
        if any(a <= x <= b and c <= y <= d for a, b, c, d in keep):
            continue
        if any(math.hypot(x - px, y - py) < clear + size / 2 for px, py in avoid):
            continue
        if any(math.hypot(x - r.x, y - r.y) < (size + r.size) / 2 for r in rocks):
            continue
        variant = len(rocks) % int(spec["variants"])
        rocks.append(Rock(variant, x, y, spec["z"] + SINK * size, yaw, size))
        if len(rocks) == count:
            return rocks
    raise _fail(path, "count", f"only {len(rocks)} of {count} rocks fit in the area")


def rocks_arg(rocks: Iterable[Rock]) -> str:
    """The world's ``rocks`` xacro argument: ``variant x y z yaw size`` per rock, ``;`` between."""
    return "; ".join(f"{r.variant} {r.x!r} {r.y!r} {r.z!r} {r.yaw!r} {r.size!r}" for r in rocks)
