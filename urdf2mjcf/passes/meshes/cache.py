"""Disk cache of loaded mesh files, so a warm conversion decodes no mesh twice.

Decoding a DAE, OBJ or STL with trimesh, cleaning it and decimating it to
``max_faces`` is the slow part of a warm conversion (a 250k-face Collada trunk
takes seconds). The meshes pass stores its result here: the per-material
parts (with UVs), the merged mesh, the materials and PNG textures found in
the file and the notes the load gave.

An entry lives in ``<cache>/meshes/<key>.bin`` (see :mod:`urdf2mjcf.cache`
for the layout, atomic writes and the size bound). The key hashes the file's
bytes, its type and stem (material names derive from it), the URDF scale,
the face limit, :data:`CACHE_FORMAT` and the versions of the libraries that
decode and simplify. Files the decoder read besides the mesh (an OBJ's
``.mtl``, textures) are recorded in the entry with the sha256 of their bytes
(or as missing), and a hit is only a hit while they still read the same.
Anything undecodable or inconsistent is a miss: loaded again, rewritten.

An entry is one JSON header and the raw arrays after it (``.npz`` costs a
zip directory and a Python-literal header per array: a third of a warm
meshes pass).
"""

from __future__ import annotations

import json
import logging
import struct
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ... import cache as store
from ...ir import MaterialAsset, MeshData, MeshPart, TextureAsset

logger = logging.getLogger(__name__)

CACHE_FORMAT = 1
"""Bump when the stored layout or the processing in the meshes pass changes."""

_SUBDIR = "meshes"
_MAGIC = b"urdf2mjcf-mesh\0\0"
_DTYPES = ("<f8", "<i4", "<i8", "|u1")

Palette = dict[str, tuple[MaterialAsset, TextureAsset | None]]
Deps = tuple[tuple[str, str | None], ...]
"""Files the decoder asked for, by the name it used, with the sha256 of their bytes
(None: it could not read them)."""


@dataclass(frozen=True)
class Entry:
    """What loading one mesh file gave, everything but its path."""

    parts: tuple[MeshPart, ...]
    merged: MeshData
    palette: Palette
    notes: tuple[tuple[str, str], ...]
    deps: Deps = ()


@dataclass
class Stats:
    """What this process's mesh caches did (read by tests and the benchmark)."""

    hits: int = 0
    misses: int = 0
    stored: int = 0
    rejected: int = 0
    """Entries present but unusable (garbage, other format, changed side files)."""


stats = Stats()


def _versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in ("trimesh", "numpy", "pycollada", "fast-simplification", "pillow", "scipy", "lxml"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = "absent"
    return out


_VERSIONS: dict[str, str] | None = None


def cache_key(
    content_sha256: str, file_type: str, stem: str, scale: tuple[float, ...], max_faces: int
) -> str:
    """The entry name of one mesh file loaded at ``scale`` with ``max_faces``."""
    global _VERSIONS
    if _VERSIONS is None:  # importlib.metadata is slow enough to matter per mesh
        _VERSIONS = _versions()
    return store.make_key(
        {
            "format": CACHE_FORMAT,
            "kind": "mesh",
            "content": content_sha256,
            "type": file_type,
            "stem": stem,
            "scale": [float(s) for s in scale],
            "max_faces": int(max_faces),
            "versions": _VERSIONS,
        }
    )


class MeshCache:
    """Loaded meshes stored under ``root/meshes/<key>.bin``."""

    def __init__(self, root: Path):
        self.dir = Path(root) / _SUBDIR

    def path(self, key: str) -> Path:
        return self.dir / f"{key}.bin"

    def load(self, key: str, read: Callable[[str], bytes | None]) -> Entry | None:
        """The stored entry, or None (a miss) when absent, unusable, or when a side
        file, read again with ``read(name)``, no longer has the recorded bytes."""
        path = self.path(key)
        data = store.read_entry(path)
        if data is None:
            stats.misses += 1
            return None
        try:
            entry = _decode(data, key)
            for name, digest in entry.deps:
                now = read(name)
                if (None if now is None else _sha256(now)) != digest:
                    raise ValueError(f"side file '{name}' changed")
        except Exception as exc:  # whatever garbage does to the decoder: a miss, rebuilt
            logger.info("ignoring cache entry %s (%s); loading the mesh again", path, exc)
            stats.rejected += 1
            stats.misses += 1
            return None
        stats.hits += 1
        return entry

    def store(self, key: str, entry: Entry) -> None:
        """Write atomically; a failure to write is logged, never raised."""
        meta: dict = {
            "format": CACHE_FORMAT,
            "key": key,
            "parts": [],
            "materials": [],
            "textures": [],
            "notes": [list(n) for n in entry.notes],
            "deps": [list(d) for d in entry.deps],
            "merged_is_part0": False,
        }
        arrays: dict[str, np.ndarray] = {}

        def put(prefix: str, mesh: MeshData) -> None:
            arrays[f"{prefix}v"] = np.ascontiguousarray(mesh.vertices, dtype="<f8")
            small = len(mesh.vertices) < 2**31  # int32 halves the largest array; read as int64
            arrays[f"{prefix}f"] = np.ascontiguousarray(mesh.faces, dtype="<i4" if small else "<i8")
            if mesh.uv is not None:
                arrays[f"{prefix}t"] = np.ascontiguousarray(mesh.uv, dtype="<f8")

        for i, part in enumerate(entry.parts):
            put(f"p{i}", part.mesh)
            meta["parts"].append({"material": part.material, "uv": part.mesh.uv is not None})
        m, p0 = entry.merged, entry.parts[0].mesh if entry.parts else None
        if (  # one part without UVs is usually its own merged mesh: store it once
            p0 is not None
            and m.uv is None
            and p0.uv is None
            and np.array_equal(m.vertices, p0.vertices)
            and np.array_equal(m.faces, p0.faces)
        ):
            meta["merged_is_part0"] = True
        else:
            put("m", m)
        textures: dict[str, TextureAsset] = {}
        for name, (material, texture) in entry.palette.items():
            tex_name = texture.name if texture else None
            meta["materials"].append(
                [name, material.name, list(material.rgba), material.texture, tex_name]
            )
            if texture is not None:
                textures.setdefault(texture.name, texture)
        for j, texture in enumerate(textures.values()):
            meta["textures"].append([texture.name, texture.file])
            arrays[f"x{j}"] = np.frombuffer(texture.data, dtype=np.uint8)
        store.write_entry(self.dir, f"{key}.bin", _pack(meta, arrays))
        stats.stored += 1


def _sha256(data: bytes) -> str:
    import hashlib

    return hashlib.sha256(data).hexdigest()


def _pack(meta: dict, arrays: dict[str, np.ndarray]) -> bytes:
    """Magic, header length, JSON header (with each array's dtype, shape and offset),
    then the arrays, each starting on a multiple of 8 bytes."""
    layout, chunks, offset = {}, [], 0
    for name, a in arrays.items():
        raw = a.tobytes()
        layout[name] = [a.dtype.str, list(a.shape), offset, len(raw)]
        pad = -len(raw) % 8
        chunks.append(raw + bytes(pad))
        offset += len(raw) + pad
    header = json.dumps({**meta, "arrays": layout}).encode()
    header += b" " * (-len(header) % 8)
    return b"".join([_MAGIC, struct.pack("<Q", len(header)), header, *chunks])


def _unpack(data: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and read-only views of the arrays; ValueError for anything malformed."""
    if not data.startswith(_MAGIC) or len(data) < len(_MAGIC) + 8:
        raise ValueError("not a mesh cache entry")
    (size,) = struct.unpack_from("<Q", data, len(_MAGIC))
    base = len(_MAGIC) + 8 + size
    if base > len(data):
        raise ValueError("truncated header")
    meta = json.loads(data[len(_MAGIC) + 8 : base])
    arrays = {}
    for name, (dtype, shape, offset, nbytes) in meta.pop("arrays").items():
        if dtype not in _DTYPES:
            raise ValueError(f"array {name} has dtype {dtype}")
        count = int(np.prod(shape)) if shape else 1
        if nbytes != count * np.dtype(dtype).itemsize or base + offset + nbytes > len(data):
            raise ValueError(f"array {name} does not fit the entry")
        arrays[name] = np.frombuffer(data, dtype=dtype, count=count, offset=base + offset).reshape(
            shape
        )
    return meta, arrays


def _decode(data: bytes, key: str) -> Entry:
    meta, arrays = _unpack(data)
    if meta.get("format") != CACHE_FORMAT:
        raise ValueError("other cache format")
    if meta["key"] != key:
        raise ValueError("entry stored under another key")

    def get(prefix: str, uv: bool) -> MeshData:
        v = np.array(arrays[f"{prefix}v"], dtype=np.float64)  # copies: writable, as loaded
        f = np.array(arrays[f"{prefix}f"], dtype=np.int64)
        t = np.array(arrays[f"{prefix}t"], dtype=np.float64) if uv else None
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"{prefix} has bad shapes {v.shape} {f.shape}")
        if len(f) and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError(f"{prefix} has faces out of range")
        if t is not None and t.shape != (len(v), 2):
            raise ValueError(f"{prefix} has bad texture coordinates {t.shape}")
        return MeshData(v, f, t)

    parts = tuple(
        MeshPart(get(f"p{i}", bool(p["uv"])), p["material"]) for i, p in enumerate(meta["parts"])
    )
    if not parts:
        raise ValueError("no parts")
    merged = parts[0].mesh if meta["merged_is_part0"] else get("m", "mt" in arrays)
    textures = {
        name: TextureAsset(name=name, file=file, data=arrays[f"x{j}"].tobytes())
        for j, (name, file) in enumerate(meta["textures"])
    }
    palette: Palette = {}
    for name, mat_name, rgba, tex_ref, tex_name in meta["materials"]:
        rgba = tuple(float(c) for c in rgba)
        if len(rgba) != 4:
            raise ValueError(f"material {mat_name} has rgba {rgba}")
        material = MaterialAsset(name=mat_name, rgba=rgba, texture=tex_ref)  # type: ignore[arg-type]
        palette[name] = (material, textures[tex_name] if tex_name is not None else None)
    return Entry(
        parts=parts,
        merged=merged,
        palette=palette,
        notes=tuple((str(k), str(m)) for k, m in meta["notes"]),
        deps=tuple((str(n), None if d is None else str(d)) for n, d in meta["deps"]),
    )
