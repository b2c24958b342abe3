"""Find the facility's components by their AprilTags, as the real robot does.

:func:`localize` detects AprilTag 36h11 markers in an RGB image (OpenCV's
``aruco.ArucoDetector``, sub-pixel corner refinement), estimates each tag's pose
in the camera from its four corners and the pinhole intrinsics of the camera
(``cv2.solvePnP`` with ``SOLVEPNP_IPPE_SQUARE``), and refines it with the depth
image: a plane fitted to the depth pixels inside the tag gives the tag's normal
and, where the ray through the tag's centre meets it, its distance (the corners
alone fix the distance only to a fraction of a pixel's worth of scale). From each
tag's known pose on its component (``facility.json``'s ``fiducials``, the
drawings) and the camera's pose in the world (the robot's own kinematics), it
gives each seen component's pose on the floor: position and yaw. Nothing here
reads a component's pose from the model.

Conventions: MuJoCo's camera looks along its -z with x right and y up; OpenCV's
along +z with x right and y down; pixel centres are at integer coordinates in
OpenCV, so the principal point of a MuJoCo camera is ((w - 1) / 2, (h - 1) / 2).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from ..bundle_manifest import Manifest, Pose, thaw
from .camera import CameraModel

if TYPE_CHECKING:
    import mujoco

    from .perception import Camera

MJ_TO_CV = np.diag([1.0, -1.0, -1.0])
"""A MuJoCo camera frame's axes -> OpenCV's (and back: it is its own inverse)."""


@dataclass(frozen=True)
class TagPose:
    """One detected tag's pose in the world (the tag's frame: z out of its face)."""

    id: int
    component: str
    position: np.ndarray
    """(3,) m, centre of the tag's face."""
    rotation: np.ndarray
    """(3, 3) tag axes in the world."""
    corners: np.ndarray
    """(4, 2) pixels: top-left, top-right, bottom-right, bottom-left."""
    depth_pixels: int
    """Depth pixels the refinement used (0: the corners alone)."""


@dataclass(frozen=True)
class Estimate:
    """A component's pose on the floor, as estimated from its tags."""

    position: np.ndarray
    """(3,) m: origin of the component's frame (its placement pose) in the world."""
    yaw: float
    """rad: heading of the component's x axis about the world's +z."""
    tags: tuple[int, ...]
    """Ids of the tags it rests on."""
    tag_poses: tuple[TagPose, ...] = field(default=())

    def matrix(self) -> np.ndarray:
        """(4, 4) pose of the component's frame in the world."""
        t = np.eye(4)
        t[:3, :3] = _yaw_matrix(self.yaw)
        t[:3, 3] = self.position
        return t

    def to_world(self, xyz: Sequence[float]) -> np.ndarray:
        """(3,) world point of a point given in the component's frame (the drawings)."""
        return self.position + _yaw_matrix(self.yaw) @ np.asarray(xyz, float)


def detector() -> cv2.aruco.ArucoDetector:
    """An AprilTag 36h11 detector with sub-pixel corner refinement."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementWinSize = 3
    params.cornerRefinementMaxIterations = 50
    params.cornerRefinementMinAccuracy = 0.01
    return cv2.aruco.ArucoDetector(dictionary, params)


def refine_edges(grey: np.ndarray, corners: np.ndarray, reach: float = 2.0) -> np.ndarray:
    """Corners from the tag's four edges fitted to sub-pixel edge points.

    Corner refinement in a small window is pulled by whatever else the window holds
    (the white border is a few pixels wide, the surface beyond it another edge), and
    its error turns the tag in its plane. An edge is long: along each, the black to
    white crossing is found on short profiles across it (bilinear samples, the level
    halfway between inside and outside), a line fitted through them, and each corner
    is where two lines meet. A corner whose edges give no line keeps its place."""
    img = grey.astype(np.float32)
    centre = corners.mean(axis=0)
    offsets = np.arange(-reach, reach + 1e-9, 0.25)
    lines = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        t = (b - a) / np.linalg.norm(b - a)
        n = np.array([t[1], -t[0]])
        if n @ (a - centre) < 0:
            n = -n  # outward: from the black square into the white border
        along = a[None, :] + np.linspace(0.15, 0.85, 24)[:, None] * (b - a)[None, :]
        samples = along[:, None, :] + offsets[None, :, None] * n[None, None, :]
        maps = samples.astype(np.float32)
        profile = cv2.remap(img, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR)
        points = []
        for k in range(len(along)):
            prof = profile[k]
            inside, outside = float(prof[:3].mean()), float(prof[-3:].mean())
            if outside - inside < 20:  # no clear edge here (occluded, washed out)
                continue
            level = (inside + outside) / 2
            above = np.nonzero(prof >= level)[0]
            j = int(above[0]) if len(above) else 0
            if j == 0:
                continue
            frac = (level - prof[j - 1]) / max(float(prof[j] - prof[j - 1]), 1e-6)
            points.append(along[k] + (offsets[j - 1] + frac * 0.25) * n)
        if len(points) < 6:
            return corners
        pts = np.array(points)
        mean = pts.mean(axis=0)
        _, _, vt = np.linalg.svd(pts - mean)
        lines.append((mean, vt[0]))
    out = np.empty_like(corners)
    for i in range(4):
        # Corner i lies on edge i-1 (ending there) and edge i (starting there).
        (p1, d1), (p2, d2) = lines[i - 1], lines[i]
        m = np.column_stack([d1, -d2])
        if abs(np.linalg.det(m)) < 1e-6:
            return corners
        s = np.linalg.solve(m, p2 - p1)
        out[i] = p1 + s[0] * d1
    if np.max(np.linalg.norm(out - corners, axis=1)) > reach:
        return corners  # a line ran astray: keep the detector's corners
    return out


def detect(rgb: np.ndarray) -> dict[int, np.ndarray]:
    """Tag id -> its (4, 2) corners in pixels, for every 36h11 tag in ``rgb`` (h, w, 3)."""
    grey = cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2GRAY)
    corners, ids, _ = detector().detectMarkers(grey)
    if ids is None:
        return {}
    pairs = zip(ids.ravel(), corners, strict=True)
    return {int(i): refine_edges(grey, c.reshape(4, 2).astype(np.float64)) for i, c in pairs}


def _object_points(size: float) -> np.ndarray:
    h = size / 2
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def _fit_plane(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid and unit normal of the least-squares plane through (n, 3) ``points``."""
    centroid = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centroid, full_matrices=False)
    return centroid, vt[2]


def _depth_points(
    corners: np.ndarray, depth: np.ndarray, camera: CameraModel, scale: float = 1.15
) -> np.ndarray:
    """Camera-frame (OpenCV) points of the depth pixels on the tag's plate: its quad
    scaled about the centre by ``scale``, into the white border (the printed tag is
    1.25 times the black square) but clear of the plate's edge, where pixels straddle
    the surface behind. More pixels and a longer lever: a better normal."""
    centre = corners.mean(axis=0)
    quad = centre + scale * (corners - centre)
    mask = np.zeros(depth.shape[:2], np.uint8)
    cv2.fillConvexPoly(mask, np.round(quad * 16).astype(np.int32), 1, cv2.LINE_8, 4)
    vs, us = np.nonzero(mask)
    z = depth[vs, us].astype(np.float64)
    ok = np.isfinite(z) & (z > 0)
    us, vs, z = us[ok], vs[ok], z[ok]
    f = camera.focal
    cx, cy = camera.principal_point
    return np.column_stack([(us - cx) / f * z, (vs - cy) / f * z, z])


def _wider_normal(
    corners: np.ndarray,
    depth: np.ndarray,
    camera: CameraModel,
    centroid: np.ndarray,
    normal: np.ndarray,
    points: np.ndarray,
    scale: float = 2.5,
) -> np.ndarray:
    """The plane's normal refitted over the surface the tag lies on, around it.

    A stereo camera's depth error grows with range (about 1 cm RMS at 1 m for a
    D435): over the tag's plate alone its normal is off by about half a degree, and
    a head-on tag's yaw is that normal. The tag lies flat on its part (2 mm proud),
    so the pixels around it on the same plane, within a few noise widths of the
    tag's plane, give a lever ``scale`` times as long and many more pixels; what is
    off that plane (an edge, the floor behind) is left out."""
    resid = (points - centroid) @ normal
    sigma = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    wide = _depth_points(corners, depth, camera, scale)
    for _ in range(3):  # trimmed refits: the plane, then only what lies on it
        near = wide[np.abs((wide - centroid) @ normal) < max(3.0 * sigma, 0.004)]
        if len(near) < len(points):
            break
        c, n = _fit_plane(near)
        normal = n if n @ normal > 0 else -n
        centroid = centroid + ((c - centroid) @ normal) * normal
    return normal


def tag_in_camera(
    corners: np.ndarray,
    size: float,
    camera: CameraModel,
    depth: np.ndarray | None = None,
    min_pixels: int = 30,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The tag's rotation (3, 3) and position (3,) in the OpenCV camera frame, and how
    many depth pixels refined them."""
    ok, rvec, tvec = cv2.solvePnP(
        _object_points(size),
        corners.astype(np.float64),
        camera.matrix(),
        None,
        flags=cv2.SOLVEPNP_IPPE_SQUARE,
    )
    if not ok:
        raise ValueError("solvePnP found no pose")
    rot, _ = cv2.Rodrigues(rvec)
    pos = tvec.reshape(3)
    if depth is None:
        return rot, pos, 0
    points = _depth_points(corners, depth, camera)
    if len(points) < min_pixels:
        return rot, pos, 0
    centroid, normal = _fit_plane(points)
    normal = _wider_normal(corners, depth, camera, centroid, normal, points)
    if normal @ rot[:, 2] < 0:
        normal = -normal
    # Distance: where the ray through the tag's centre meets the depth plane.
    ray = pos / np.linalg.norm(pos)
    pos = ray * float(centroid @ normal) / float(ray @ normal)
    # Normal from the depth plane, the in-plane direction from the corners.
    x = rot[:, 0] - (rot[:, 0] @ normal) * normal
    x /= np.linalg.norm(x)
    rot = np.column_stack([x, np.cross(normal, x), normal])
    return rot, pos, len(points)


def _yaw_matrix(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _component_pose(
    tags: Sequence[TagPose], known: Mapping[int, Mapping[str, Any]]
) -> tuple[np.ndarray, float]:
    """Position and yaw of a component from its seen tags: each tag's rotation gives a
    yaw (the component only turns about +z); two or more tags also give one from the
    line between them, weighted by how far apart they are (a tag's normal and the
    baseline between tags see the same yaw error shrink with size and distance)."""
    sines, cosines = [], []
    for t in tags:
        r_comp = np.asarray(known[t.id]["pose_in_component"]["matrix"], float).reshape(3, 3)
        r = t.rotation @ r_comp.T
        sines.append(r[1, 0])
        cosines.append(r[0, 0])
    yaw = math.atan2(float(np.mean(sines)), float(np.mean(cosines)))
    if len(tags) >= 2:
        p = np.array([known[t.id]["pose_in_component"]["xyz"] for t in tags], float)
        q = np.array([t.position for t in tags])
        dp, dq = p[:, :2] - p[:, :2].mean(0), q[:, :2] - q[:, :2].mean(0)
        # 2-D Procrustes: the rotation taking the known layout onto the seen one.
        base = math.atan2(
            float(np.sum(dp[:, 0] * dq[:, 1] - dp[:, 1] * dq[:, 0])),
            float(np.sum(dp[:, 0] * dq[:, 0] + dp[:, 1] * dq[:, 1])),
        )
        spread = float(np.sqrt((dp**2).sum(1).mean()))
        size = float(np.mean([known[t.id]["size"] for t in tags]))
        # Weights ~ lever arm squared: the tag's own size for its rotation, the
        # layout's spread for the baseline.
        w_base = spread**2 / (spread**2 + size**2)
        delta = math.atan2(math.sin(base - yaw), math.cos(base - yaw))
        yaw += w_base * delta
    r = _yaw_matrix(yaw)
    origins = [
        t.position - r @ np.asarray(known[t.id]["pose_in_component"]["xyz"], float) for t in tags
    ]
    return np.mean(origins, axis=0), yaw


def localize(
    rgb: np.ndarray,
    depth: np.ndarray | None,
    camera: CameraModel,
    cam_pose_world: np.ndarray,
    fiducials: Sequence[Mapping[str, Any]],
) -> dict[str, Estimate]:
    """Component -> its estimated pose, for every component with a tag in view.

    ``rgb``: (h, w, 3) uint8; ``depth``: (h, w) metres along the optical axis (None:
    the corners alone); ``cam_pose_world``: (4, 4) pose of the MuJoCo camera frame
    (x right, y up, looking along -z) in the world; ``fiducials``: facility.json's
    ``fiducials`` (each with ``pose_in_component``). Tags the list does not know are
    ignored."""
    known = {int(f["id"]): f for f in fiducials if "pose_in_component" in f}
    seen = detect(rgb)
    r_wc = np.asarray(cam_pose_world, float)[:3, :3] @ MJ_TO_CV
    p_wc = np.asarray(cam_pose_world, float)[:3, 3]
    by_component: dict[str, list[TagPose]] = {}
    for tag_id in sorted(seen):
        info = known.get(tag_id)
        if info is None:
            continue
        rot, pos, used = tag_in_camera(seen[tag_id], float(info["size"]), camera, depth)
        pose = TagPose(
            tag_id, str(info["component"]), p_wc + r_wc @ pos, r_wc @ rot, seen[tag_id], used
        )
        by_component.setdefault(pose.component, []).append(pose)
    out = {}
    for name, tags in sorted(by_component.items()):
        position, yaw = _component_pose(tags, known)
        out[name] = Estimate(position, yaw, tuple(t.id for t in tags), tuple(tags))
    return out


def camera_pose(xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
    """(4, 4) pose from a MuJoCo camera's ``cam_xpos`` (3,) and ``cam_xmat`` (9,)."""
    t = np.eye(4)
    t[:3, :3] = np.asarray(xmat, float).reshape(3, 3)
    t[:3, 3] = xpos
    return t


def locate(camera: Camera, d: mujoco.MjData, manifest: Manifest) -> dict[str, Estimate]:
    """What the runner calls: render ``camera`` (a ``perception.Camera``, with the
    trial's sensor noise if it was given one), and localize every tagged component in
    view from facility.json's ``fiducials``. The camera's pose is the robot's own
    kinematics (the camera rides on the robot); no component pose is read."""
    rgb, depth = camera.rgbd(d)
    h, w = camera.size
    model = CameraModel.of(camera.m, camera.cam, w, h)
    pose = camera_pose(d.cam_xpos[camera.cam], d.cam_xmat[camera.cam])
    return localize(rgb, depth, model, pose, thaw(manifest.fiducials))


def localization_record(
    estimates: Mapping[str, Estimate], truths: Mapping[str, Pose]
) -> dict[str, dict[str, float]]:
    """For a trial's report only: each estimate minus its component's true pose
    (``truths``: component -> pose, the model's, or facility.json's
    ``Manifest.poses()``): ``{"position_error_m", "yaw_error_deg"}``."""
    out = {}
    for name, e in sorted(estimates.items()):
        truth = truths.get(name)
        if truth is None:
            continue
        dyaw = math.degrees(e.yaw - float(truth.yaw))
        out[name] = {
            "position_error_m": float(np.linalg.norm(e.position - np.asarray(truth.xyz))),
            "yaw_error_deg": (dyaw + 180.0) % 360.0 - 180.0,
        }
    return out
