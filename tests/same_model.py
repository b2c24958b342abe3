"""Two compiled MuJoCo models compared field by field, bit for bit."""

from __future__ import annotations

from typing import Any

import numpy as np


def _fields(obj: Any) -> dict[str, Any]:
    out = {}
    for name in dir(obj):
        if name.startswith("_"):
            continue
        try:
            value = getattr(obj, name)
        except Exception:  # an accessor that needs arguments or is not readable
            continue
        if isinstance(value, np.ndarray | int | float | bytes | str) and not callable(value):
            out[name] = value
    return out


def _where_found(name: str) -> bool:
    """The asset file names MuJoCo records (``paths``, ``*_pathadr``) and the buffer
    size that holds them: absolute when it read the files from disk, as named when
    it compiled them from memory. Where a file was found, not what it holds."""
    return name in ("paths", "npaths", "nbuffer") or name.endswith("_pathadr")


def differences(a: Any, b: Any) -> list[str]:
    """The fields of two ``MjModel``s (their arrays, sizes, ``opt``, ``stat`` and the
    global visual settings) that differ in shape, type or any bit; empty when they are
    the same model. The file names MuJoCo recorded for its assets are not compared
    (:func:`_where_found`)."""
    found = []
    for part in ("", "opt", "stat", "vis.global_", "vis.headlight"):
        x, y = a, b
        for attr in filter(None, part.split(".")):
            x, y = getattr(x, attr), getattr(y, attr)
        fx, fy = _fields(x), _fields(y)
        for name in sorted(set(fx) | set(fy)):
            if not part and _where_found(name):
                continue
            label = f"{part}.{name}" if part else name
            if name not in fx or name not in fy:
                found.append(f"{label}: only in one")
                continue
            u, v = np.asarray(fx[name]), np.asarray(fy[name])
            if u.dtype != v.dtype or u.shape != v.shape or u.tobytes() != v.tobytes():
                found.append(label)
    return found
