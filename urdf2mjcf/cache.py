"""The disk cache every pass shares: one folder, one sub-folder per kind of entry.

::

    <root>/coacd/<key>.npz      convex decompositions (passes/collision/decompositions.py)
    <root>/hull_gap/<key>.json  hull gaps of collision meshes (passes/collision/decompositions.py)
    <root>/hulls/<key>.npz      convex hulls of near-convex collision meshes (the same module)
    <root>/primitive_fits/<key>.json  primitives fitted to collision meshes (the same module)
    <root>/meshes/<key>.bin     loaded, cleaned, decimated mesh files (passes/meshes/cache.py)

An entry's name is :func:`make_key` of everything it depends on, so an entry
is never stale: changed input is another key. Entries are written to a
temporary name and moved into place with ``os.replace`` (names from
``mkstemp``, unique across processes), so conversions sharing a cache only
ever see whole files; whatever cannot be decoded is a miss, computed again.
Nothing here is ever fatal: a cache that cannot be read or written only
makes a conversion slower.

Entries are untrusted data (a cache folder may be shared, or written by
someone else): the readers check every name, shape and count in an entry and
treat anything unexpected as a miss. An entry that is a symlink, or not a
regular file, or larger than ``$URDF2MJCF_MAX_CACHE_ENTRY_MB``, is a miss; a kind
sub-folder that is a symlink is neither read, written nor cleaned.

We delete only what we wrote. The root carries a ``CACHEDIR.TAG`` (the Cache
Directory Tagging spec, https://bford.info/cachedir/, with a second line
naming urdf2mjcf), written when we create the root or first write into it: a
missing or empty folder, or one with none of our kind sub-folders, or one
whose kind sub-folders hold only files named as we name them (an older
version's cache), gets it. A folder without our tag is still read and written
(entries are content-addressed) but never evicted from, and ``cache clear``
refuses it. Eviction and ``clear`` delete only ``<64 hex digits><suffix of
that kind>`` files and our stale temporary files, never following a symlink.

Size bound: ``$URDF2MJCF_CACHE_MAX_MB`` (default 2048; 0 for no bound; a value
that is not a number from 0 to 1e7 is an InputError when a cache is opened).
Reading an entry touches its modification time, so mtime orders entries by
last use; a write that takes the cache over the bound deletes the least
recently used entries down to 90 % of it (the slack spares a full scan on
every later write). Each process counts the cache once, at its first write,
and adds what it writes itself; what other processes write at the same time
is counted by the next process.
"""

from __future__ import annotations

import errno
import hashlib
import json
import logging
import os
import re
import stat
import tempfile
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from .errors import ForgeError, OutputError
from .untrusted import env_number, limit_bytes, printable

logger = logging.getLogger(__name__)

KINDS = {
    "coacd": "convex decompositions",
    "hull_gap": "hull gaps",
    "hulls": "convex hulls",
    "primitive_fits": "primitives fitted to meshes",
    "meshes": "loaded meshes",
    "certificate": "geometric figures of certificates",
}
"""Every sub-folder we write, with what it holds; ``clear`` touches nothing else."""

SUFFIXES = {
    "coacd": ".npz",
    "hull_gap": ".json",
    "hulls": ".npz",
    "primitive_fits": ".json",
    "meshes": ".bin",
    "certificate": ".json",
}
"""The file name suffix of each kind's entries (the stem is a :func:`make_key`)."""

DEFAULT_MAX_MB = 2048
MAX_MB_ENV = "URDF2MJCF_CACHE_MAX_MB"
MAX_MB = 1e7
"""The largest bound ``$URDF2MJCF_CACHE_MAX_MB`` may set (10 TB)."""

TAG_NAME = "CACHEDIR.TAG"
TAG_SIGNATURE = "Signature: 8a477f597d28d172789f06886806bc55"
TAG_TEXT = (
    f"{TAG_SIGNATURE}\n"
    "# This file is a cache directory tag created by urdf2mjcf (mjcf-forge).\n"
    "# For information about cache directory tags see https://bford.info/cachedir/\n"
)
"""Our marker: the spec's signature line, then a comment line naming urdf2mjcf (another
tool's tag does not make a folder ours)."""

_KEY = re.compile(r"[0-9a-f]{64}")
_TMP = re.compile(r"\.[0-9a-f]{16}\.[a-z0-9_]{8}\.tmp")
"""``write_entry``'s temporary files: ``.`` + 16 hex digits of the key + mkstemp's part."""
_TAG_MAX = 4096
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_READ = os.O_RDONLY | _NOFOLLOW | getattr(os, "O_NONBLOCK", 0) | _CLOEXEC
_DIR = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | _NOFOLLOW | _CLOEXEC


def default_cache_dir() -> Path:
    """``$URDF2MJCF_CACHE``, else ``$XDG_CACHE_HOME/urdf2mjcf``, else ``~/.cache/urdf2mjcf``."""
    explicit = os.environ.get("URDF2MJCF_CACHE")
    if explicit:
        return Path(explicit).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "urdf2mjcf"


def max_bytes() -> int | None:
    """The size bound from ``$URDF2MJCF_CACHE_MAX_MB``; None: no bound. An InputError
    naming the variable when it is not a number from 0 to :data:`MAX_MB`."""
    raw = os.environ.get(MAX_MB_ENV, "").strip()
    mb = env_number(MAX_MB_ENV, raw, low=0, high=MAX_MB) if raw else DEFAULT_MAX_MB
    return None if mb <= 0 else int(mb * 1024 * 1024)


def check_environment() -> None:
    """Raise the InputError of a bad cache setting now, when a run opens its cache: a
    cache write, which is never fatal, must not be where it surfaces."""
    max_bytes()
    limit_bytes("cache_entry")


def make_key(payload: Mapping[str, object]) -> str:
    """sha256 of the canonical JSON of ``payload``: the file name stem of an entry."""
    return hashlib.sha256(json.dumps(dict(payload), sort_keys=True).encode()).hexdigest()


def is_entry_name(kind: str, name: str) -> bool:
    """Whether ``name`` is named as we name ``kind``'s entries (64 hex digits, suffix)."""
    suffix = SUFFIXES.get(kind)
    return (
        suffix is not None
        and name.endswith(suffix)
        and _KEY.fullmatch(name[: -len(suffix)]) is not None
    )


def _is_temp_name(name: str) -> bool:
    return _TMP.fullmatch(name) is not None


# -- reading and writing one entry ----------------------------------------------------


def read_entry(path: Path) -> bytes | None:
    """An entry's bytes (None when absent or unusable); marks it as just used.

    Only a regular file is read, never through a symlink (the entry or its kind
    folder), at most ``$URDF2MJCF_MAX_CACHE_ENTRY_MB``; the mtime is touched on the open
    file, so nothing else's time changes."""
    if os.path.islink(path.parent):
        logger.info("cache folder %s is a symlink; not read", path.parent)
        return None
    try:
        fd = os.open(path, _READ)
    except FileNotFoundError:
        return None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            logger.info("cache entry %s is a symlink; ignored", path)
        else:
            logger.warning("cannot read cache entry %s: %s", path, exc)
        return None
    try:
        st = os.fstat(fd)
        limit = limit_bytes("cache_entry")
        if not stat.S_ISREG(st.st_mode) or st.st_size > limit:
            logger.info("cache entry %s is not a regular file within the limit; ignored", path)
            return None
        data = _read_fd(fd, limit)
        if data is None:
            logger.info("cache entry %s grew past the limit; ignored", path)
            return None
        try:  # least recently used = oldest mtime
            if os.utime in os.supports_fd:
                os.utime(fd)
            else:
                os.utime(path, follow_symlinks=False)
        except OSError:
            pass  # a read-only cache still answers
        return data
    except OSError as exc:
        logger.warning("cannot read cache entry %s: %s", path, exc)
        return None
    finally:
        os.close(fd)


def _read_fd(fd: int, limit: int) -> bytes | None:
    chunks: list[bytes] = []
    total = 0
    while True:
        chunk = os.read(fd, min(1 << 22, limit + 1 - total))
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)
        total += len(chunk)
        if total > limit:
            return None


def write_entry(folder: Path, name: str, data: bytes) -> None:
    """Temp file then ``os.replace``: readers only ever see whole files.

    Failures are logged, never raised. The root is created and marked as ours where
    that is safe (see the module doc). Afterwards the cache is held to its bound.
    """
    tmp_name = None
    try:
        if os.path.islink(folder):
            logger.warning("cache folder %s is a symlink; not writing into it", folder)
            return
        ours = _prepare_root(folder.parent)
        folder.mkdir(exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(dir=folder, prefix=f".{name[:16]}.", suffix=".tmp")
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp_name, folder / name)  # replaces a symlink there, never its target
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
    _wrote(folder.parent, len(data), ours)


# -- the marker -----------------------------------------------------------------------

_lock = threading.Lock()
_warned: set[Path] = set()
"""Roots this process has warned about (no tag of ours): once each."""


def _root_key(root: Path) -> Path:
    try:
        return root.resolve()
    except (OSError, RuntimeError):
        return root.absolute()


def is_ours(root: Path) -> bool:
    """Whether ``root`` holds our ``CACHEDIR.TAG``: a regular file (not a symlink) whose
    first line is the spec's signature and a later comment line names urdf2mjcf."""
    try:
        fd = os.open(root / TAG_NAME, _READ)
    except OSError:
        return False
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size > _TAG_MAX:
            return False
        text = os.read(fd, _TAG_MAX).decode("utf-8", "replace")
    except OSError:
        return False
    finally:
        os.close(fd)
    lines = text.splitlines()
    return (
        bool(lines)
        and lines[0] == TAG_SIGNATURE
        and any(line.startswith("#") and "urdf2mjcf" in line for line in lines[1:])
    )


def _adoptable(root: Path) -> bool:
    """Whether a root without our tag may be marked: no tag of another tool, and each
    kind sub-folder present is a real folder holding only files named as we name them
    (so: a new or empty folder, a folder of other things, or an older version's cache)."""
    if os.path.lexists(root / TAG_NAME):
        return False
    for kind in KINDS:
        try:
            st = os.lstat(root / kind)
        except FileNotFoundError:
            continue
        if not stat.S_ISDIR(st.st_mode):
            return False
        for name in os.listdir(root / kind):
            if not (is_entry_name(kind, name) or _is_temp_name(name)):
                return False
    return True


def _prepare_root(root: Path) -> bool:
    """Create ``root`` when missing; write our tag into it when it may be marked.
    Whether it is ours (checked on every write: a tag is one small read)."""
    root.mkdir(parents=True, exist_ok=True)
    if is_ours(root):
        return True
    if _adoptable(root):
        try:
            fd = os.open(root / TAG_NAME, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o644)
        except FileExistsError:
            pass  # another process marked it this instant
        else:
            with os.fdopen(fd, "w") as fh:
                fh.write(TAG_TEXT)
    return is_ours(root)


def _warn_not_ours(root: Path, consequence: str) -> None:
    key = _root_key(root)
    with _lock:
        if key in _warned:
            return
        _warned.add(key)
    logger.warning(
        "cache folder %s holds no %s of ours; %s (see 'urdf2mjcf cache info')",
        printable(str(root)),
        TAG_NAME,
        consequence,
    )


# -- the size bound -------------------------------------------------------------

_totals: dict[Path, int] = {}
"""Bytes in each cache root as this process knows it (counted at its first write)."""


def _wrote(root: Path, size: int, ours: bool) -> None:
    try:
        limit = max_bytes()
    except ForgeError as exc:  # checked when the cache was opened; changed since
        logger.warning("%s; the cache is not held to a bound", exc)
        return
    key = _root_key(root)
    if limit is not None and not ours:
        _warn_not_ours(root, "its entries are never evicted")
        return
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
    kind: str
    name: str
    size: int
    used: float


def _open_kind(root: Path, kind: str) -> int | None:
    """A descriptor of ``root/kind``; None when absent, not a folder or a symlink."""
    try:
        return os.open(root / kind, _DIR)
    except FileNotFoundError:
        return None
    except OSError as exc:
        if exc.errno in (errno.ELOOP, errno.ENOTDIR) and os.path.islink(root / kind):
            logger.warning("cache folder %s is a symlink; skipped", printable(str(root / kind)))
        return None


def _kind_files(fd: int, kind: str, temps: bool = False) -> list[_Entry]:
    """The regular files (symlinks not followed) in the kind folder ``fd`` named as we
    name its entries (and our temporary files with ``temps``)."""
    out = []
    with os.scandir(fd) as it:
        for e in it:
            if not (is_entry_name(kind, e.name) or (temps and _is_temp_name(e.name))):
                continue
            try:
                if not e.is_file(follow_symlinks=False):
                    continue
                st = e.stat(follow_symlinks=False)
            except OSError:
                continue  # deleted meanwhile by another process
            out.append(_Entry(kind, e.name, st.st_size, st.st_mtime))
    return out


def _entries(root: Path) -> list[_Entry]:
    out = []
    for kind in KINDS:
        fd = _open_kind(root, kind)
        if fd is None:
            continue
        try:
            out += _kind_files(fd, kind)
        except OSError:
            continue
        finally:
            os.close(fd)
    return out


def _unlink(root: Path, kind: str, name: str) -> None:
    """Delete ``root/kind/name`` without following a symlink at ``kind``."""
    fd = _open_kind(root, kind)
    if fd is None:
        raise FileNotFoundError(errno.ENOENT, "no such cache folder", str(root / kind))
    try:
        os.unlink(name, dir_fd=fd)
    finally:
        os.close(fd)


def _evict(root: Path, target: int) -> int:
    """Delete least recently used entries until at most ``target`` bytes remain."""
    entries = sorted(_entries(root), key=lambda e: e.used)
    total = sum(e.size for e in entries)
    removed = 0
    for e in entries:
        if total <= target:
            break
        try:
            _unlink(root, e.kind, e.name)
        except FileNotFoundError:
            pass  # another process evicted it first
        except OSError as exc:
            logger.warning("cannot evict cache entry %s/%s: %s", e.kind, e.name, exc)
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
    ours: bool = True
    """Whether the root holds our CACHEDIR.TAG (what ``clear`` and eviction need)."""

    @property
    def entries(self) -> int:
        return sum(k.entries for k in self.kinds)

    @property
    def bytes(self) -> int:
        return sum(k.bytes for k in self.kinds)


def info(root: Path) -> CacheInfo:
    """Entries by kind (named as ours, regular files), read only: any folder may be shown."""
    limit = max_bytes()  # a bad setting is the error, before anything is scanned
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
    return CacheInfo(root=root, kinds=kinds, limit=limit, ours=is_ours(root))


def not_ours_message(root: Path) -> str:
    """Why ``clear`` refuses ``root``, and what the user can do."""
    return (
        f"holds no {TAG_NAME} of ours, so it is not known to be a urdf2mjcf cache; "
        "nothing deleted. If it is one (an older version's cache), delete the folder "
        f"yourself, or create {TAG_NAME} in it whose first line is '{TAG_SIGNATURE}' "
        "and second line '# urdf2mjcf cache'"
    )


def clear(root: Path) -> tuple[int, int]:
    """Delete every entry (and stale temporary file) we wrote; (entries, bytes) deleted.

    Refuses (OutputError) a folder without our tag. Only files in our kind sub-folders
    named as we name them go (never through a symlink), and the sub-folders once
    empty: anything else a user keeps there is left alone.
    """
    if not os.path.lexists(root):
        return 0, 0
    if not is_ours(root):
        raise OutputError(not_ours_message(root), file=root)
    count = size = 0
    for kind in KINDS:
        fd = _open_kind(root, kind)
        if fd is None:
            continue
        try:
            for e in _kind_files(fd, kind, temps=True):
                try:
                    os.unlink(e.name, dir_fd=fd)
                except FileNotFoundError:
                    continue
                if is_entry_name(kind, e.name):
                    count += 1
                    size += e.size
        finally:
            os.close(fd)
        try:
            os.rmdir(root / kind)  # a symlink there is no folder: rmdir refuses it
        except OSError:
            pass  # not empty: something that is not ours
    with _lock:
        _totals.pop(_root_key(root), None)
    return count, size
