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

NOISE_CHANNELS = ("depth", "rgb", "exposure", "wrench")
"""The sensor noise channels (``urdf2mjcf.runner.noise``)."""
NOISE_RANGES: dict[str, tuple[float, float, bool]] = {
    # field: (low, high, low_open). Each is >= 0 (> 0 for a divisor) and bounded where a
    # larger value stops describing a sensor: a gain or light factor of 1 +- x with
    # x > 1 would turn negative, images are 0..255 DN, a camera's focal length and
    # baseline are those of a real one.
    "subpixel": (0.0, 100.0, False),
    "baseline": (0.0, 10.0, True),  # m
    "focal_px": (0.0, 1e6, True),  # px
    "read_std": (0.0, 255.0, False),  # DN
    "shot_gain": (0.0, 255.0, False),  # DN
    "gain": (0.0, 1.0, False),
    "light": (0.0, 1.0, False),
    "force_std": (0.0, 1e5, False),  # N
    "torque_std": (0.0, 1e4, False),  # N m
    "force_bias": (0.0, 1e5, False),
    "torque_bias": (0.0, 1e4, False),
}
"""A sensor noise setting -> (low, high, low_open): a recipe's ``noise:`` (make-facility)
and a bundle's ``noise`` (the runtime) are checked against these; every value finite."""
