"""The model's IMUs and force-torque sensors on ROS 2 topics.

An IMU is a site with an accelerometer and a gyro (and a framequat, its orientation in
the world) -> sensor_msgs/Imu; a force and a torque sensor on one site ->
geometry_msgs/WrenchStamped (in the site's frame, as MuJoCo measures them). Each is on
the topic and frame the description's Gazebo tags name (:mod:`.described`), else on
``/<site>/imu`` or ``/<site>/wrench`` with the site as its frame (the URDF sensor's
link, as the conversion names it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco

from . import described, keyexpr
from .server import Extension, Server, ros_time
from .session import Node, Publisher

S = mujoco.mjtSensor


@dataclass
class _Site:
    name: str
    adr: dict[int, int] = field(default_factory=dict)
    """sensor type -> sensordata address"""
    frame: str = ""
    """The messages' header frame: the described one, else the site."""


def _sites(m: mujoco.MjModel) -> dict[int, _Site]:
    out: dict[int, _Site] = {}
    wanted = {
        int(t)
        for t in (
            S.mjSENS_ACCELEROMETER,
            S.mjSENS_GYRO,
            S.mjSENS_FORCE,
            S.mjSENS_TORQUE,
            S.mjSENS_FRAMEQUAT,
        )
    }
    for i in range(m.nsensor):
        kind = int(m.sensor_type[i])
        if kind not in wanted:
            continue
        if kind == int(S.mjSENS_FRAMEQUAT) and int(m.sensor_objtype[i]) != int(
            mujoco.mjtObj.mjOBJ_SITE
        ):
            continue
        if kind == int(S.mjSENS_FRAMEQUAT) and int(m.sensor_reftype[i]) != int(
            mujoco.mjtObj.mjOBJ_UNKNOWN
        ):
            continue  # relative to another frame: not an IMU's orientation
        site = int(m.sensor_objid[i])
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, site)
        if not name:
            continue
        out.setdefault(site, _Site(name)).adr.setdefault(kind, int(m.sensor_adr[i]))
    return out


class Sensors(Extension):
    def __init__(self, m: mujoco.MjModel) -> None:
        self.m = m
        sites = _sites(m)
        A, G, Q = int(S.mjSENS_ACCELEROMETER), int(S.mjSENS_GYRO), int(S.mjSENS_FRAMEQUAT)
        F, T = int(S.mjSENS_FORCE), int(S.mjSENS_TORQUE)
        self.imus = [s for s in sites.values() if A in s.adr and G in s.adr]
        self.wrenches = [s for s in sites.values() if F in s.adr and T in s.adr]
        self._keys = (A, G, Q, F, T)
        named = described.topics(m)
        self.topics: dict[str, str] = {}
        """site -> topic, per kind prefix (``imu:<site>``, ``wrench:<site>``)"""
        for kind, group in (("imu", self.imus), ("wrench", self.wrenches)):
            for s in group:
                topic, frame = named.get((kind, s.name), (f"/{s.name}/{kind}", None))
                self.topics[f"{kind}:{s.name}"] = topic
                s.frame = frame or s.name

    def open(self, node: Node, server: Server) -> None:
        self.d = server.d
        imu, wrench = "sensor_msgs/msg/Imu", "geometry_msgs/msg/WrenchStamped"
        self._imu: list[tuple[_Site, Publisher]] = [
            (s, node.publisher(self.topics[f"imu:{s.name}"], imu, keyexpr.DEFAULT))
            for s in self.imus
        ]
        self._ft: list[tuple[_Site, Publisher]] = [
            (s, node.publisher(self.topics[f"wrench:{s.name}"], wrench)) for s in self.wrenches
        ]

    def publish(self) -> None:
        A, G, Q, F, T = self._keys
        sd = self.d.sensordata
        stamp = ros_time(self.d.time)

        def vec(adr: int) -> dict[str, float]:
            return {"x": float(sd[adr]), "y": float(sd[adr + 1]), "z": float(sd[adr + 2])}

        for s, pub in self._imu:
            msg = {
                "header": {"stamp": stamp, "frame_id": s.frame},
                "angular_velocity": vec(s.adr[G]),
                "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": vec(s.adr[A]),
                "linear_acceleration_covariance": [0.0] * 9,
            }
            if Q in s.adr:
                q = sd[s.adr[Q] : s.adr[Q] + 4]
                msg["orientation"] = {
                    "x": float(q[1]),
                    "y": float(q[2]),
                    "z": float(q[3]),
                    "w": float(q[0]),
                }
                msg["orientation_covariance"] = [0.0] * 9
            else:  # REP-145: no orientation estimate
                msg["orientation"] = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
                msg["orientation_covariance"] = [-1.0] + [0.0] * 8
            pub.publish(msg)
        for s, pub in self._ft:
            pub.publish(
                {
                    "header": {"stamp": stamp, "frame_id": s.frame},
                    "wrench": {"force": vec(s.adr[F]), "torque": vec(s.adr[T])},
                }
            )
