"""Seeded pose uncertainty: reproducible random offsets of the placed components.

The paper names the lack of this as a lesson learned: the pose of the bag the
robot grasps was never randomised. Offsets are uniform in +-range, drawn from one
``numpy.random.default_rng(seed)`` in a fixed order: the fixed components sorted
by name, then the free bodies sorted by name (so adding or removing a free body
never changes a fixed component's draw). A component whose ranges are None (the
reference a runner measures from) never moves and draws nothing. The same seed
gives the same facility; a different seed moves only the jittered poses.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping

import numpy as np

from ..errors import InputError
from .recipe import Pose2D, Ranges
from .values import SEED_MAX


def jittered(
    placements: Mapping[str, Pose2D],
    ranges: Mapping[str, Ranges],
    free: Collection[str],
    seed: int | None,
) -> tuple[dict[str, Pose2D], dict[str, dict[str, float]]]:
    """Poses after jitter (the unmoved ones first, then in the order drawn), and the
    offsets applied (for the manifest). ``ranges``: component -> {position, yaw} (a
    missing component: 0, 0) or None (never moves). ``seed=None``: the nominal poses,
    no offsets."""
    if seed is None:
        return dict(placements), {}
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= SEED_MAX:
        raise InputError(f"'{seed}' is not a seed (0 .. {SEED_MAX})", file="--seed")
    rng = np.random.default_rng(seed)
    offsets: dict[str, dict[str, float]] = {}

    def move(pose: Pose2D, dpos: float, dyaw: float, name: str) -> Pose2D:
        # Always draw three numbers so one component's range never shifts another's draw.
        dx, dy, dth = rng.uniform(-1.0, 1.0, size=3)
        delta = {"dx": float(dx * dpos), "dy": float(dy * dpos), "dyaw": float(dth * dyaw)}
        offsets[name] = delta
        x, y, z = pose.xyz
        return Pose2D((x + delta["dx"], y + delta["dy"], z), pose.yaw + delta["dyaw"])

    out = {n: p for n, p in placements.items() if n in ranges and ranges[n] is None}
    moving = [n for n in placements if n not in out]
    order = sorted(n for n in moving if n not in free) + sorted(n for n in moving if n in free)
    for name in order:
        r = ranges.get(name) or {}
        out[name] = move(placements[name], r.get("position", 0.0), r.get("yaw", 0.0), name)
    return out, offsets
