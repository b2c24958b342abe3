"""Meshes pass: load every mesh file once and turn visuals into MuJoCo geoms.

Fills ``Model.meshes`` (for visuals and collisions alike), the visual geoms
and the mesh, texture and material assets they use.

Colour precedence, as RViz does it: a part's own material from the mesh file
(a DAE or OBJ diffuse colour or texture, or a PLY's vertex colours) wins; a
part without one takes the URDF ``<material>`` (colour and texture); with
neither the geom gets nothing and emit's default class gives the grey. Every
colour becomes a :class:`MaterialAsset`; this pass never sets ``Geom.rgba``.

Collada: ``<unit meter=...>`` of the document is applied and ``<up_axis>`` is
ignored, which is what RViz (assimp, skipping the root node's up-axis
rotation, then rescaling by the unit) and Gazebo show. trimesh applies the
node transforms but only records the unit in metadata, so we scale here.

OBJ texture coordinates are written as read (v up, as in the file): MuJoCo
flips v itself when it loads an OBJ, so images appear the right way up.

Flat or tiny meshes (a textured quad, a thin decal) are kept: MuJoCo 4.0
rejects them ("mesh volume is too small") even on massless visual geoms
unless the ``<mesh>`` asset has ``inertia="shell"``, which emit must write.

What loading a file gives (parts, merged mesh, its materials and textures,
notes) is kept in the disk cache (:mod:`.cache`), keyed by the
file's bytes and the options, so a warm conversion decodes no mesh twice.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import logging
import os
import stat
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ... import assets, untrusted
from ...cache import default_cache_dir
from ...errors import MeshError
from ...geometry import primitive_geom
from ...ir import (
    RGBA,
    Collision,
    Geom,
    LoadedMesh,
    Material,
    MaterialAsset,
    MeshAsset,
    MeshData,
    MeshPart,
    MeshRef,
    Model,
    Note,
    TextureAsset,
    Vec3,
    Visual,
)
from ...transforms import quat_from_rpy, vec3
from . import cache as mesh_cache

log = logging.getLogger(__name__)

FORMATS = (".stl", ".obj", ".dae", ".ply", ".glb", ".gltf")
LFS_MAGIC = b"version https://git-lfs.github.com/spec/v1"


@dataclass(frozen=True)
class MeshConfig:
    max_faces: int = 200_000
    """MuJoCo's STL reader refuses more faces than this; larger meshes are decimated."""
    strict_visual: bool = False
    """A missing or unusable mesh (visual or collision) is an error, not a warning that
    drops the geom (``--strict``)."""
    cache_dir: Path | None = None
    """None: the default cache folder (see :func:`urdf2mjcf.cache.default_cache_dir`)."""
    use_cache: bool = True
    """Read and write loaded meshes in the disk cache."""


class _Unusable(Exception):
    """A mesh file that cannot be used; the message says why."""

    def __init__(self, message: str, *, fatal: bool = False):
        super().__init__(message)
        self.fatal = fatal
        """An error even for a visual (a Git LFS pointer means a broken checkout)."""


Key = tuple[Path, Vec3]
Palette = dict[str, tuple[MaterialAsset, TextureAsset | None]]
"""Materials found in mesh files, by asset name, with their textures."""


def run(model: Model, cfg: MeshConfig) -> Model:
    robot = model.robot
    meshes: dict[Key, LoadedMesh] = dict(model.meshes)
    failed: dict[Key, _Unusable] = {}
    palette: Palette = {}
    notes = list(model.notes)
    cache = _open_cache(cfg)

    # Load in document order: link by link, visuals then collisions.
    kept_links, changed = [], False
    for link in robot.links:
        dropped: list[Collision] = []
        for role, items in (("visual", link.visuals), ("collision", link.collisions)):
            for item in items:
                ref = item.geometry
                if not isinstance(ref, MeshRef):
                    continue
                where = f"link '{link.name}' {role} mesh '{ref.filename}'"
                problem = _ensure_loaded(ref, cfg, cache, meshes, failed, palette, notes)
                if problem is None:
                    continue
                if cfg.strict_visual or problem.fatal:
                    raise MeshError(str(problem), file=robot.source, element=where)
                # missing, ambiguous or undecodable: the robot without it, as RViz shows it
                notes.append(Note("warning", where, f"{problem}; {role} dropped"))
                log.info("%s: %s; %s dropped", where, problem, role)
                if role == "collision":
                    dropped.append(item)  # type: ignore[arg-type]
        if dropped:
            left = tuple(c for c in link.collisions if not any(c is d for d in dropped))
            if not left:
                notes.append(
                    Note(
                        "warning",
                        f"link '{link.name}'",
                        "has no collision geometry left: its collision meshes were dropped",
                    )
                )
            link, changed = dataclasses.replace(link, collisions=left), True
        kept_links.append(link)
    if changed:
        robot = dataclasses.replace(robot, links=tuple(kept_links))

    out = _Assets(
        {m.name: m for m in model.materials},
        {t.name: t for t in model.textures},
    )
    ours: dict[str, list[Geom]] = {}
    for link in robot.links:
        for visual in link.visuals:
            geometry = visual.geometry
            if isinstance(geometry, MeshRef) and (geometry.path, geometry.scale) not in meshes:
                continue  # dropped above
            urdf_mat = _urdf_material(visual.material, notes, link.name, robot.source)
            geoms = ours.setdefault(link.name, [])
            if isinstance(geometry, MeshRef):
                loaded = meshes[(geometry.path, geometry.scale)]  # type: ignore[index]
                geoms += _mesh_geoms(visual, loaded, urdf_mat, palette, out)
            else:
                material = out.use(*urdf_mat[0]) if urdf_mat else None
                geoms.append(primitive_geom("visual", visual.origin, geometry, material=material))
    # one merge for all: identical content stored once, under the first name
    mesh_assets, renamed = assets.merge_assets(model.mesh_assets, list(out.pending.values()))
    visual_geoms = dict(model.visual_geoms)
    for name, geoms in ours.items():
        visual_geoms[name] = tuple(
            dataclasses.replace(g, mesh=renamed[g.mesh]) if g.mesh else g for g in geoms
        )

    return dataclasses.replace(
        model,
        robot=robot,
        meshes=meshes,
        mesh_assets=mesh_assets,
        textures=tuple(out.textures.values()),
        materials=tuple(out.materials.values()),
        visual_geoms=visual_geoms,
        notes=tuple(notes),
    )


@dataclass
class _Assets:
    """The assets visual geoms use, each stored once, in order of first use."""

    materials: dict[str, MaterialAsset]
    textures: dict[str, TextureAsset]
    pending: dict[str, MeshAsset] = field(default_factory=dict)
    """New mesh assets by provisional name, merged once at the end (each merge is O(n))."""
    made: dict[tuple[str, str, int, bool], MeshAsset] = field(default_factory=dict)
    """Assets by (content hash, stem, part, with UVs): a mesh several visuals use
    (left and right links) is encoded once."""

    def use(self, material: MaterialAsset, texture: TextureAsset | None) -> str:
        if texture is not None and not _one_file_name(texture.file):  # it becomes assets/<file>
            raise MeshError(f"texture file name {texture.file!r} is not a plain file name; refused")
        self.materials.setdefault(material.name, material)
        if texture is not None:
            self.textures.setdefault(texture.name, texture)
        return material.name

    def add_mesh(self, asset: MeshAsset) -> str:
        self.pending.setdefault(asset.name, asset)
        return asset.name


def _one_file_name(name: str) -> bool:
    """One path component (no separator, not ``.`` or ``..``, no control character): a
    name that stays inside the staging folder's ``assets/`` whatever wrote it."""
    return name not in ("", ".", "..") and "/" not in name and "\\" not in name and (
        untrusted.printable(name) == name
    )


def _open_cache(cfg: MeshConfig) -> mesh_cache.MeshCache | None:
    if not cfg.use_cache:
        return None
    try:
        return mesh_cache.MeshCache(cfg.cache_dir or default_cache_dir())
    except RuntimeError as exc:  # no home directory to keep it in: work without one
        log.warning("no mesh cache: %s", exc)
        return None


def _ensure_loaded(
    ref: MeshRef,
    cfg: MeshConfig,
    cache: mesh_cache.MeshCache | None,
    meshes: dict[Key, LoadedMesh],
    failed: dict[Key, _Unusable],
    palette: Palette,
    notes: list[Note],
) -> _Unusable | None:
    """Load ``ref`` into ``meshes`` unless already tried; the problem, or None."""
    if ref.path is None:
        return _Unusable("cannot be resolved to a file (unknown package or bad path)")
    key = (ref.path, ref.scale)
    if key in meshes:
        return None
    if key not in failed:
        try:
            loaded, found, messages = _load(ref.path, ref.scale, cfg, cache)
        except _Unusable as exc:
            failed[key] = exc
        else:
            meshes[key] = loaded
            palette.update(found)
            for kind, message in messages:
                notes.append(Note(kind, f"mesh '{ref.filename}'", message))  # type: ignore[arg-type]
                log.info("mesh '%s': %s", ref.filename, message)
    return failed.get(key)


def _load(
    path: Path, scale: Vec3, cfg: MeshConfig, cache: mesh_cache.MeshCache | None = None
) -> tuple[LoadedMesh, Palette, list[tuple[str, str]]]:
    """One mesh file in metres, split by material, cleaned and within the face limit."""
    ext = path.suffix.lower()
    data = _read(path, "mesh", "mesh file")
    if data.startswith(LFS_MAGIC):
        raise _Unusable(
            f"{path} is a Git LFS pointer, not a mesh; run 'git lfs pull' in its repository",
            fatal=True,
        )
    if ext not in FORMATS:
        raise _Unusable(f"unsupported mesh format '{path.suffix}'; supported: {', '.join(FORMATS)}")

    digest = hashlib.sha256(data + repr(tuple(float(s) for s in scale)).encode()).hexdigest()
    stem = assets.safe_stem(path.stem)
    if cache is None:
        entry = _decode(path, data, ext, stem, scale, cfg)
    else:
        key = mesh_cache.cache_key(digest, ext, stem, scale, cfg.max_faces)
        found = cache.load(key, functools.partial(_side_file, path))
        if found is None:
            entry = _decode(path, data, ext, stem, scale, cfg)
            cache.store(key, entry)
        else:
            entry = found
    loaded = LoadedMesh(
        path=path, scale=scale, parts=entry.parts, merged=entry.merged, sha256=digest
    )
    return loaded, dict(entry.palette), list(entry.notes)


def _read(path: Path, kind: str, what: str) -> bytes:
    """The bytes of a regular file within ``kind``'s size limit. A missing or unreadable
    file is :class:`_Unusable` (a visual is dropped with a warning); a FIFO, device or
    socket, or a file over the limit, is refused before it is read, and an error even
    for a visual: no honest description names one."""
    try:
        return untrusted.read_file(path, kind, error=MeshError, what=what)
    except MeshError as exc:
        raise _Unusable(exc.detail, fatal=_refused(path, kind)) from None


def _refused(path: Path, kind: str) -> bool:
    """Whether ``path`` exists but is not a regular file, or is over ``kind``'s limit."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return False
    if stat.S_ISDIR(st.st_mode):
        return False  # a folder named like a mesh: unreadable, as before
    return not stat.S_ISREG(st.st_mode) or st.st_size > untrusted.limit_bytes(kind)


def _side_file(path: Path, name: str) -> bytes | None:
    """A file the decoder of ``path`` reads besides it (a texture, an ``.mtl``), found
    as trimesh finds it; None where it cannot (missing, unreadable). ``name`` comes from
    a cache entry: it is read exactly as the decoder reads (``Recording._checked_get``),
    only as a regular file within its kind's size limit (a FIFO would hang us,
    ``/dev/zero`` fill memory); one refused is None, as the decoder recorded it."""
    try:
        return _resolver(path)._checked_get(name)
    except Exception:  # as the decoder saw it: no file
        return None


def _resolver(path: Path, log: dict[str, str | None] | None = None) -> Any:
    """trimesh's resolver for ``path``'s side files; with ``log``, recording each file
    read (name -> sha256 of its bytes, None when it could not be read)."""
    import trimesh

    class Recording(trimesh.resolvers.FilePathResolver):
        def __init__(self, source: str, allow_anywhere: bool = False):
            super().__init__(source, allow_anywhere=allow_anywhere)
            self.refused: list[str] = []
            """Why each side file that exists but was not read was refused."""

        def get(self, name: str) -> bytes:
            try:
                data = self._checked_get(name)
            except Exception:
                if log is not None:
                    log.setdefault(name, None)
                raise
            if log is not None:
                log.setdefault(name, hashlib.sha256(data).hexdigest())
            return data

        def _checked_get(self, name: str) -> bytes:
            # trimesh's get() with its candidates, but reading through read_file: an
            # OBJ's 'mtllib /dev/zero' or a FIFO texture is refused, not opened
            stripped = name.strip()
            for candidate in (stripped, stripped.lstrip("/"), os.path.split(name)[-1]):
                try:
                    found = self.absolute(candidate)
                except ValueError:
                    continue
                if found.exists():
                    kind = "mesh" if found.suffix.lower() == ".mtl" else "texture"
                    try:
                        return untrusted.read_file(found, kind, error=MeshError, what="file")
                    except MeshError as exc:
                        self.refused.append(exc.detail)
                        raise
            raise FileNotFoundError(name)

    # ROS meshes often reference '../textures/x.png'; trimesh 5 refuses that by default
    return Recording(str(path), allow_anywhere=True)


def _decode(
    path: Path, data: bytes, ext: str, stem: str, scale: Vec3, cfg: MeshConfig
) -> mesh_cache.Entry:
    """Decode, split by material, clean and decimate (the work the cache saves)."""
    import trimesh  # heavy; only this pass needs it

    notes: list[tuple[str, str]] = []
    side_files: dict[str, str | None] = {}
    resolver = _resolver(path, side_files)
    try:
        source = _unbind_broken_materials(data, notes) if ext == ".dae" else data
        scene = trimesh.load_scene(
            io.BytesIO(source), file_type=ext[1:], resolver=resolver, process=False
        )
    except Exception as exc:  # trimesh and pycollada raise anything on bad input
        if resolver.refused:  # trimesh may pass our refusal on, or swallow it
            raise _Unusable(resolver.refused[0], fatal=True) from None
        raise _Unusable(f"cannot read {path}: {type(exc).__name__}: {exc}") from None
    if resolver.refused:  # a FIFO, device or oversized .mtl or texture: as for the mesh
        raise _Unusable(resolver.refused[0], fatal=True)

    unit = _collada_unit(data) if ext == ".dae" else 1.0
    linear = np.diag(np.asarray(scale, dtype=float) * unit)
    groups: dict[str | None, list[MeshData]] = {}
    palette: Palette = {}
    for node in scene.graph.nodes_geometry:
        matrix, geom_name = scene.graph[node]
        mesh = scene.geometry[geom_name]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue  # points and lines carry no surface
        m = linear @ matrix[:3, :3]
        with np.errstate(over="ignore", invalid="ignore"):  # a 1e300 vertex: dropped below
            verts = np.asarray(mesh.vertices, dtype=float) @ m.T + linear @ matrix[:3, 3]
        verts, faces = _finite_faces(verts, np.asarray(mesh.faces, dtype=np.int64), notes)
        if not len(faces):
            continue
        if np.linalg.det(m) < 0:  # a mirror turns triangles inside out; keep normals outward
            faces = faces[:, ::-1]
        mat, uv = _own_material(mesh.visual, stem)
        uv = uv if uv is not None and len(uv) == len(verts) else None
        if mat is not None:
            palette.setdefault(mat[0].name, mat)
        name = mat[0].name if mat else None
        groups.setdefault(name, []).append(MeshData(verts, faces, uv))

    parts: list[MeshPart] = []
    for i, (name, pieces) in enumerate(groups.items()):
        # material-less parts keep their UVs for a URDF texture
        keep_uv = name is None or palette[name][1] is not None
        mesh = _decimate(_clean(_concat(pieces, keep_uv)), cfg.max_faces, f"part {i}", notes)
        if len(mesh.vertices) >= 4:  # MuJoCo: "at least 4 vertices required"
            parts.append(MeshPart(mesh, name))
        elif len(mesh.faces):
            notes.append(
                ("warning", f"part {i} has fewer than 4 vertices, which MuJoCo refuses; dropped")
            )
    if not parts:
        why = "; ".join(message for kind, message in notes if kind == "warning")
        raise _Unusable(f"{path} contains no usable triangles" + (f" ({why})" if why else ""))
    merged = _clean(_concat([p.mesh for p in parts], keep_uv=False))
    merged = _decimate(merged, cfg.max_faces, "all parts together", notes)
    used = {p.material for p in parts}
    return mesh_cache.Entry(
        parts=tuple(parts),
        merged=merged,
        palette={k: v for k, v in palette.items() if k in used},
        notes=tuple(notes),
        deps=tuple(side_files.items()),
    )


MAX_COORDINATE = 1e6
"""Largest vertex coordinate (metres, after scale and unit) a mesh may use: a face
with a vertex beyond it, or with a NaN or infinite one, is dropped with a warning
(the rest of the mesh is kept; a mesh left with no face is unusable)."""


def _finite_faces(
    verts: np.ndarray, faces: np.ndarray, notes: list[tuple[str, str]]
) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) without the faces that use a non-finite or far-out vertex (see
    :data:`MAX_COORDINATE`), those vertices zeroed (unused now; a NaN left in would
    spoil the mesh's size that cleaning measures); one warning saying how many."""
    with np.errstate(invalid="ignore"):
        good = np.isfinite(verts).all(axis=1) & (np.abs(verts) <= MAX_COORDINATE).all(axis=1)
    if good.all():
        return verts, faces
    verts = np.where(good[:, None], verts, 0.0)
    keep = np.asarray(((faces >= 0) & (faces < len(verts))).all(axis=1))
    keep[keep] = good[faces[keep]].all(axis=1)
    dropped = int(len(faces) - keep.sum())
    if dropped:
        notes.append(
            (
                "warning",
                f"{dropped} face(s) with a NaN, infinite or out-of-range vertex coordinate "
                f"(beyond {MAX_COORDINATE:g} m) dropped",
            )
        )
    return verts, faces[keep]


def _unbind_broken_materials(data: bytes, notes: list[tuple[str, str]]) -> bytes:
    """The document without bindings to materials pycollada could not load.

    pycollada drops a whole geometry instance when one of its materials is
    broken (say, a texture sampler without its surface); assimp, and so RViz,
    still shows the geometry. Unbound, those triangles take the URDF colour.
    """
    import collada
    from lxml import etree

    doc = collada.Collada(io.BytesIO(data), ignore=[collada.common.DaeError])
    if not doc.errors:
        return data
    loaded = {m.id for m in doc.materials}
    root = etree.fromstring(data, etree.XMLParser(huge_tree=True))
    broken = []
    for el in root.iter("{*}instance_material"):
        target = el.get("target", "").lstrip("#")
        if target not in loaded:
            broken.append(target)
            el.getparent().remove(el)
    if not broken:
        return data
    names = ", ".join(sorted(set(broken)))
    notes.append(("warning", f"unreadable Collada material(s) {names}; their parts lose colour"))
    return etree.tostring(root)


def _collada_unit(data: bytes) -> float:
    """``COLLADA/asset/unit@meter`` (metres per file unit), read as RViz reads it."""
    try:
        for _, el in ET.iterparse(io.BytesIO(data), events=("end",)):
            tag = el.tag.rsplit("}", 1)[-1]
            if tag == "unit":
                return float(el.get("meter", "1"))
            if tag == "asset":  # the document's asset comes first; it has no unit
                return 1.0
    except (ET.ParseError, ValueError):
        pass  # pycollada already accepted the file; keep its units
    return 1.0


def _own_material(
    visual: Any, stem: str
) -> tuple[tuple[MaterialAsset, TextureAsset | None] | None, np.ndarray | None]:
    """The mesh file's material for one trimesh geometry, and its UVs."""
    from trimesh.visual import ColorVisuals, TextureVisuals
    from trimesh.visual.material import color_image

    if isinstance(visual, ColorVisuals):
        if visual.kind is None:
            return None, None
        return (_material(stem, _rgba(visual.main_color), None), None), None  # one colour per part
    if not isinstance(visual, TextureVisuals):
        return None, None
    mat = visual.material
    mat = mat.to_simple() if hasattr(mat, "baseColorFactor") else mat
    uv = None if visual.uv is None else np.asarray(visual.uv, dtype=float)
    image = getattr(mat, "image", None)
    placeholder = color_image()  # trimesh's stand-in when an OBJ has UVs but no material
    if (
        image is not None
        and image.size == placeholder.size
        and image.tobytes() == placeholder.tobytes()
    ):
        return None, uv
    name = mat.name if mat.name not in (None, "material_0") else stem  # trimesh's default name
    texture = None
    if image is not None and uv is not None:
        tex_stem = Path(image.info.get("file_path", name)).stem
        texture = _texture(tex_stem, image)
    else:
        uv = None
    rgba = _rgba(mat.diffuse)
    if rgba[3] == 0.0:  # invisible: an exporter's transparency mix-up, not an intent
        rgba = (*rgba[:3], 1.0)
    return (_material(name, rgba, texture), texture), uv


def _rgba(color: Any) -> RGBA:
    c = [round(float(x) / 255.0, 4) for x in np.asarray(color)[:4]]
    return (c[0], c[1], c[2], c[3] if len(c) > 3 else 1.0)


def _material(stem: str, rgba: RGBA, texture: TextureAsset | None) -> MaterialAsset:
    key = repr((rgba, texture.name if texture else None)).encode()
    return MaterialAsset(
        name=assets.content_name(stem, key), rgba=rgba, texture=texture.name if texture else None
    )


def _texture(stem: str, image: Any) -> TextureAsset:
    """8-bit RGB (RGBA if any pixel is translucent) PNG; the bytes depend on the pixels alone."""
    rgba = image.convert("RGBA")
    opaque = rgba.getchannel("A").getextrema() == (255, 255)
    pixels = rgba.convert("RGB") if opaque else rgba
    data = _png(pixels.mode, pixels.size, pixels.tobytes())
    name = assets.content_name(stem, data)
    return TextureAsset(name=name, file=f"{name}.png", data=data)


@functools.lru_cache(maxsize=16)  # one texture is often shared by many mesh files
def _png(mode: str, size: tuple[int, int], pixels: bytes) -> bytes:
    """Fixed settings and no metadata (fresh image), so the encoding is reproducible."""
    from PIL import Image

    buf = io.BytesIO()
    Image.frombytes(mode, size, pixels).save(buf, format="PNG", optimize=False, compress_level=6)
    return buf.getvalue()


def _urdf_material(
    material: Material | None, notes: list[Note], link: str, source: Path | None = None
) -> tuple[tuple[MaterialAsset, TextureAsset | None], tuple[MaterialAsset, None]] | None:
    """The URDF colour as ((textured material, texture), (plain material, None)), or None.

    Textures need UVs: primitives (mapped by MuJoCo) and mesh parts with UVs
    take the first, parts without UVs the second.
    """
    if material is None or (material.rgba is None and material.texture is None):
        return None
    rgba = material.rgba if material.rgba is not None else (1.0, 1.0, 1.0, 1.0)
    stem = material.name or "material"
    plain = (_material(stem, rgba, None), None)
    if material.texture is None:
        return plain, plain
    from PIL import Image

    where = f"link '{link}' material '{material.name}'"
    try:
        data = _read(material.texture, "texture", "texture")
        # PIL opens bytes we read (regular file, size-limited), never the path itself;
        # a decompression bomb (huge pixel count in a small file) is refused by PIL
        with Image.open(io.BytesIO(data)) as img:
            texture = _texture(material.texture.stem, img)
    except _Unusable as exc:
        if exc.fatal:  # a FIFO, device or oversized file: refused, as a mesh would be
            raise MeshError(str(exc), file=source, element=where) from None
        notes.append(Note("warning", where, f"{exc}; colour only"))
        return plain, plain
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        notes.append(
            Note("warning", where, f"texture {material.texture} unreadable ({exc}); colour only")
        )
        return plain, plain
    return (_material(stem, rgba, texture), texture), plain


def _mesh_geoms(
    visual: Visual,
    loaded: LoadedMesh,
    urdf_mat: tuple[tuple[MaterialAsset, TextureAsset | None], tuple[MaterialAsset, None]] | None,
    palette: Palette,
    out: _Assets,
) -> list[Geom]:
    """One geom per part, placed at the visual origin."""
    stem = assets.safe_stem(loaded.path.stem)
    pos, quat = vec3(visual.origin.xyz), quat_from_rpy(visual.origin.rpy)
    geoms = []
    for i, part in enumerate(loaded.parts):
        mesh = part.mesh
        material = palette.get(part.material) if part.material else None
        if material is None and urdf_mat is not None:
            material = urdf_mat[0] if mesh.uv is not None else urdf_mat[1]
        if mesh.uv is not None and (material is None or material[1] is None):
            mesh = MeshData(mesh.vertices, mesh.faces)  # untextured: STL, not OBJ
        made = (loaded.sha256, stem, i, mesh.uv is not None)
        if made not in out.made:
            out.made[made] = assets.mesh_asset(
                stem if len(loaded.parts) == 1 else f"{stem}_{i}", mesh
            )
        name = out.add_mesh(out.made[made])
        geoms.append(
            Geom(
                role="visual",
                type="mesh",
                pos=pos,
                quat=quat,
                mesh=name,
                material=out.use(*material) if material else None,
            )
        )
    return geoms


def _concat(pieces: list[MeshData], keep_uv: bool) -> MeshData:
    offsets = np.cumsum([0] + [len(p.vertices) for p in pieces])
    verts = np.concatenate([p.vertices for p in pieces])
    faces = np.concatenate([p.faces + o for p, o in zip(pieces, offsets[:-1], strict=True)])
    uv = None
    if keep_uv and any(p.uv is not None for p in pieces):
        uv = np.concatenate(
            [p.uv if p.uv is not None else np.zeros((len(p.vertices), 2)) for p in pieces]
        )
    return MeshData(verts, faces, uv)


def _clean(mesh: MeshData) -> MeshData:
    """Merge identical vertices, drop degenerate and repeated faces and unused vertices.

    Every step keeps first-occurrence order, so the result depends on the input alone.
    """
    v, f, uv = mesh.vertices, mesh.faces, mesh.uv
    if len(f):
        key = v if uv is None else np.hstack([v, uv])
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        rank = np.empty(len(first), dtype=np.int64)
        rank[np.argsort(first)] = np.arange(len(first))
        keep = np.sort(first)
        v, uv, f = v[keep], None if uv is None else uv[keep], rank[inverse.reshape(-1)][f]
        tri = v[f]
        doubled_area = np.linalg.norm(
            np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1
        )
        size = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
        ok = (
            (f[:, 0] != f[:, 1])
            & (f[:, 1] != f[:, 2])
            & (f[:, 0] != f[:, 2])
            & (doubled_area > 1e-12 * size**2)
        )
        f = f[ok]
        # a face repeated with the same winding (any rotation) is a duplicate;
        # the reverse winding is kept, it is the back of a two-sided sheet
        rot = np.argmin(f, axis=1)[:, None]
        canon = np.take_along_axis(f, (rot + np.arange(3)) % 3, axis=1)
        _, first = np.unique(canon, axis=0, return_index=True)
        f = f[np.sort(first)]
    used = np.zeros(len(v), dtype=bool)
    used[f.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return MeshData(
        v[used], remap[f].reshape(-1, 3).astype(np.int64), None if uv is None else uv[used]
    )


def _decimate(mesh: MeshData, max_faces: int, what: str, notes: list[tuple[str, str]]) -> MeshData:
    """Quadric decimation (fast-simplification, deterministic) to at most ``max_faces``."""
    if len(mesh.faces) <= max_faces:
        return mesh
    try:
        import fast_simplification
    except ImportError:
        raise _Unusable(
            f"has {len(mesh.faces)} faces, more than the limit of {max_faces}; "
            "decimating it needs 'pip install fast-simplification'"
        ) from None
    target, out = max_faces, mesh
    while len(out.faces) > max_faces and target > 4:
        verts, faces = fast_simplification.simplify(mesh.vertices, mesh.faces, target_count=target)
        uv = None
        if mesh.uv is not None:  # each new vertex takes the UV of the nearest old one
            from scipy.spatial import cKDTree

            uv = mesh.uv[cKDTree(mesh.vertices).query(verts)[1]]
        out = _clean(
            MeshData(np.asarray(verts, dtype=float), np.asarray(faces, dtype=np.int64), uv)
        )
        target = int(target * 0.9)
    notes.append(
        (
            "decimated",
            f"{what}: {len(mesh.faces)} faces decimated to {len(out.faces)} (limit {max_faces})",
        )
    )
    return out
