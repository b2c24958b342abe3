"""Headless rendering: choose MuJoCo's OpenGL backend before mujoco is imported.

No machine of ours has a display. ``MUJOCO_GL=egl`` renders on a GPU or on
Mesa's software EGL; where no EGL library exists, OSMesa renders on the CPU.
A value the user already set is kept.
"""

from __future__ import annotations

import ctypes.util
import os


def configure() -> str | None:
    """Set ``MUJOCO_GL`` (and PyOpenGL's platform) unless already set; returns the choice."""
    if "MUJOCO_GL" not in os.environ:
        if ctypes.util.find_library("EGL"):
            os.environ["MUJOCO_GL"] = "egl"
        elif ctypes.util.find_library("OSMesa"):
            os.environ["MUJOCO_GL"] = "osmesa"
        else:
            return None
    os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
    return os.environ["MUJOCO_GL"]
