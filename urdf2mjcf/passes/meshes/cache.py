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

An entry is untrusted (a shared cache folder can be written by anyone who shares
it): material and texture names must be plain file names
(:func:`urdf2mjcf.untrusted.is_plain_name`), a texture's file is its name plus
``.png`` and must decode as a PNG, every array's dtype, shape and place in the
entry is checked before it is viewed, faces index their vertices, values are
finite, notes are of a known kind and short, and side files are read again only
as regular files within the mesh size limit.

An entry is one JSON header and the raw arrays after it (``.npz`` costs a
zip directory and a Python-literal header per array: a third of a warm
meshes pass).
"""

from __future__ import annotations

import io
import json
import logging
import math
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import get_args

import numpy as np

from ... import cache as store
from ... import untrusted
from ...ir import MaterialAsset, MeshData, MeshPart, NoteKind, TextureAsset

logger = logging.getLogger(__name__)

CACHE_FORMAT = 1
"""Bump when the stored layout or the processing in the meshes pass changes."""

_SUBDIR = "meshes"
_MAGIC = b"urdf2mjcf-mesh\0\0"

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
        store.check_environment()  # a bad $URDF2MJCF_CACHE_MAX_MB: an error now, not later
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
            for name, digest in entry.deps:  # names unique: each file read once
                now = read(name)
                if (None if now is None else _sha256(now)) != digest:
                    raise ValueError(f"side file '{untrusted.excerpt(name)}' changed")
        except Exception as exc:  # whatever garbage does to the decoder: a miss, rebuilt
            message = untrusted.excerpt(str(exc), 200)
            logger.info("ignoring cache entry %s (%s); loading the mesh again", path, message)
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


_ARRAY = re.compile(r"(?:p(\d{1,6})|m)([vft])|x(\d{1,6})")
_ROLE_DTYPES = {"v": ("<f8",), "t": ("<f8",), "f": ("<i4", "<i8"), "x": ("|u1",)}
_ROLE_WIDTH = {"v": 3, "f": 3, "t": 2}
_PNG = b"\x89PNG\r\n\x1a\n"
MAX_NOTES = 1000
MAX_NOTE = 4000
"""Characters of one stored note (the loader's notes are one sentence)."""
MAX_DEPS = 1000
MAX_DEP_NAME = 4096
TEXTURE_MAX_PIXELS = 2**26
"""A stored texture decodes to at most this many pixels (64 M: 8192 x 8192)."""


def _int(value: object) -> int:
    if type(value) is not int or value < 0:
        raise ValueError(f"{value!r} is not a count")
    return value


def _unpack(data: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and read-only views of the arrays; ValueError for anything malformed:
    each array's name, dtype, shape and place are checked before it is viewed."""
    if not data.startswith(_MAGIC) or len(data) < len(_MAGIC) + 8:
        raise ValueError("not a mesh cache entry")
    (size,) = struct.unpack_from("<Q", data, len(_MAGIC))
    base = len(_MAGIC) + 8 + size
    if base > len(data):
        raise ValueError("truncated header")
    meta = json.loads(data[len(_MAGIC) + 8 : base])
    if not isinstance(meta, dict) or not isinstance(meta.get("arrays"), dict):
        raise ValueError("header is not an object with arrays")
    arrays = {}
    for name, spec in meta.pop("arrays").items():
        match = _ARRAY.fullmatch(name)
        if match is None or not isinstance(spec, list) or len(spec) != 4:
            raise ValueError(f"unexpected array {name!r}")
        role = match.group(2) or "x"
        dtype, shape, offset, nbytes = spec
        if dtype not in _ROLE_DTYPES[role] or not isinstance(shape, list):
            raise ValueError(f"array {name} has dtype {dtype!r}")
        dims = [_int(d) for d in shape]
        width = _ROLE_WIDTH.get(role)  # meshes: (n, 3) or (n, 2); texture bytes: (n,)
        if len(dims) != (2 if width else 1) or (width and dims[1] != width):
            raise ValueError(f"array {name} has shape {dims}")
        count = math.prod(dims)
        start = base + _int(offset)
        if _int(nbytes) != count * np.dtype(dtype).itemsize or start + nbytes > len(data):
            raise ValueError(f"array {name} does not fit the entry")
        arrays[name] = np.frombuffer(data, dtype=dtype, count=count, offset=start).reshape(dims)
    return meta, arrays


def _name(value: object, what: str) -> str:
    """A name from the entry that becomes an MJCF name and a file name: plain only."""
    if not untrusted.is_plain_name(value, max_length=128):
        raise ValueError(f"{what} {untrusted.excerpt(repr(value))} is not a plain name")
    return value  # type: ignore[return-value]


def _mesh(arrays: dict[str, np.ndarray], prefix: str, uv: bool) -> MeshData:
    """One stored mesh: finite vertices, faces indexing them, UVs per vertex."""
    v = np.array(arrays.pop(f"{prefix}v"), dtype=np.float64)  # copies: writable, as loaded
    f = np.array(arrays.pop(f"{prefix}f"), dtype=np.int64)
    t = np.array(arrays.pop(f"{prefix}t"), dtype=np.float64) if uv else None
    if len(f) == 0 or f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"{prefix} has no faces or faces out of range")
    if not np.isfinite(v).all() or (t is not None and not np.isfinite(t).all()):
        raise ValueError(f"{prefix} has values that are not finite")
    if t is not None and len(t) != len(v):
        raise ValueError(f"{prefix} has bad texture coordinates {t.shape}")
    return MeshData(v, f, t)


_DECODED: set[str] = set()
"""sha256 of the stored textures this process has decoded (one texture is often shared
by many meshes; hashing is ten times quicker than decoding)."""


def _png(data: bytes, name: str) -> bytes:
    """A stored texture: a PNG that decodes (MuJoCo would fail on anything else: a bad
    entry must be a miss, not a failed conversion), within :data:`TEXTURE_MAX_PIXELS`."""
    from PIL import Image

    if not data.startswith(_PNG):
        raise ValueError(f"texture {name} is not a PNG")
    digest = _sha256(data)
    if digest in _DECODED:
        return data
    with Image.open(io.BytesIO(data), formats=["PNG"]) as img:
        if img.width * img.height > TEXTURE_MAX_PIXELS or img.mode not in ("RGB", "RGBA"):
            raise ValueError(f"texture {name} is {img.mode} {img.width}x{img.height}")
        img.load()
    _DECODED.add(digest)
    return data


def _decode(data: bytes, key: str) -> Entry:
    """The entry, every part checked against what the meshes pass makes (plain names,
    shapes, ranges, consistent references); ValueError (or anything the garbage makes
    the decoders raise) otherwise."""
    meta, arrays = _unpack(data)
    if type(meta.get("format")) is not int or meta["format"] != CACHE_FORMAT:
        raise ValueError("other cache format")
    if meta.get("key") != key:
        raise ValueError("entry stored under another key")
    stored = meta["parts"]
    if not isinstance(stored, list) or not 0 < len(stored) <= 100_000:
        raise ValueError("no parts")
    parts = []
    for i, p in enumerate(stored):
        material = p["material"]
        if material is not None:
            _name(material, "part material")
        if type(p["uv"]) is not bool:
            raise ValueError(f"part {i} has uv {p['uv']!r}")
        parts.append(MeshPart(_mesh(arrays, f"p{i}", p["uv"]), material))
    if type(meta["merged_is_part0"]) is not bool:
        raise ValueError("merged_is_part0 is not a bool")
    if meta["merged_is_part0"]:
        if parts[0].mesh.uv is not None:
            raise ValueError("part 0 has UVs: it is not the merged mesh")
        merged = parts[0].mesh
    else:
        merged = _mesh(arrays, "m", "mt" in arrays)
    textures: dict[str, TextureAsset] = {}
    for j, (name, file) in enumerate(meta["textures"]):
        _name(name, "texture")
        if file != f"{name}.png" or name in textures:
            raise ValueError(f"texture {name} has file {untrusted.excerpt(repr(file))}")
        png = _png(arrays.pop(f"x{j}").tobytes(), name)
        textures[name] = TextureAsset(name=name, file=file, data=png)
    if arrays:
        raise ValueError(f"arrays {sorted(arrays)} belong to nothing")
    palette: Palette = {}
    for name, mat_name, rgba, tex_ref, tex_name in meta["materials"]:
        if _name(name, "material") != mat_name or tex_ref != tex_name or name in palette:
            raise ValueError(f"material {name} is inconsistent")
        if tex_name is not None and tex_name not in textures:
            raise ValueError(f"material {name} names a texture the entry lacks")
        if not isinstance(rgba, list) or len(rgba) != 4:
            raise ValueError(f"material {name} has rgba {untrusted.excerpt(repr(rgba))}")
        colour = tuple(float(c) if type(c) in (int, float) else math.nan for c in rgba)
        if not all(0.0 <= c <= 1.0 for c in colour):  # NaN fails too
            raise ValueError(f"material {name} has rgba {untrusted.excerpt(repr(rgba))}")
        material = MaterialAsset(name=name, rgba=colour, texture=tex_ref)  # type: ignore[arg-type]
        palette[name] = (material, textures[tex_name] if tex_name is not None else None)
    if any(p.material is not None and p.material not in palette for p in parts):
        raise ValueError("a part names a material the entry lacks")
    return Entry(
        parts=tuple(parts), merged=merged, palette=palette, notes=_notes(meta), deps=_deps(meta)
    )


_NOTE_KINDS = frozenset(get_args(NoteKind))


def _notes(meta: dict) -> tuple[tuple[str, str], ...]:
    notes = meta["notes"]
    if not isinstance(notes, list) or len(notes) > MAX_NOTES:
        raise ValueError("bad notes")
    out = []
    for kind, message in notes:
        if kind not in _NOTE_KINDS or not isinstance(message, str) or len(message) > MAX_NOTE:
            raise ValueError(f"bad note {untrusted.excerpt(repr(kind))}")
        out.append((kind, message))
    return tuple(out)


def _deps(meta: dict) -> Deps:
    """Side files by the name the decoder used (relative to the mesh's folder, so
    ``..`` is allowed: ``../textures/x.png``), each read again only as a regular file."""
    deps = meta["deps"]
    if not isinstance(deps, list) or len(deps) > MAX_DEPS:
        raise ValueError("bad deps")
    out: dict[str, str | None] = {}
    for name, digest in deps:
        if (
            not isinstance(name, str)
            or name in out
            or not 0 < len(name) <= MAX_DEP_NAME
            or untrusted.printable(name) != name
            or (digest is not None and not (isinstance(digest, str) and _SHA256.fullmatch(digest)))
        ):
            raise ValueError(f"bad side file {untrusted.excerpt(repr(name))}")
        out[name] = digest
    return tuple(out.items())


_SHA256 = re.compile(r"[0-9a-f]{64}")
