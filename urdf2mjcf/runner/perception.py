"""Find the CTB's red handle strap on the wrist camera and turn it into a grasp pose.

Render RGB and depth headlessly (call :func:`urdf2mjcf.headless.configure`
before mujoco is first imported), segment red by colour, take the region's
centroid, size and principal axis (PCA), and back-project with the depth and
the pinhole intrinsics of the MuJoCo camera (``urdf2mjcf.runner.camera``: square
pixels, principal point at the image centre; the camera looks along its -z,
x right, y up). Nothing here reads the true pose of the bag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from .camera import pinhole_focal
from .noise import SensorNoise


@dataclass
class Segment:
    mask: np.ndarray  # bool (h, w)
    pixels: int
    centroid: np.ndarray  # (u, v): column, row (pixel centres at +0.5)
    axis: np.ndarray  # unit principal axis in the image (du, dv)
    angle_deg: float  # of the axis, atan2(dv, du) in [0, 180)
    length_px: float  # extent along the axis
    width_px: float  # extent across it
    aspect: float


@dataclass
class Grasp:
    position: np.ndarray  # world point on the strap's seen surface at the centroid
    axis: np.ndarray  # strap direction in the world (horizontal unit vector)
    yaw: float  # atan2 of the axis
    depth: float  # m, along the optical axis
    segment: Segment


def red_mask(rgb: np.ndarray) -> np.ndarray:
    """Red: a strong red channel well above green and blue."""
    img = rgb.astype(np.int32)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r > 90) & (r > 2 * g) & (r > 2 * b)


def segment(mask: np.ndarray, min_pixels: int = 50) -> Segment | None:
    """Centroid, principal axis and extents of the largest blob of ``mask``
    (the whole mask: the strap and its loops are one red region)."""
    vs, us = np.nonzero(mask)
    if len(us) < min_pixels:
        return None
    u, v = us + 0.5, vs + 0.5
    c = np.array([u.mean(), v.mean()])
    cov = np.cov(np.vstack([u - c[0], v - c[1]]))
    evals, evecs = np.linalg.eigh(cov)
    axis = evecs[:, 1]
    along = np.vstack([u - c[0], v - c[1]]).T @ axis
    across = np.vstack([u - c[0], v - c[1]]).T @ evecs[:, 0]
    length = float(along.max() - along.min() + 1)
    width = float(across.max() - across.min() + 1)
    angle = math.degrees(math.atan2(axis[1], axis[0])) % 180.0
    return Segment(mask, len(us), c, axis, angle, length, width, length / max(width, 1.0))


def focal(m: mujoco.MjModel, cam: int, height: int) -> float:
    return pinhole_focal(height, float(m.cam_fovy[cam]))


def backproject(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    cam: int,
    u: float,
    v: float,
    depth: float,
    size: tuple[int, int],
) -> np.ndarray:
    """World point seen at pixel (u, v) (column, row; centres at +0.5) at ``depth``
    along the optical axis, for an image of ``size`` = (height, width)."""
    h, w = size
    f = focal(m, cam, h)
    p_cam = np.array([(u - w / 2) / f * depth, -(v - h / 2) / f * depth, -depth])
    return d.cam_xpos[cam] + d.cam_xmat[cam].reshape(3, 3) @ p_cam


def render_rgbd(
    r: mujoco.Renderer,
    m: mujoco.MjModel,
    d: mujoco.MjData,
    cam: int,
    noise: SensorNoise | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """RGB (uint8) and depth (m along the optical axis) of camera ``cam`` at the
    renderer's size; with ``noise``, as the real sensor reads them."""
    r.disable_depth_rendering()
    r.update_scene(d, camera=cam)
    rgb = r.render().copy()
    r.enable_depth_rendering()
    try:
        r.update_scene(d, camera=cam)
        depth = r.render().copy()
    finally:
        r.disable_depth_rendering()
    if noise is not None:
        rgb, depth = noise.rgb(rgb), noise.depth(depth, float(m.cam_fovy[cam]))
    return rgb, depth


class Camera:
    """Offscreen RGB and depth of one model camera; with ``noise``, as the real sensor
    reads them (``urdf2mjcf.runner.noise``)."""

    def __init__(
        self,
        m: mujoco.MjModel,
        cam: int,
        size: tuple[int, int] | None = None,
        noise: SensorNoise | None = None,
    ):
        self.m, self.cam, self.noise = m, cam, noise
        h, w = size if size else (int(m.cam_resolution[cam][1]), int(m.cam_resolution[cam][0]))
        if h <= 0 or w <= 0:
            h, w = 480, 640
        self.size = (h, w)
        self.renderer = mujoco.Renderer(m, h, w)

    def rgbd(self, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        return render_rgbd(self.renderer, self.m, d, self.cam, self.noise)

    def close(self) -> None:
        self.renderer.close()


def find_handle(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    cam: int,
    rgb: np.ndarray,
    depth: np.ndarray,
    min_pixels: int = 50,
) -> Grasp | None:
    """The strap's grasp point and direction, or None when no red is in view."""
    mask = red_mask(rgb)
    seg = segment(mask, min_pixels)
    if seg is None:
        return None
    size = mask.shape
    z = float(np.median(depth[mask]))
    p = backproject(m, d, cam, seg.centroid[0], seg.centroid[1], z, size)
    half = 0.25 * seg.length_px
    ua, va = seg.centroid - half * seg.axis
    ub, vb = seg.centroid + half * seg.axis
    a = backproject(m, d, cam, ua, va, z, size)
    b = backproject(m, d, cam, ub, vb, z, size)
    ax = b - a
    ax[2] = 0.0
    ax /= np.linalg.norm(ax)
    return Grasp(p, ax, math.atan2(ax[1], ax[0]), z, seg)


def grasp_rotation(strap_axis: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Tool rotation for a top-down grasp across the strap: tool z down, the finger
    direction (tool y) across the strap, tool x along it, the sign nearest ``current``."""
    x = np.asarray(strap_axis, float).copy()
    x[2] = 0.0
    x /= np.linalg.norm(x)
    if x @ current[:, 0] < 0:
        x = -x
    z = np.array([0.0, 0.0, -1.0])
    y = np.cross(z, x)
    return np.column_stack([x, y, z])
