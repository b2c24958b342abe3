"""The documented ranges that a facility bundle's builder and its runtime both check.

``make-facility`` checks recipes against them; ``facility-demo`` and ``rover-drive``
check a bundle (and a waypoints file) against the same numbers without importing the
builder: the runtime reads bundles, never ``urdf2mjcf.facility`` (docs/security.md
explains each range).
"""

from __future__ import annotations

import math

SEED_MAX = 2**32 - 1
"""Largest seed (``make-facility --seed``, ``facility-demo --seed``, ``rocks.seed``):
numpy takes any integer >= 0, 32 bits are more trials than anyone runs."""
LENGTH_MAX = 10_000.0
"""m: largest coordinate of a placement, a rock area or a keep-out (10 km; the
lunar terrain is 1 km across)."""
ANGLE_MAX = 4 * math.pi
"""rad: largest yaw or roll-pitch-yaw angle (two turns either way)."""
TIMESTEP_RANGE = (1e-5, 0.1)
"""s: ``simulation.timestep`` (MuJoCo's default is 0.002); below it one simulated
second is over 100,000 steps, above it no contact is stable."""
TAG_FAMILY = "tag36h11"
TAG_COUNT = 587
"""Ids of the 36h11 family: 0 .. 586."""
