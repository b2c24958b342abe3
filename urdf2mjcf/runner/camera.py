"""The one camera model: how a MuJoCo camera maps the world onto its pixels.

MuJoCo renders a pinhole camera without distortion, with square pixels, the principal
point at the image centre and a vertical field of view ``fovy``: its focal length in
pixels is ``f = (h / 2) / tan(fovy / 2)`` for an image ``h`` rows high. Perception,
localization, the recordings' ``CameraInfo`` and the depth noise model all take their
intrinsics from here.

Pixel coordinates: OpenCV and ROS put pixel centres on integers, so the principal point
is ``((w - 1) / 2, (h - 1) / 2)`` (:class:`CameraModel`); ``perception`` puts them at
+0.5, the same point at ``(w / 2, h / 2)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import mujoco


def pinhole_focal(height: int, fovy_deg: float) -> float:
    """Focal length (pixels, fx = fy) of a MuJoCo camera's image of ``height`` rows:
    MuJoCo renders a pinhole with square pixels and vertical field of view ``fovy``."""
    return (height / 2) / math.tan(math.radians(fovy_deg) / 2)


@dataclass(frozen=True)
class CameraModel:
    """A pinhole camera without distortion, as MuJoCo renders: square pixels, the
    principal point at the image centre."""

    width: int
    height: int
    fovy_deg: float
    """Vertical field of view (MuJoCo's ``fovy``), degrees."""

    @property
    def focal(self) -> float:
        """Focal length in pixels (fx = fy)."""
        return pinhole_focal(self.height, self.fovy_deg)

    @property
    def principal_point(self) -> tuple[float, float]:
        """(cx, cy) in pixels, pixel centres on integers (OpenCV's and ROS's convention)."""
        return (self.width - 1) / 2, (self.height - 1) / 2

    def matrix(self) -> np.ndarray:
        """(3, 3) OpenCV camera matrix."""
        f = self.focal
        cx, cy = self.principal_point
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    @classmethod
    def from_manifest(cls, camera: Mapping[str, Any]) -> CameraModel:
        """From a ``facility.json`` camera entry (``resolution`` [w, h], ``fovy``)."""
        w, h = camera["resolution"]
        return cls(int(w), int(h), float(camera["fovy"]))

    @classmethod
    def of(cls, m: mujoco.MjModel, cam: int, width: int, height: int) -> CameraModel:
        """Camera ``cam`` of model ``m`` rendering images of ``width`` x ``height``."""
        return cls(width, height, float(m.cam_fovy[cam]))
