"""A component's pose on the floor, as recipes give it and fiducials, jitter and the
manifest read it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Pose2D:
    """A pose on the floor: position (m) and yaw about +z (rad)."""

    xyz: tuple[float, float, float]
    yaw: float = 0.0
