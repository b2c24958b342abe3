"""A recipe's ``noise:`` section: how unlike ideal sensors the runner's sensors are.

Every channel is on unless the recipe turns it off; ``urdf2mjcf.runner.noise``
applies them, seeded per trial. In the recipe (all keys optional; the values shown
are the defaults)::

    noise:
      depth: {subpixel: 0.2165, baseline: 0.050, focal_px: null}  # D435: 2 % at 2 m
      rgb: {read_std: 2.0, shot_gain: 0.05}                      # DN of 0..255
      exposure: {gain: 0.15, light: 0.2}                         # +- fraction per seed
      wrench: {force_std: 0.5, torque_std: 0.02, force_bias: 2.0, torque_bias: 0.1}

``noise: false`` turns every channel off, ``depth: false`` (and so on) one of them.
The models and their sources are in docs/facility.md ("Sensor noise").
"""

from __future__ import annotations

from typing import Any

from ..limits import NOISE_RANGES
from ..schema import Source
from .values import number

DEFAULTS: dict[str, dict[str, float | None]] = {
    # Depth RMS error = z^2 * subpixel / (focal_px * baseline) (Grunnet-Jepsen et al.,
    # "Tuning depth cameras for best performance", Intel RealSense white paper) with the
    # D435's 50 mm baseline and the subpixel that meets its datasheet bound, 2 % RMS at
    # 2 m, with its 433 px focal length at 640 x 480: 0.02 * 433 * 0.05 / 2 = 0.2165
    # (the white paper's typical 0.08 is a well-textured, well-lit scene: 0.74 % at 2 m);
    # focal_px null: the focal length of the camera that renders the depth image.
    "depth": {"subpixel": 0.2165, "baseline": 0.050, "focal_px": None},
    # Read noise (Gaussian, DN) plus shot noise (variance shot_gain * signal, DN^2).
    "rgb": {"read_std": 2.0, "shot_gain": 0.05},
    # Per seed: the image gain in 1 +- gain and every light's intensity in 1 +- light.
    "exposure": {"gain": 0.15, "light": 0.2},
    # White noise (std per axis) and a bias per axis drawn once per seed (std).
    "wrench": {"force_std": 0.5, "torque_std": 0.02, "force_bias": 2.0, "torque_bias": 0.1},
}
CHANNELS = tuple(DEFAULTS)
RANGES = NOISE_RANGES
"""Each setting's range (every value is finite: ``urdf2mjcf.facility.values.number``);
the runtime checks a bundle's against the same (``urdf2mjcf.limits``)."""


def parse_noise(value: Any, src: Source, key: str = "noise") -> dict[str, dict | bool]:
    """The resolved ``noise:`` section: channel -> its settings (defaults filled in) or
    False (off). None (no section): every channel on with its defaults."""
    if value is None or value is True:
        value = {}
    if value is False:
        return {name: False for name in CHANNELS}
    section = src.mapping(value, key, "a mapping of sensor channels, or false (no noise)")
    src.known(section, CHANNELS, key)
    out: dict[str, dict | bool] = {}
    for name, defaults in DEFAULTS.items():
        given = section.get(name, {})
        where = f"{key}.{name}"
        if given is False:
            out[name] = False
            continue
        given = src.mapping(None if given is True else given, where, "a mapping or false")
        src.known(given, defaults, where)
        settings: dict[str, float | None] = dict(defaults)
        for field, v in given.items():
            if v is None and defaults[field] is None:
                continue
            low, high, low_open = RANGES[field]
            settings[field] = number(v, src, f"{where}.{field}", low=low, high=high,
                                     low_open=low_open)
        out[name] = settings
    return out
