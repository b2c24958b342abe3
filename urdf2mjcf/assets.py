"""Byte-stable asset files and content-hash names, shared by the mesh passes."""

from __future__ import annotations

import hashlib
import re
import struct

import numpy as np

from .fmt import fmt_floats
from .ir import MeshAsset, MeshData

_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def safe_stem(text: str) -> str:
    """A name fragment safe for MJCF names and file names."""
    stem = _SAFE.sub("_", text).strip("._") or "mesh"
    return stem[:48]


def content_name(stem: str, data: bytes, digest: bytes | None = None) -> str:
    """``<stem>_<10 hex digits of sha256(data)>``: identical content, identical suffix
    (``digest``: that sha256, when the caller has it)."""
    digest = digest if digest is not None else hashlib.sha256(data).digest()
    return f"{safe_stem(stem)}_{digest.hex()[:10]}"


def stl_bytes(mesh: MeshData) -> bytes:
    """Binary STL with an all-zero header, so the bytes depend on geometry alone."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    tri = v[f]  # (m, 3, 3)
    a, b = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    # np.cross and np.linalg.norm, written out: the same operations in the same order
    # (the same bytes), without their generic axis handling (a third of the time)
    n = np.empty_like(a)
    n[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    n[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    n[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    norm = np.sqrt(n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1] + n[:, 2] * n[:, 2])[:, None]
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
    rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    rec["n"] = n
    rec["v"] = tri
    return b"\0" * 80 + struct.pack("<I", len(f)) + rec.tobytes()


def obj_bytes(mesh: MeshData) -> bytes:
    """Wavefront OBJ with texture coordinates when the mesh has them."""
    lines = ["# urdf2mjcf"]
    v = iter(fmt_floats(np.asarray(mesh.vertices).reshape(-1, 3)))
    lines += [f"v {x} {y} {z}" for x, y, z in zip(v, v, v, strict=True)]
    faces = (np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3) + 1).tolist()
    if mesh.uv is not None:
        t = iter(fmt_floats(np.asarray(mesh.uv).reshape(-1, 2)))
        lines += [f"vt {u} {w}" for u, w in zip(t, t, strict=True)]
        lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in faces]
    else:
        lines += [f"f {a} {b} {c}" for a, b, c in faces]
    return ("\n".join(lines) + "\n").encode()


def mesh_asset(stem: str, mesh: MeshData) -> MeshAsset:
    """A content-named asset: OBJ when the mesh carries texture coordinates, else STL."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if mesh.uv is not None:
        data, ext = obj_bytes(mesh), "obj"  # repr() of each float: exact
    else:
        data, ext = stl_bytes(mesh), "stl"
        # what the file holds: the faces' corners (in index order), rounded to float32;
        # a mask, not np.unique: the same corners without sorting every index
        used = np.zeros(len(vertices), dtype=bool)
        used[np.asarray(mesh.faces, dtype=np.int64).ravel()] = True
        vertices = vertices[used].astype(np.float32).astype(np.float64)
    digest = hashlib.sha256(data).digest()
    name = content_name(stem, data, digest)
    return MeshAsset(name=name, file=f"{name}.{ext}", data=data, vertices=vertices, digest=digest)


def merge_assets(
    existing: tuple[MeshAsset, ...], new: list[MeshAsset]
) -> tuple[tuple[MeshAsset, ...], dict[str, str]]:
    """Add ``new`` to ``existing``, storing identical content once.

    Returns the combined assets and a map from each new asset's name to the
    name it is stored under (the first asset with the same bytes wins).
    """
    by_data = {_digest(a): a.name for a in existing}
    out = list(existing)
    renamed: dict[str, str] = {}
    names = {a.name for a in existing}
    for asset in new:
        key = _digest(asset)
        if key in by_data:
            renamed[asset.name] = by_data[key]
            continue
        if (
            asset.name in names
        ):  # same stem and hash prefix but different bytes: impossible in practice
            raise RuntimeError(f"asset name collision: {asset.name}")
        by_data[key] = asset.name
        names.add(asset.name)
        out.append(asset)
        renamed[asset.name] = asset.name
    return tuple(out), renamed


def _digest(asset: MeshAsset) -> bytes:
    return asset.digest or hashlib.sha256(asset.data).digest()
