"""The disk cache every pass shares: one folder, one sub-folder per kind of entry.

::

    <root>/coacd/<key>.npz      convex decompositions (passes/collision/decompositions.py)
    <root>/hull_gap/<key>.json  hull gaps of collision meshes (passes/collision/decompositions.py)
    <root>/hulls/<key>.npz      convex hulls of near-convex collision meshes (the same module)
    <root>/meshes/<key>.bin     loaded, cleaned, decimated mesh files (passes/meshes/cache.py)

An entry's name is :func:`make_key` of everything it depends on, so an entry
is never stale: changed input is another key. Entries are written to a
temporary name and moved into place with ``os.replace`` (names from
``mkstemp``, unique across processes), so conversions sharing a cache only
ever see whole files; whatever cannot be decoded is a miss, computed again.
Nothing here is ever fatal: a cache that cannot be read or written only
makes a conversion slower.

Size bound: ``$URDF2MJCF_CACHE_MAX_MB`` (default 2048; 0 for no bound).
Reading an entry touches its modification time, so mtime orders entries by
last use; a write that takes the cache over the bound deletes the least
recently used entries down to 90 % of it (the slack spares a full scan on
every later write). Each process counts the cache once, at its first write,
and adds what it writes itself; what other processes write at the same time
is counted by the next process.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

logger = logging.getLogger(__name__)

KINDS = {
    "coacd": "convex decompositions",
    "hull_gap": "hull gaps",
    "hulls": "convex hulls",
    "meshes": "loaded meshes",
}
"""Every sub-folder we write, with what it holds; ``clear`` touches nothing else."""

DEFAULT_MAX_MB = 2048
_SUFFIXES = (".npz", ".json", ".bin")
_TMP_SUFFIX = ".tmp"


def default_cache_dir() -> Path:
    """``$URDF2MJCF_CACHE``, else ``$XDG_CACHE_HOME/urdf2mjcf``, else ``~/.cache/urdf2mjcf``."""
    explicit = os.environ.get("URDF2MJCF_CACHE")
    if explicit:
        return Path(explicit).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "urdf2mjcf"


def max_bytes() -> int | None:
    """The size bound from ``$URDF2MJCF_CACHE_MAX_MB``; None: no bound."""
    raw = os.environ.get("URDF2MJCF_CACHE_MAX_MB", "").strip()
    mb: float = DEFAULT_MAX_MB
    if raw:
        try:
            mb = float(raw)
        except ValueError:
            logger.warning(
                "URDF2MJCF_CACHE_MAX_MB=%r is not a number; using %d", raw, DEFAULT_MAX_MB
            )
    return None if mb <= 0 else int(mb * 1024 * 1024)


def make_key(payload: Mapping[str, object]) -> str:
    """sha256 of the canonical JSON of ``payload``: the file name stem of an entry."""
    return hashlib.sha256(json.dumps(dict(payload), sort_keys=True).encode()).hexdigest()


def read_entry(path: Path) -> bytes | None:
    """An entry's bytes (None when absent or unreadable); marks it as just used."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        logger.warning("cannot read cache entry %s: %s", path, exc)
        return None
    try:
        os.utime(path)  # least recently used = oldest mtime
    except OSError:
        pass  # a read-only cache still answers
    return data


def write_entry(folder: Path, name: str, data: bytes) -> None:
    """Temp file then ``os.replace``: readers only ever see whole files.

    Failures are logged, never raised. Afterwards the cache is held to its bound.
    """
    tmp_name = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(dir=folder, prefix=f".{name[:16]}.", suffix=_TMP_SUFFIX)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp_name, folder / name)
        tmp_name = None
    except OSError as exc:
        logger.warning("cannot write cache entry in %s: %s", folder, exc)
        return
    finally:
        if tmp_name is not None:
            try:
                os.unlink(tmp_name)
            except OSError:
                pass
    _wrote(folder.parent, len(data))


# -- the size bound -------------------------------------------------------------

_lock = threading.Lock()
_totals: dict[Path, int] = {}
"""Bytes in each cache root as this process knows it (counted at its first write)."""


def _wrote(root: Path, size: int) -> None:
    limit = max_bytes()
    key = root.resolve()
    with _lock:
        if limit is None:  # unbounded: count again once a bound is set
            _totals.pop(key, None)
            return
        if key not in _totals:
            _totals[key] = sum(e.size for e in _entries(root))  # includes what we just wrote
        else:
            _totals[key] += size
        if _totals[key] > limit:
            _totals[key] = _evict(root, int(limit * 0.9))


@dataclass(frozen=True)
class _Entry:
    path: Path
    kind: str
    size: int
    used: float


def _entries(root: Path) -> list[_Entry]:
    out = []
    for kind in KINDS:
        try:
            with os.scandir(root / kind) as it:
                for e in it:
                    if not e.name.endswith(_SUFFIXES) or e.name.startswith("."):
                        continue
                    try:
                        st = e.stat()
                    except OSError:
                        continue  # deleted meanwhile by another process
                    out.append(_Entry(Path(e.path), kind, st.st_size, st.st_mtime))
        except OSError:
            continue  # no such kind yet
    return out


def _evict(root: Path, target: int) -> int:
    """Delete least recently used entries until at most ``target`` bytes remain."""
    entries = sorted(_entries(root), key=lambda e: e.used)
    total = sum(e.size for e in entries)
    removed = 0
    for e in entries:
        if total <= target:
            break
        try:
            e.path.unlink()
        except FileNotFoundError:
            pass  # another process evicted it first
        except OSError as exc:
            logger.warning("cannot evict cache entry %s: %s", e.path, exc)
            continue
        total -= e.size
        removed += 1
    if removed:
        logger.info("cache %s: evicted %d least recently used entries", root, removed)
    return total


# -- what `urdf2mjcf cache info|clear` show -------------------------------------


@dataclass(frozen=True)
class KindInfo:
    kind: str
    description: str
    entries: int
    bytes: int


@dataclass(frozen=True)
class CacheInfo:
    root: Path
    kinds: tuple[KindInfo, ...]
    limit: int | None

    @property
    def entries(self) -> int:
        return sum(k.entries for k in self.kinds)

    @property
    def bytes(self) -> int:
        return sum(k.bytes for k in self.kinds)


def info(root: Path) -> CacheInfo:
    entries = _entries(root)
    kinds = tuple(
        KindInfo(
            kind,
            description,
            sum(1 for e in entries if e.kind == kind),
            sum(e.size for e in entries if e.kind == kind),
        )
        for kind, description in KINDS.items()
    )
    return CacheInfo(root=root, kinds=kinds, limit=max_bytes())


def clear(root: Path) -> tuple[int, int]:
    """Delete every entry (and stale temporary file) we wrote; (entries, bytes) deleted.

    Only our sub-folders' ``.npz``/``.json``/``.tmp`` files go, and the sub-folders
    once empty: anything else a user keeps there is left alone.
    """
    count = size = 0
    for kind in KINDS:
        folder = root / kind
        try:
            names = os.listdir(folder)
        except OSError:
            continue
        for name in names:
            if not name.endswith((*_SUFFIXES, _TMP_SUFFIX)):
                continue
            path = folder / name
            try:
                n = path.stat().st_size
                path.unlink()
            except FileNotFoundError:
                continue
            if not name.startswith("."):
                count += 1
                size += n
        try:
            folder.rmdir()
        except OSError:
            pass  # not empty: something that is not ours
    with _lock:
        _totals.pop(root.resolve(), None)
    return count, size
