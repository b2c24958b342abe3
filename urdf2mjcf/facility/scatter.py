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

Bounds (a recipe is a stranger's file; docs/security.md): ``count`` <= 10,000
(every recipe in ``recipes/`` asks for 30; each rock is a body in the compiled
model and about 60 characters of the xacro argument, and 10,000 rocks are a
crowded square kilometre), ``variants`` 1 .. 100, ``seed`` 0 .. 2**32-1,
coordinates within +-10 km, sizes 0.01 .. 100 m, at most 100 keep-out
rectangles. The scatter gives up after 2,000 draws per rock, 200,000 draws in all
or ``WORK_MAX`` checks, whichever comes first, so a count that does not fit fails
in seconds, not hours.
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
from .values import LENGTH_MAX, SEED_MAX, fail, number, whole

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
COUNT_MAX = 10_000
"""Most rocks a recipe may ask for (see the module's docstring)."""
VARIANTS_MAX = 100
KEEPOUT_MAX = 100
SIZE_RANGE = (0.01, 100.0)
"""m: the smallest and the largest rock size allowed."""
TRY_MAX = 200_000
"""Most draws one scatter makes before giving up (a few seconds); the recipes' scatters
end long before it (30 rocks: at most 60,000 draws, in practice under 100)."""
WORK_MAX = 5_000_000
"""Most draws x (keep-outs + placements) checks one scatter makes before giving up."""
_BATCH = 1024
"""Draws taken from the generator at once (the same numbers as one draw at a time)."""
_AROUND = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]


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


def _numbers(
    value: Any,
    n: int,
    path: Path | Source | None,
    key: str,
    low: float = -LENGTH_MAX,
    high: float = LENGTH_MAX,
) -> list[float]:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise _fail(path, key, f"needs {n} numbers")
    return [number(v, path, f"rocks.{key}", low=low, high=high) for v in value]


def parse_rocks(data: Any, path: Path | Source | None) -> dict[str, Any]:
    """A recipe's ``rocks:`` section, checked and completed with the defaults."""
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise fail(path, "rocks", "a mapping of rock settings")
    unknown = set(data) - set(ROCK_KEYS)
    if unknown:
        raise _fail(path, ", ".join(sorted(unknown)), f"unknown key; valid: {', '.join(ROCK_KEYS)}")
    spec = {**DEFAULTS, **{str(k): v for k, v in data.items()}}
    whole(spec["count"], path, "rocks.count", low=0, high=COUNT_MAX)
    whole(spec["seed"], path, "rocks.seed", low=0, high=SEED_MAX)
    whole(spec["variants"], path, "rocks.variants", low=1, high=VARIANTS_MAX)
    area = _numbers(spec["area"], 4, path, "area")
    if not (area[0] < area[1] and area[2] < area[3]):
        raise _fail(path, "area", "needs x0 < x1 and y0 < y1")
    size = _numbers(spec["size"], 2, path, "size", *SIZE_RANGE)
    if not size[0] <= size[1]:
        raise _fail(path, "size", "needs smallest <= largest")
    clearance = _numbers([spec["clearance"]], 1, path, "clearance", 0.0)[0]
    if not isinstance(spec["keepout"], (list, tuple)) or len(spec["keepout"]) > KEEPOUT_MAX:
        message = f"a list of at most {KEEPOUT_MAX} [x0, x1, y0, y1] rectangles"
        raise _fail(path, "keepout", message)
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
    # Rocks by grid cell (a cell as wide as the largest rock): two rocks overlap only
    # when their centres are nearer than that, so only the 3 x 3 cells around a draw
    # can hold one it overlaps. The same test as against every rock, in O(1).
    cell = smax
    grid: dict[tuple[int, int], list[Rock]] = {}
    tries = min(TRIES_PER_ROCK * count, TRY_MAX, WORK_MAX // (1 + len(keep) + len(avoid)))
    draws: list[list[float]] = []
    for i in range(tries):
        if i % _BATCH == 0:
            draws = rng.random((_BATCH, 4)).tolist()
        # always four draws per try, so one setting never shifts another's numbers
        u = draws[i % _BATCH]
        x, y = x0 + u[0] * (x1 - x0), y0 + u[1] * (y1 - y0)
        size = smin + u[2] * (smax - smin)
        yaw = u[3] * 2 * math.pi
        if any(a <= x <= b and c <= y <= d for a, b, c, d in keep):
            continue
        if any(math.hypot(x - px, y - py) < clear + size / 2 for px, py in avoid):
            continue
        cx, cy = math.floor(x / cell), math.floor(y / cell)
        if _overlaps(grid, cx, cy, x, y, size):
            continue
        variant = len(rocks) % int(spec["variants"])
        rock = Rock(variant, x, y, spec["z"] + SINK * size, yaw, size)
        rocks.append(rock)
        grid.setdefault((cx, cy), []).append(rock)
        if len(rocks) == count:
            return rocks
    raise _fail(path, "count", f"only {len(rocks)} of {count} rocks fit in the area")


def _overlaps(
    grid: dict[tuple[int, int], list[Rock]], cx: int, cy: int, x: float, y: float, size: float
) -> bool:
    """Whether a rock at (x, y) of ``size`` overlaps one in the 3 x 3 cells around (cx, cy)."""
    for dx, dy in _AROUND:
        for r in grid.get((cx + dx, cy + dy), ()):
            if math.hypot(x - r.x, y - r.y) < (size + r.size) / 2:
                return True
    return False


def rocks_arg(rocks: Iterable[Rock]) -> str:
    """The world's ``rocks`` xacro argument: ``variant x y z yaw size`` per rock, ``;`` between."""
    return "; ".join(f"{r.variant} {r.x!r} {r.y!r} {r.z!r} {r.yaw!r} {r.size!r}" for r in rocks)
