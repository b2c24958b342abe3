"""Headless rendering: choose MuJoCo's OpenGL backend before mujoco is imported.

No machine of ours has a display. ``MUJOCO_GL=egl`` renders on a GPU or on
Mesa's software EGL; where no EGL library exists, OSMesa renders on the CPU.
A value the user already set is kept.
"""

from __future__ import annotations

import ctypes.util
import functools
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


@functools.cache
def gl_context_error() -> str | None:
    """Why no offscreen OpenGL context can be made here (MuJoCo's backends raise ImportError
    or RuntimeError), or None when one can: the one check tests skip on."""
    configure()
    import mujoco

    gl_context = getattr(mujoco, "GLContext", None)
    if gl_context is None:
        return f"MuJoCo loaded no OpenGL backend (MUJOCO_GL={os.environ.get('MUJOCO_GL')})"
    try:
        ctx = gl_context(8, 8)
        ctx.make_current()
        ctx.free()
    except (ImportError, RuntimeError) as exc:
        return f"{type(exc).__name__}: {exc}"
    return None
