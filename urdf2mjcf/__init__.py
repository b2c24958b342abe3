"""urdf2mjcf: compile URDF and xacro robot descriptions into MuJoCo MJCF."""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["ConvertOptions", "ConversionError", "Report", "build", "convert", "make_options"]

_EXPORTS = {
    "ConvertOptions": "api",
    "build": "api",
    "convert": "api",
    "make_options": "api",
    "ConversionError": "errors",
    "Report": "report",
}


def __getattr__(name: str) -> object:
    # Lazy: importing the package must not import mujoco (its OpenGL backend is
    # chosen at import time; see urdf2mjcf.headless) or the heavy mesh stack.
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module 'urdf2mjcf' has no attribute {name!r}")
