"""Disk cache of convex decompositions, so a second conversion decomposes nothing.

It also keeps hull gaps (each with its hull's figures, :class:`~.convexity.HullFigures`),
convex hulls and primitive-fit candidates (JSON, checked field by field on reading), so
that a warm conversion neither measures nor fits.

One ``.npz`` file per decomposition, named by a key that hashes everything the
result depends on: the mesh (its content hash and the exact arrays handed to
CoACD), the CoACD parameters, the versions of coacd, trimesh and numpy, and
:data:`CACHE_FORMAT`. Reading and writing go through :mod:`urdf2mjcf.cache`,
shared with the mesh cache: files are written to a temporary name and moved
into place with ``os.replace``, so concurrent conversions sharing one cache
only ever see whole files, and the folder is held to its size bound. An entry
that is truncated, garbage or inconsistent is a miss: the result is computed
again and the entry rewritten. Nothing here is ever fatal.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import logging
import math
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...cache import check_environment, default_cache_dir, make_key, read_entry, write_entry
from ...ir import MeshData
from ...untrusted import excerpt
from .convexity import HullFigures
from .primitives import Candidate, Deviation, Fit

__all__ = ["DecompositionCache", "array_digest", "cache_key", "default_cache_dir"]

logger = logging.getLogger(__name__)

CACHE_FORMAT = 1
"""Bump when the stored layout or the processing around CoACD changes."""

_SUBDIR = "coacd"
_GAP_SUBDIR = "hull_gap"
_HULL_SUBDIR = "hulls"
_FIT_SUBDIR = "primitive_fits"

_HULL_FIGURES = {f.name for f in dataclasses.fields(HullFigures)}

_FIT_SIZES = {"sphere": 1, "capsule": 2, "cylinder": 2, "box": 3}
"""Primitive type -> the number of MuJoCo half sizes it takes."""
MAX_CANDIDATES = 1_000
"""More candidates (and primitives in one candidate) than any fit proposes."""


@functools.cache  # importlib.metadata reads the disk: once per process, not once per mesh
def _versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    import trimesh

    try:
        coacd_version = version("coacd")
    except PackageNotFoundError:  # pragma: no cover - coacd is a dependency
        coacd_version = "unknown"
    return {"coacd": coacd_version, "trimesh": trimesh.__version__, "numpy": np.__version__}


def array_digest(vertices: np.ndarray, faces: np.ndarray) -> str:
    """sha256 of the exact float64 vertices and int64 faces (shape included)."""
    h = hashlib.sha256()
    for a, dtype in ((vertices, "<f8"), (faces, "<i8")):
        a = np.ascontiguousarray(a, dtype=dtype)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def cache_key(mesh_sha256: str, data_sha256: str, params: Mapping[str, object]) -> str:
    """The file name stem of one decomposition: sha256 of everything it depends on."""
    payload = {
        "format": CACHE_FORMAT,
        "mesh": mesh_sha256,
        "data": data_sha256,
        "params": dict(params),
        "versions": _versions(),
    }
    return make_key(payload)


class DecompositionCache:
    """Convex parts stored under ``root/coacd/<key>.npz``."""

    def __init__(self, root: Path):
        check_environment()  # a bad $URDF2MJCF_CACHE_MAX_MB: an error now, not later
        self.dir = Path(root) / _SUBDIR

    def path(self, key: str) -> Path:
        return self.dir / f"{key}.npz"

    def load(self, key: str) -> list[MeshData] | None:
        """The stored parts, or None when absent, unreadable or inconsistent."""
        return self._load(self.path(key), key)

    def load_hull(self, key: str) -> MeshData | None:
        """A stored convex hull (a warm run then needs neither trimesh nor qhull)."""
        parts = self._load(self.dir.parent / _HULL_SUBDIR / f"{key}.npz", key)
        return parts[0] if parts is not None and len(parts) == 1 else None

    def store_hull(self, key: str, hull: MeshData) -> None:
        write_entry(self.dir.parent / _HULL_SUBDIR, f"{key}.npz", _encode(key, [hull]))

    def _load(self, path: Path, key: str) -> list[MeshData] | None:
        data = read_entry(path)
        if data is None:
            return None
        try:
            return _decode(data, key)
        except Exception as exc:  # whatever garbage does to np.load: a miss, rebuilt
            message = excerpt(str(exc), 200)
            logger.info("ignoring corrupt cache entry %s (%s); computing it again", path, message)
            return None

    def store(self, key: str, parts: list[MeshData]) -> None:
        """Write atomically; a failure to write is logged, never raised."""
        write_entry(self.dir, f"{key}.npz", _encode(key, parts))

    def load_gap(self, key: str) -> float | None:
        """A stored hull gap (the convexity test is the slow part of a warm run)."""
        raw = read_entry(self.dir.parent / _GAP_SUBDIR / f"{key}.json")
        if raw is None:
            return None
        try:
            data = json.loads(raw)
        except Exception:  # truncated or garbage: a miss, rebuilt
            return None
        if not isinstance(data, dict) or data.get("key") != key:
            return None
        gap = data.get("gap")
        if not isinstance(gap, int | float) or isinstance(gap, bool):
            return None
        try:
            value = float(gap)
        except OverflowError:  # an int of a thousand digits
            return None
        return value if math.isfinite(value) and value >= 0.0 else None

    def load_fits(self, key: str) -> list[Candidate] | None:
        """Stored primitive-fit candidates, or None when absent or not exactly what
        :meth:`store_fits` writes (types, counts, finite numbers, positive sizes)."""
        raw = read_entry(self.dir.parent / _FIT_SUBDIR / f"{key}.json")
        if raw is None:
            return None
        try:
            return _decode_fits(json.loads(raw), key)
        except Exception as exc:  # truncated, garbage or inconsistent: a miss, refitted
            message = excerpt(str(exc), 200)
            logger.info("ignoring corrupt primitive-fit entry %s (%s); fitting again", key, message)
            return None

    def store_fits(self, key: str, cands: list[Candidate]) -> None:
        entry = {
            "key": key,
            "candidates": [
                {
                    "fits": [
                        {"type": f.type, "pos": f.pos, "quat": f.quat, "size": f.size}
                        for f in c.fits
                    ],
                    "deviation": dataclasses.asdict(c.deviation),
                    "cost": c.cost,
                }
                for c in cands
            ],
        }
        write_entry(self.dir.parent / _FIT_SUBDIR, f"{key}.json", json.dumps(entry).encode())

    def load_hull_figures(self, key: str) -> HullFigures | None:
        """The hull's figures stored beside its hull gap (:meth:`store_gap`), or None
        when absent or not three numbers (the ratio may be null: an open mesh)."""
        raw = read_entry(self.dir.parent / _GAP_SUBDIR / f"{key}.json")
        if raw is None:
            return None
        try:
            data = json.loads(raw)
            if not isinstance(data, dict) or data.get("key") != key:
                return None
            hull = data.get("hull")
            if not isinstance(hull, dict) or set(hull) != _HULL_FIGURES:
                return None
            ratio = hull["volume_ratio"]
            figures = HullFigures(
                volume_ratio=None if ratio is None else _finite(ratio, "volume ratio"),
                hausdorff_m=_finite(hull["hausdorff_m"], "hausdorff"),
                diagonal_m=_finite(hull["diagonal_m"], "diagonal"),
            )
        except Exception:  # truncated, garbage or inconsistent: a miss, measured again
            return None
        values = (figures.hausdorff_m, figures.diagonal_m, figures.volume_ratio or 0.0)
        return figures if min(values) >= 0.0 else None

    def store_gap(self, key: str, gap: float, hull: HullFigures | None = None) -> None:
        """The hull gap and, where measured, the hull's figures (one entry a mesh)."""
        entry: dict[str, Any] = {"key": key, "gap": gap}
        if hull is not None:
            entry["hull"] = dataclasses.asdict(hull)
        write_entry(self.dir.parent / _GAP_SUBDIR, f"{key}.json", json.dumps(entry).encode())


def _finite(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{what} is not a number")
    x = float(value)  # OverflowError for an int of a thousand digits: a miss too
    if not math.isfinite(x):
        raise ValueError(f"{what} is not finite")
    return x


def _numbers(value: Any, count: int, what: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != count:
        raise ValueError(f"{what} is not {count} numbers")
    return tuple(_finite(v, what) for v in value)


def _decode_fits(data: Any, key: str) -> list[Candidate]:
    """The candidates of a primitive-fit entry; ValueError unless it is exactly what
    :meth:`DecompositionCache.store_fits` writes."""
    if not isinstance(data, dict) or set(data) != {"key", "candidates"} or data["key"] != key:
        raise ValueError("not an entry of this key")
    raw = data["candidates"]
    if not isinstance(raw, list) or len(raw) > MAX_CANDIDATES:
        raise ValueError("candidates is not a list of the expected length")
    out = []
    for i, c in enumerate(raw):
        if not isinstance(c, dict) or set(c) != {"fits", "deviation", "cost"}:
            raise ValueError(f"candidate {i} has other keys")
        fits_raw = c["fits"]
        if not isinstance(fits_raw, list) or not 1 <= len(fits_raw) <= MAX_CANDIDATES:
            raise ValueError(f"candidate {i} has no fits")
        fits = []
        for f in fits_raw:
            if not isinstance(f, dict) or set(f) != {"type", "pos", "quat", "size"}:
                raise ValueError(f"candidate {i} has a malformed fit")
            kind = f["type"]
            if not isinstance(kind, str) or kind not in _FIT_SIZES:
                raise ValueError(f"candidate {i} has an unknown type")
            quat = _numbers(f["quat"], 4, "quat")
            size = _numbers(f["size"], _FIT_SIZES[kind], "size")
            if not math.isclose(math.hypot(*quat), 1.0, abs_tol=1e-6) or min(size) <= 0:
                raise ValueError(f"candidate {i} has a bad rotation or size")
            pos = _numbers(f["pos"], 3, "pos")
            fits.append(Fit(type=kind, pos=pos, quat=quat, size=size))  # type: ignore[arg-type]
        dev = c["deviation"]
        names = ("hausdorff_m", "uncovered_m", "volume_ratio")
        if not isinstance(dev, dict) or set(dev) != set(names):
            raise ValueError(f"candidate {i} has a malformed deviation")
        values = [_finite(dev[n], n) for n in names]
        if min(values) < 0:
            raise ValueError(f"candidate {i} has a negative deviation")
        deviation = Deviation(hausdorff_m=values[0], uncovered_m=values[1], volume_ratio=values[2])
        cost = _finite(c["cost"], "cost")
        out.append(Candidate(fits=tuple(fits), deviation=deviation, cost=cost))
    return out


def _encode(key: str, parts: list[MeshData]) -> bytes:
    buf = io.BytesIO()
    arrays: dict[str, np.ndarray] = {
        "format": np.array([CACHE_FORMAT], dtype="<i8"),
        "key": np.frombuffer(key.encode(), dtype=np.uint8),
        "count": np.array([len(parts)], dtype="<i8"),
    }
    for i, part in enumerate(parts):
        arrays[f"v{i}"] = np.ascontiguousarray(part.vertices, dtype="<f8")
        arrays[f"f{i}"] = np.ascontiguousarray(part.faces, dtype="<i8")
    np.savez(buf, **arrays)  # type: ignore[arg-type]  # stub confuses **kwds with allow_pickle
    return buf.getvalue()


MAX_PARTS = 10_000
"""More convex parts than any decomposition makes (CoACD's default limit is far lower)."""


def _members(data: bytes, count_limit: int) -> set[str]:
    """The array names of an ``.npz`` entry; ValueError unless it is a zip whose members
    are all stored uncompressed (as ``np.savez`` writes them), so that what ``np.load``
    reads is bounded by the entry's own size (a deflated member could expand a
    thousandfold)."""
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        infos = archive.infolist()
        if len(infos) > count_limit:
            raise ValueError(f"{len(infos)} members")
        names = set()
        for info in infos:
            if info.compress_type != zipfile.ZIP_STORED or info.file_size > len(data):
                raise ValueError(f"member {info.filename!r} is compressed or too large")
            if not info.filename.endswith(".npy"):
                raise ValueError(f"member {info.filename!r} is not an array")
            names.add(info.filename[:-4])
    return names


def _array(npz: Any, name: str, dtype: str, ndim: int) -> np.ndarray:
    a = npz[name]
    if a.dtype.str != dtype or a.ndim != ndim:
        raise ValueError(f"{name} is {a.dtype.str} with {a.ndim} dimensions")
    return a


def _decode(data: bytes, key: str) -> list[MeshData]:
    """The parts, checked: exactly the arrays we write, each of its dtype and shape,
    finite vertices, faces in range. ValueError (or whatever garbage makes ``np.load``
    raise; never a pickle, ``allow_pickle=False``) otherwise."""
    names = _members(data, 3 + 2 * MAX_PARTS)
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        fmt = _array(npz, "format", "<i8", 1)
        if fmt.shape != (1,) or int(fmt[0]) != CACHE_FORMAT:
            raise ValueError("other cache format")
        if _array(npz, "key", "|u1", 1).tobytes() != key.encode():
            raise ValueError("entry stored under another key")
        count_array = _array(npz, "count", "<i8", 1)
        count = int(count_array[0]) if count_array.shape == (1,) else 0
        if not 1 <= count <= MAX_PARTS:
            raise ValueError("no parts")
        expected = {"format", "key", "count"} | {f"{a}{i}" for i in range(count) for a in "vf"}
        if names != expected:
            raise ValueError("arrays other than the parts")
        parts = []
        for i in range(count):
            v = np.array(_array(npz, f"v{i}", "<f8", 2), dtype=np.float64)
            f = np.array(_array(npz, f"f{i}", "<i8", 2), dtype=np.int64)
            if v.shape[1] != 3 or f.shape[1] != 3 or len(f) == 0:
                raise ValueError(f"part {i} has bad shapes {v.shape} {f.shape}")
            if not np.all(np.isfinite(v)) or f.min() < 0 or f.max() >= len(v):
                raise ValueError(f"part {i} has invalid values")
            parts.append(MeshData(vertices=v, faces=f))
    return parts
