"""The ROS topics a converted model's description named for its sensors: the
conversion writes each as a ``<custom><text name="ros2:<kind>:<key>" data="TOPIC
[FRAME]"/>`` (``passes/emit.py``), and the server publishes there, with that header
frame, in place of the names it makes from sites and links. A model of another origin
(no such texts, or one that is not a ROS name) keeps the made names."""

from __future__ import annotations

import re

import mujoco

_TEXT = re.compile(r"ros2:(?P<kind>imu|wrench|scan|camera):(?P<key>.+)")
_NAME = re.compile(r"/[A-Za-z_][A-Za-z0-9_/]*")
_FRAME = re.compile(r"[A-Za-z_][A-Za-z0-9_/.\-]*")


def camera_info_topic(image: str) -> str:
    """A camera's CameraInfo topic beside its image topic (``/ns/cam/image_raw`` ->
    ``/ns/cam/camera_info``), as image_transport pairs them."""
    parent = image.rsplit("/", 1)[0]
    return f"{parent}/camera_info"


def topics(m: mujoco.MjModel) -> dict[tuple[str, str], tuple[str, str | None]]:
    """(kind, key) -> (topic, frame or None), from the model's custom texts."""
    out: dict[tuple[str, str], tuple[str, str | None]] = {}
    for i in range(m.ntext):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TEXT, i) or ""
        found = _TEXT.fullmatch(name)
        if found is None:
            continue
        start, size = int(m.text_adr[i]), int(m.text_size[i])
        parts = bytes(m.text_data[start : start + size]).split(b"\0")[0].decode().split()
        if not parts or not _NAME.fullmatch(parts[0]) or len(parts) > 2:
            continue
        frame = parts[1] if len(parts) == 2 and _FRAME.fullmatch(parts[1]) else None
        out[(found["kind"], found["key"])] = (parts[0], frame)
    return out
