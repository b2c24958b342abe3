"""Sensors like the real ones: seeded noise on depth, images and the wrench.

The facility's recipe says how much (its ``noise:`` section, listed in
``facility.json``; defaults in ``urdf2mjcf.facility.noise``); a trial's seed says
which draw. Every channel draws from its own ``numpy.random.Generator`` spawned from
the seed, so the same seed and the same calls give identical noise, and reading one
sensor more often never changes another's noise. What is constant in a trial (the
exposure gain, the light intensities, the force-torque bias) is drawn once, when
:class:`SensorNoise` is made.

Models (sources in docs/facility.md, "Sensor noise"):

* depth: Gaussian per pixel with the RMS error of a stereo camera,
  ``sigma(z) = z**2 * subpixel / (focal_px * baseline)`` (Intel's RealSense D400
  formula; the D435's baseline 50 mm, and by default subpixel 0.2165: its datasheet's
  2 % RMS at 2 m with the 433 px focal length);
* image: exposure gain (per seed), then shot noise (variance ``shot_gain * signal``,
  DN^2) and read noise (``read_std`` DN), rounded and clipped to 0..255;
* lighting: every light's diffuse and ambient intensity and the headlight's scaled
  by one factor per seed (:meth:`SensorNoise.light`, once per loaded model);
* wrench: a bias per axis drawn once per seed (std ``force_bias``, ``torque_bias``)
  plus white noise per reading (std ``force_std``, ``torque_std``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from ..bundle_manifest import Manifest, thaw
from .camera import pinhole_focal

if TYPE_CHECKING:
    import mujoco

_STREAMS = {"depth": 0, "rgb": 1, "exposure": 2, "wrench": 3}
"""Each channel's stream: spawned from the seed by its own key."""


def depth_rms(z: np.ndarray | float, focal_px: float, baseline: float, subpixel: float) -> Any:
    """RMS depth error (m) of a stereo camera at depth ``z`` (m): Intel's formula
    ``z**2 * subpixel / (focal_px * baseline)``."""
    return np.square(z) * subpixel / (focal_px * baseline)


class SensorNoise:
    """Seeded noise for one trial; a channel that is off passes its data through."""

    def __init__(
        self, config: Mapping[str, Any], seed: int | None, fovy_deg: float | None = None
    ) -> None:
        """``config``: facility.json's ``noise`` (channel -> settings or False);
        ``fovy_deg``: the cameras' vertical field of view, for the depth model's focal
        length when the config gives none."""
        self.config = {k: v for k, v in config.items() if v}
        self.seed = 0 if seed is None else int(seed)
        self.fovy_deg = fovy_deg
        self._rng = {
            name: np.random.default_rng(np.random.SeedSequence([self.seed, key]))
            for name, key in _STREAMS.items()
        }
        exposure = self.config.get("exposure") or {}
        draw = self._rng["exposure"].uniform(-1.0, 1.0, size=2)  # always two: stable streams
        self.gain = 1.0 + float(draw[0]) * float(exposure.get("gain", 0.0))
        """Image gain of this trial (exposure)."""
        self.light_scale = 1.0 + float(draw[1]) * float(exposure.get("light", 0.0))
        """Scale of every light's intensity in this trial."""
        wrench = self.config.get("wrench") or {}
        bias = self._rng["wrench"].standard_normal(6)
        self.force_bias = bias[:3] * float(wrench.get("force_bias", 0.0))
        """(3,) N, constant in this trial."""
        self.torque_bias = bias[3:] * float(wrench.get("torque_bias", 0.0))
        """(3,) N m, constant in this trial."""

    @classmethod
    def from_manifest(cls, manifest: Manifest | None, seed: int | None) -> SensorNoise:
        """The noise a built facility's recipe asks for (none for a facility.json
        without ``noise``, or no manifest: ideal sensors), for the trial ``seed``."""
        if manifest is None:
            return cls({}, seed, None)
        fovy = float(manifest.cameras[0].fovy) if manifest.cameras else None
        return cls(thaw(manifest.noise), seed, fovy)

    def focal_px(self, height: int, fovy_deg: float | None = None) -> float:
        """The depth model's focal length (pixels): the config's, else that of a camera
        of ``height`` rows and ``fovy_deg`` (else the facility's cameras')."""
        given = (self.config.get("depth") or {}).get("focal_px")
        if given:
            return float(given)
        fovy = fovy_deg if fovy_deg is not None else self.fovy_deg
        if fovy is None:
            raise ValueError("depth noise needs a focal length: give fovy_deg or focal_px")
        return pinhole_focal(height, fovy)

    def depth_std(self, z: np.ndarray | float, height: int, fovy_deg: float | None = None) -> Any:
        """The configured RMS depth error (m) at depth ``z`` (0 when depth noise is off)."""
        cfg = self.config.get("depth")
        if not cfg:
            return np.zeros_like(np.asarray(z, float))
        f = self.focal_px(height, fovy_deg)
        return depth_rms(np.asarray(z, float), f, float(cfg["baseline"]), float(cfg["subpixel"]))

    def depth(self, depth: np.ndarray, fovy_deg: float | None = None) -> np.ndarray:
        """A noisy copy of a (h, w) depth image (m along the optical axis); pixels
        without a return (0) stay 0."""
        if not self.config.get("depth"):
            return depth
        z = np.asarray(depth, np.float64)
        sigma = self.depth_std(z, z.shape[0], fovy_deg)
        noisy = z + sigma * self._rng["depth"].standard_normal(z.shape)
        noisy = np.where(z > 0, np.maximum(noisy, 0.0), 0.0)
        return noisy.astype(depth.dtype, copy=False)

    def rgb(self, image: np.ndarray) -> np.ndarray:
        """A noisy copy of an (h, w, 3) uint8 image: gain, shot and read noise."""
        cfg = self.config.get("rgb")
        if not cfg and self.gain == 1.0:
            return image
        x = np.asarray(image, np.float64) * self.gain
        if cfg:
            var = float(cfg["shot_gain"]) * np.clip(x, 0.0, None) + float(cfg["read_std"]) ** 2
            x = x + np.sqrt(var) * self._rng["rgb"].standard_normal(x.shape)
        return np.clip(np.rint(x), 0, 255).astype(np.uint8)

    def wrench(self, force: np.ndarray, torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A force-torque reading ((3,) N, (3,) N m) with this trial's bias and noise."""
        cfg = self.config.get("wrench")
        f, t = np.asarray(force, float), np.asarray(torque, float)
        if not cfg:
            return f, t
        white = self._rng["wrench"].standard_normal(6)
        f = f + self.force_bias + white[:3] * float(cfg["force_std"])
        t = t + self.torque_bias + white[3:] * float(cfg["torque_std"])
        return f, t

    def light(self, m: mujoco.MjModel) -> None:
        """Scale the model's lights and headlight by this trial's factor (in place; call
        once per loaded model, before rendering)."""
        if self.light_scale == 1.0:
            return
        s = self.light_scale
        m.light_diffuse[:] = np.clip(m.light_diffuse * s, 0.0, 1.0)
        m.light_ambient[:] = np.clip(m.light_ambient * s, 0.0, 1.0)
        head = m.vis.headlight
        head.diffuse[:] = np.clip(np.asarray(head.diffuse) * s, 0.0, 1.0)
        head.ambient[:] = np.clip(np.asarray(head.ambient) * s, 0.0, 1.0)
