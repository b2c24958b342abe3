"""Seeded pose uncertainty: reproducible random offsets of mockups and the CTB.

The paper names the lack of this as a lesson learned: the CTB pose was never
randomised. Offsets are uniform in +-range, drawn from one
``numpy.random.default_rng(seed)`` in a fixed order (components sorted by
name, then the CTB), so the same seed gives the same facility and a
different seed moves only the jittered poses.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .recipe import Pose2D


def jittered(
    placements: Mapping[str, Pose2D],
    ctb: Pose2D | None,
    ranges: Mapping[str, float],
    seed: int | None,
) -> tuple[dict[str, Pose2D], Pose2D | None, dict[str, dict[str, float]]]:
    """Poses after jitter, and the offsets applied (for the manifest).

    ``seed=None``: the nominal poses, no offsets.
    """
    if seed is None:
        return dict(placements), ctb, {}
    rng = np.random.default_rng(seed)
    offsets: dict[str, dict[str, float]] = {}

    def move(pose: Pose2D, dpos: float, dyaw: float, name: str) -> Pose2D:
        # Always draw three numbers so one component's range never shifts another's draw.
        dx, dy, dth = rng.uniform(-1.0, 1.0, size=3)
        delta = {"dx": float(dx * dpos), "dy": float(dy * dpos), "dyaw": float(dth * dyaw)}
        offsets[name] = delta
        x, y, z = pose.xyz
        return Pose2D((x + delta["dx"], y + delta["dy"], z), pose.yaw + delta["dyaw"])

    out = {
        name: move(placements[name], ranges.get("position", 0.0), ranges.get("yaw", 0.0), name)
        for name in sorted(placements)
    }
    moved_ctb = None
    if ctb is not None:
        moved_ctb = move(ctb, ranges.get("ctb_position", 0.0), ranges.get("ctb_yaw", 0.0), "ctb")
    return out, moved_ctb, offsets
