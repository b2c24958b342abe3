"""The model's planar lidars as sensor_msgs/LaserScan, on the topic and frame the
description's Gazebo tags name (:mod:`.described`), else on ``/<link>/scan`` in the
link's frame.

The conversion makes a Gazebo ray sensor one MuJoCo rangefinder per ray, each on a
site ``<link>_ray_NNN`` of the sensor's link, looking along its +z: rays whose
directions lie in the link's xy plane, evenly spaced in angle, are one scan (angle
from the link's x axis, as Gazebo and ROS count it). MuJoCo's -1 (nothing within the
cutoff) is +inf, as REP-117 says; ``range_max`` is the cutoff.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import mujoco
import numpy as np

from . import described
from .server import Extension, Server, ros_time
from .session import Node, Publisher

_RAY = re.compile(r"^(?P<link>.+)_ray_\d+$")


@dataclass(frozen=True)
class Scan:
    link: str
    adr: np.ndarray
    """sensordata addresses, in angle order"""
    angle_min: float
    angle_increment: float
    range_max: float


def scans(m: mujoco.MjModel) -> list[Scan]:
    by_link: dict[str, list[tuple[float, int, float]]] = {}
    for i in range(m.nsensor):
        if int(m.sensor_type[i]) != int(mujoco.mjtSensor.mjSENS_RANGEFINDER):
            continue
        if int(m.sensor_objtype[i]) != int(mujoco.mjtObj.mjOBJ_SITE):
            continue
        site = int(m.sensor_objid[i])
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, site) or ""
        match = _RAY.match(name)
        if match is None:
            continue
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, m.site_quat[site])
        z = mat.reshape(3, 3)[:, 2]  # the ray in its body's frame
        if abs(z[2]) > 1e-6:
            continue  # out of the plane: not a planar scan
        angle = math.atan2(z[1], z[0])
        by_link.setdefault(match["link"], []).append(
            (angle, int(m.sensor_adr[i]), float(m.sensor_cutoff[i]))
        )
    out = []
    for link, rays in sorted(by_link.items()):
        rays.sort()
        angles = np.array([a for a, _, _ in rays])
        step = float(np.mean(np.diff(angles))) if len(rays) > 1 else 0.0
        if len(rays) > 1 and not np.allclose(np.diff(angles), step, atol=1e-6):
            continue  # unevenly spaced: no LaserScan describes it
        cutoff = max(c for _, _, c in rays) or math.inf
        out.append(Scan(link, np.array([a for _, a, _ in rays]), float(angles[0]), step, cutoff))
    return out


class Scans(Extension):
    def __init__(self, m: mujoco.MjModel) -> None:
        self.scans = scans(m)
        named = described.topics(m)
        self.named = {
            s.link: named.get(("scan", s.link), (f"/{s.link}/scan", None)) for s in self.scans
        }
        """link -> (topic, described frame or None)"""

    def open(self, node: Node, server: Server) -> None:
        self.d = server.d
        self._pubs: list[tuple[Scan, Publisher]] = [
            (s, node.publisher(self.named[s.link][0], "sensor_msgs/msg/LaserScan"))
            for s in self.scans
        ]

    def publish(self) -> None:
        stamp = ros_time(self.d.time)
        for s, pub in self._pubs:
            r = self.d.sensordata[s.adr]
            ranges = np.where(r < 0, np.inf, r)
            pub.publish(
                {
                    "header": {"stamp": stamp, "frame_id": self.named[s.link][1] or s.link},
                    "angle_min": s.angle_min,
                    "angle_max": s.angle_min + s.angle_increment * (len(s.adr) - 1),
                    "angle_increment": s.angle_increment,
                    "time_increment": 0.0,
                    "scan_time": 0.0,
                    "range_min": 0.0,
                    "range_max": s.range_max,
                    "ranges": ranges.tolist(),
                    "intensities": [],
                }
            )
