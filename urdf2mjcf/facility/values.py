"""Checked values from recipe files: one error shape (file and key) for every field."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..schema import Source


def fail(path: Path | Source | None, key: str, message: str) -> InputError:
    """The error naming the file and the key (and its line, given the file's Source)."""
    if isinstance(path, Source):
        return path.fail(key, message)  # type: ignore[return-value]
    return InputError(message, file=path or "recipe", element=key)


def number(value: Any, path: Path | Source | None, key: str) -> float:
    """A finite float, or an InputError naming the file and the key."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise fail(path, key, f"'{value}' is not a number") from None
    if not math.isfinite(x):
        raise fail(path, key, f"'{value}' is not finite")
    return x
