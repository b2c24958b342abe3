"""Certificate figures kept in the cache by content.

A figure that depends only on files and numbers (a link's collision figures, the
inertia of its geometry, how deep two source shapes overlap at a pose) is stored
under :func:`~urdf2mjcf.cache.make_key` of everything it depends on, in the cache's
``certificate`` kind, as JSON. Entries are untrusted: :func:`load` returns the
parsed value and each reader checks its shape, anything unexpected a miss.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

KIND = "certificate"


def load(root: Path, key: str) -> Any:
    """The stored JSON value under ``key`` (None: absent or not JSON)."""
    from ..cache import read_entry

    data = read_entry(root / KIND / f"{key}.json")
    if data is None:
        return None
    try:
        return json.loads(data)
    except ValueError:
        return None


def store(root: Path, key: str, value: Any) -> None:
    from ..cache import write_entry

    data = json.dumps(value, sort_keys=True, allow_nan=False).encode()
    write_entry(root / KIND, f"{key}.json", data)


@lru_cache(maxsize=32)
def version_of(distribution: str) -> str | None:
    """An installed distribution's version, None when it is not installed (reading
    its metadata costs milliseconds: once per process)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(distribution)
    except PackageNotFoundError:
        return None


def library_versions() -> tuple[str | None, ...]:
    """The versions of the libraries the geometric figures come from."""
    return tuple(version_of(d) for d in ("trimesh", "numpy", "scipy", "manifold3d"))


def key(payload: Mapping[str, Any]) -> str:
    """The entry name of ``payload`` with the figures' libraries' versions in it."""
    from ..cache import make_key

    return make_key({**payload, "versions": library_versions()})


def is_number(value: Any, *, low: float = -math.inf) -> bool:
    """A finite number (not a bool) at least ``low``."""
    return (
        not isinstance(value, bool)
        and isinstance(value, int | float)
        and math.isfinite(value)
        and value >= low
    )


def is_short_text(value: Any, limit: int = 500) -> bool:
    return isinstance(value, str) and len(value) <= limit
