"""The model's cameras on ROS 2 (``--camera-rate HZ``): each MuJoCo camera rendered at
that rate of simulated time, at its own resolution, to the image topic the description's
Gazebo tags name (:mod:`.described`), else ``/<camera>/image_raw`` (sensor_msgs/Image,
rgb8), and the ``camera_info`` beside it (sensor_msgs/CameraInfo: the pinhole MuJoCo
renders, as the recordings write it), in the frame the tags name, else the camera's
frame as named in the model (the conversion names an optical frame so).

Rendering runs in the simulation thread (the one that opened the renderers), between
steps: a camera costs real time, so none is rendered unless asked for.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..runner.record import camera_info
from . import described
from .server import Extension, Server, ros_time
from .session import Node, Publisher


class Cameras(Extension):
    def __init__(self, m: mujoco.MjModel, rate: float) -> None:
        self.m, self.rate = m, rate
        self.names = [
            mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_CAMERA, c) or f"camera_{c}"
            for c in range(m.ncam)
        ]
        named = described.topics(m)
        self.topics = {n: named.get(("camera", n), (f"/{n}/image_raw", None)) for n in self.names}
        """camera -> (image topic, described frame or None)"""
        self._next = 0.0

    def open(self, node: Node, server: Server) -> None:
        self.d = server.d
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._pubs: list[tuple[int, Publisher, Publisher, dict]] = []
        for c, name in enumerate(self.names):
            w, h = (int(v) for v in self.m.cam_resolution[c])
            info = camera_info(self.m, c, h, w)
            topic = self.topics[name][0]
            image = node.publisher(topic, "sensor_msgs/msg/Image")
            infos = node.publisher(described.camera_info_topic(topic), "sensor_msgs/msg/CameraInfo")
            self._pubs.append((c, image, infos, info))
            if (h, w) not in self._renderers:  # made here: the GL context costs a moment
                self._renderers[(h, w)] = mujoco.Renderer(self.m, h, w)

    def publish(self) -> None:
        t = self.d.time
        if t + 1e-9 < self._next:
            return
        self._next = max(self._next + 1.0 / self.rate, t)
        stamp = ros_time(t)
        for c, image, infos, info in self._pubs:
            w, h = info["width"], info["height"]
            r = self._renderers[(h, w)]
            r.update_scene(self.d, camera=c)
            pixels = np.ascontiguousarray(r.render())
            name = self.names[c]
            header = {"stamp": stamp, "frame_id": self.topics[name][1] or name}
            image.publish(
                {
                    "header": header,
                    "height": h,
                    "width": w,
                    "encoding": "rgb8",
                    "is_bigendian": 0,
                    "step": 3 * w,
                    "data": pixels.tobytes(),
                }
            )
            infos.publish({"header": header, **info})
