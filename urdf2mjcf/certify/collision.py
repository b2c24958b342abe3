"""Collision figures of the certificate: what the model collides with, per link,
against the description's collision geometry.

Two shapes are compared in the link's frame:

* the **source**: the URDF's ``<collision>`` elements of the link as yourdfpy
  reads them (origin, primitive sizes, mesh file and scale), the meshes loaded
  with trimesh from the file the conversion's resolver finds, independently of
  the conversion's own mesh pass;
* the **model**: the link's colliding geoms in the compiled MuJoCo model
  (``contype | conaffinity != 0``), placed by ``geom_pos``/``geom_quat`` in
  their body. A mesh geom is its vertices' convex hull, because that is what
  MuJoCo's collision detection uses; primitives are their exact shapes.

Figures (per link):

``hausdorff_mm``
    The one-sided Hausdorff distance from the model to the source, in mm: the
    largest distance from a point of the model's collision surface to the
    source's surface, over ``SAMPLES`` points spread uniformly by area over the
    model's surface (seed 0, so deterministic). How far the collision shape
    sticks out of the description: a convex hull bridging a cavity, or a shape
    swapped for a bigger one. The maximum over the sampled points is exact (see
    :class:`MeshDistance`); between samples it may miss a thin spike.
``uncovered_mm``
    The reverse direction, cheaply: the largest distance by which a point of
    the source's surface (``SAMPLES`` points) lies outside every model geom
    (outside a hull: its largest face-plane distance, a lower bound of the
    Euclidean one). Collision geometry the conversion lost shows here.
``volume_ratio``
    The volume the model's collision geoms enclose (their union, by manifold3d
    when there are several) over the volume the source encloses (its union
    likewise, each mesh's closed parts taken outward: a part wound inside out
    encloses what it encloses, see :func:`~urdf2mjcf.mesh_distance.enclosed_volume`);
    None, with a ``reason``, when a source mesh is not watertight (its volume is
    undefined).
``size_mm``, ``tolerance_mm``
    The source's bounding-box diagonal, and the distance tolerance of the link:
    the larger of ``hausdorff_mm`` and ``hausdorff_rel`` x ``size_mm``.

A link fails when either distance exceeds its tolerance, when its volume ratio
is outside ``volume_ratio``, or when the description collides there and the
model does not. A link not measured says why (``reason``): no collision in
either, a source mesh that cannot be read, a geom with no measurable shape.

Primitives the conversion keeps are measured like everything else, so an
exact copy shows ratio 1 and 0 mm rather than being assumed to.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..mesh_distance import (
    HAUSDORFF_MM,
    HAUSDORFF_REL,
    SAMPLES,
    SEED,
    VOLUME_RATIO,
    MeshDistance,
    sample_triangles,
    solid_parts,
    to_manifold,
    union_volume,
)
from ..solids import Hull, Primitive, SourcePart, largest_distance, sample_union
from . import stored

if TYPE_CHECKING:
    import mujoco
    import trimesh

    from .reference import Reference

log = logging.getLogger(__name__)

# HAUSDORFF_MM, HAUSDORFF_REL, VOLUME_RATIO, SAMPLES and SEED are the collision pass's
# decomposition rule's (urdf2mjcf.mesh_distance): a hull the pass keeps passes here.
_COLLISION_NAME = re.compile(r"^(?P<link>.*)_collision(?:_\d+)?$")


# -- shapes ------------------------------------------------------------------


# -- the source ---------------------------------------------------------------


@dataclass
class SourceShape:
    """A link's collision (or visual) elements in the link frame."""

    primitives: list[Primitive]
    meshes: list[trimesh.Trimesh]
    problems: list[str]  # what could not be read, one phrase each
    zero_size: list[str] = field(default_factory=list)
    """Shapes of zero size (a sphere of radius 0), one phrase each: the description's
    flaw, left out (they have no surface; the conversion drops them, as MuJoCo needs
    size > 0)."""

    @property
    def empty(self) -> bool:
        return not self.primitives and not self.meshes


@lru_cache(maxsize=256)
def _load_mesh(path: str, size: int, mtime: float) -> trimesh.Trimesh:
    """A mesh file as one trimesh (scene graphs flattened); cached by file state, as the
    collision figures and the inertia check read the same files."""
    import trimesh

    mesh = trimesh.load(path, force="mesh", process=True)
    if not isinstance(mesh, trimesh.Trimesh) or not len(mesh.faces):
        raise ValueError("no triangles")
    return mesh


def load_mesh(path: Path) -> trimesh.Trimesh:
    st = path.stat()
    return _load_mesh(str(path), st.st_size, st.st_mtime)


def source_shape(ref: Reference, link: Any, kind: str = "collisions") -> SourceShape:
    """``link``'s ``<collision>`` (or ``<visual>``: kind="visuals") elements."""
    prims: list[Primitive] = []
    meshes: list[trimesh.Trimesh] = []
    problems: list[str] = []
    zero: list[str] = []
    for el in getattr(link, kind):
        pose = np.eye(4) if el.origin is None else np.asarray(el.origin, float)
        g = el.geometry
        flaw = zero_size(g)
        if flaw is not None:
            zero.append(flaw)
        elif g.box is not None:
            prims.append(Primitive("box", np.asarray(g.box.size, float) / 2, pose))
        elif g.sphere is not None:
            prims.append(Primitive("sphere", np.array([g.sphere.radius], float), pose))
        elif g.cylinder is not None:
            size = np.array([g.cylinder.radius, g.cylinder.length / 2], float)
            prims.append(Primitive("cylinder", size, pose))
        elif g.mesh is not None:
            try:
                mesh = load_mesh(ref.resolve(g.mesh.filename)).copy()
            except Exception as exc:  # missing, unreadable or empty: said, not fatal
                problems.append(f"{g.mesh.filename}: {' '.join(str(exc).split())[:120]}")
                continue
            if g.mesh.scale is not None:
                scale = _scale3(g.mesh.scale)
                mesh.apply_transform(np.diag([*scale, 1.0]))
            mesh.apply_transform(pose)
            meshes.append(mesh)
    return SourceShape(prims, meshes, problems, zero)


def _scale3(value: Any) -> np.ndarray:
    """A mesh scale as three factors: one value for all, else the first three (as the
    conversion reads pybullet's ``scale="1 1 1 1"``)."""
    scale = np.asarray(value, float).ravel()
    return np.broadcast_to(scale, 3) if scale.size == 1 else scale[:3]


def zero_size(g: Any) -> str | None:
    """``sphere of radius 0`` for a shape of zero size (yourdfpy's geometry), else None."""
    if g.box is not None and 0.0 in [float(x) for x in g.box.size]:
        return f"box of size {' '.join(f'{float(x):g}' for x in g.box.size)}"
    if g.sphere is not None and float(g.sphere.radius) == 0.0:
        return "sphere of radius 0"
    if g.cylinder is not None and 0.0 in (float(g.cylinder.radius), float(g.cylinder.length)):
        return (
            f"cylinder of radius {float(g.cylinder.radius):g}, length {float(g.cylinder.length):g}"
        )
    if g.mesh is not None and g.mesh.scale is not None:
        scale = np.asarray(g.mesh.scale, float).ravel()
        if 0.0 in scale:
            return f"mesh '{g.mesh.filename}' scaled by {' '.join(f'{x:g}' for x in scale)}"
    return None


# -- the model ----------------------------------------------------------------


def colliding_geoms(m: mujoco.MjModel) -> list[int]:
    """Geoms that collide with something (planes and height fields of the world excluded:
    the scene's floor is not the robot)."""
    import mujoco

    ground = (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD)
    return [
        i
        for i in range(m.ngeom)
        if (m.geom_contype[i] or m.geom_conaffinity[i]) and int(m.geom_type[i]) not in ground
    ]


def geom_links(ref: Reference, m: mujoco.MjModel, geoms: list[int]) -> dict[int, str]:
    """The URDF link each geom stands for: the one its name says (``<link>_collision``,
    also when ``--fuse-fixed`` moved it into a parent body), else its body's."""
    import mujoco

    links = set(ref.link_names)
    out: dict[int, str] = {}
    for g in geoms:
        match = _COLLISION_NAME.match(m.geom(g).name or "")
        if match and match["link"] in links:
            out[g] = match["link"]
            continue
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g])) or ""
        if body in links:
            out[g] = body
        elif m.geom_bodyid[g] == 0 and "world" in links:
            out[g] = "world"
    return out


def geom_pose(m: mujoco.MjModel, g: int) -> np.ndarray:
    """4x4 body <- geom."""
    import mujoco

    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, m.geom_quat[g])
    pose = np.eye(4)
    pose[:3, :3] = mat.reshape(3, 3)
    pose[:3, 3] = m.geom_pos[g]
    return pose


def body_from_link(ref: Reference, m: mujoco.MjModel, link: str, body: int) -> np.ndarray:
    """4x4 link <- body (identity unless the link was fused into another body)."""
    import mujoco

    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, body) or ""
    if name == link or (body == 0 and link == "world"):
        return np.eye(4)
    frames = _zero_frames(ref)
    if name not in frames:
        raise KeyError(f"body {name!r} is no link of the description")
    return np.linalg.inv(frames[link]) @ frames[name]


def _zero_frames(ref: Reference) -> dict[str, np.ndarray]:
    return ref.frames(None)  # fixed joints only matter: any configuration


def _placed_geoms(
    ref: Reference, m: mujoco.MjModel, link: str, geoms: list[int]
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Each geom as (kind, vertices in ``link``'s frame or size, pose in it)."""
    import mujoco

    kinds = {
        mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
        mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
        mujoco.mjtGeom.mjGEOM_ELLIPSOID: "ellipsoid",
        mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
        mujoco.mjtGeom.mjGEOM_BOX: "box",
    }
    out: list[tuple[str, np.ndarray, np.ndarray]] = []
    for g in geoms:
        pose = body_from_link(ref, m, link, int(m.geom_bodyid[g])) @ geom_pose(m, g)
        t = int(m.geom_type[g])
        if t == mujoco.mjtGeom.mjGEOM_MESH:
            mid = int(m.geom_dataid[g])
            adr, num = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
            v = np.asarray(m.mesh_vert[adr : adr + num], float)
            out.append(("hull", v @ pose[:3, :3].T + pose[:3, 3], pose))
        elif t in kinds:
            out.append((kinds[t], np.array(m.geom_size[g], float), pose))
        else:  # an SDF or height field: no shape we can measure
            raise ValueError(f"geom {m.geom(g).name or g} has type {mujoco.mjtGeom(t).name}")
    return out


def model_signature(ref: Reference, m: mujoco.MjModel, link: str, geoms: list[int]) -> list[Any]:
    """What :func:`model_shapes` builds from, as a cache key's part (no hull computed)."""
    import hashlib

    return [
        [kind, hashlib.sha256(data.round(12).tobytes()).hexdigest()]
        if kind == "hull"
        else [kind, data.tolist(), pose.round(12).tolist()]
        for kind, data, pose in _placed_geoms(ref, m, link, geoms)
    ]


def model_shapes(
    ref: Reference, m: mujoco.MjModel, link: str, geoms: list[int]
) -> list[Primitive | Hull]:
    """The geoms, in ``link``'s frame, as MuJoCo collides with them."""
    out: list[Primitive | Hull] = []
    for (kind, data, pose), g in zip(_placed_geoms(ref, m, link, geoms), geoms, strict=True):
        if kind != "hull":
            out.append(Primitive(kind, data, pose))
            continue
        try:
            out.append(Hull(data))
        except Exception as exc:  # qhull: a flat or degenerate mesh
            raise ValueError(f"geom {m.geom(g).name or g}: no convex hull ({exc})") from None
    return out


def _union_volume(clouds: list[np.ndarray]) -> float:
    """Volume of the union of convex hulls of point clouds (manifold3d)."""
    import manifold3d

    parts = [manifold3d.Manifold.hull_points(c.astype(np.float64)) for c in clouds]
    return float(manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add).volume())


def _model_volume(shapes: list[Primitive | Hull]) -> float:
    if len(shapes) == 1:
        s = shapes[0]
        return float(s.area_volume()[1]) if isinstance(s, Primitive) else s.volume
    return _union_volume([s.cloud() if isinstance(s, Primitive) else s.points for s in shapes])


def _source_volume(src: SourceShape) -> tuple[float | None, str | None]:
    """(volume, None) or (None, why not). Each mesh's volume is what it encloses, its
    closed parts each taken outward (:func:`~urdf2mjcf.mesh_distance.solid_parts`): a
    part wound inside out does not cancel another's volume."""
    meshes = []
    for mesh in src.meshes:
        parts = solid_parts(mesh)
        if parts is None:
            return None, "the source mesh is not watertight: its volume is undefined"
        meshes.extend(parts)
    if len(src.primitives) + len(meshes) == 1:
        if src.primitives:
            return float(src.primitives[0].area_volume()[1]), None
        return float(meshes[0].volume), None
    import manifold3d

    solids = [manifold3d.Manifold.hull_points(p.cloud()) for p in src.primitives]
    for part in meshes:
        solid = to_manifold(part)
        if solid is None:
            return None, "the source meshes do not form a closed solid: volume undefined"
        solids.append(solid)
    return union_volume(solids), None


def source_size(src: SourceShape) -> float:
    """The diagonal of the source's bounding box (m)."""
    pts = np.vstack([p.cloud() for p in src.primitives] + [x.vertices for x in src.meshes])
    return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))


# -- the section --------------------------------------------------------------


def measure_link(
    src: SourceShape, shapes: list[Primitive | Hull], samples: int = SAMPLES
) -> dict[str, Any]:
    """The figures of one link whose source and model both have geometry."""
    rng = np.random.default_rng(SEED)
    meshes = [MeshDistance(x.triangles, rng) for x in src.meshes]
    parts: list[SourcePart] = [*src.primitives, *meshes]
    model_points = sample_union(shapes, samples, rng)
    hausdorff = largest_distance(parts, model_points)
    src_shapes: list[Primitive | Hull] = list(src.primitives)
    src_points = [sample_union(src_shapes, samples, rng)] if src_shapes else []
    for mesh in src.meshes:
        n = max(1, samples // max(1, len(src.meshes) + len(src_shapes)))
        src_points.append(sample_triangles(np.asarray(mesh.triangles), n, rng))
    pts = np.vstack(src_points)
    outside = np.min([np.maximum(s.sdf(pts), 0.0) for s in shapes], axis=0)
    volume, reason = _source_volume(src)
    ratio = None if volume is None or volume <= 0 else _model_volume(shapes) / volume
    out: dict[str, Any] = {
        "volume_ratio": None if ratio is None else round(float(ratio), 6),
        "size_mm": round(source_size(src) * 1e3, 1),
        "hausdorff_mm": round(hausdorff * 1e3, 3),
        "uncovered_mm": round(float(outside.max()) * 1e3, 3),
    }
    if reason is not None:
        out["reason"] = reason
    return out


FIGURES_FORMAT = 3
"""Bump when what :func:`measure_link` computes changes (the cached figures go stale)."""


def _element_kind(link: Any) -> str:
    geoms = [el.geometry for el in link.collisions]
    if any(g.mesh is not None for g in geoms):
        return "mesh"
    return "primitive" if geoms else "none"


@lru_cache(maxsize=512)
def _file_digest(path: str, size: int, mtime: float) -> str:
    import hashlib

    from ..untrusted import read_file

    return hashlib.sha256(read_file(path, "mesh")).hexdigest()


def source_elements(ref: Reference, link: Any, which: str = "collisions") -> list[Any] | None:
    """A link's collision (or visual) elements as a cache key's part (mesh files by
    content); None when a file cannot be read (then nothing is cached: the figures
    say why). Kept on ``ref``: three kinds of figures ask for the same link's."""
    memo = ref.memo.setdefault("source_elements", {})
    key = (link.name, which)
    if key not in memo:
        memo[key] = _source_elements(ref, getattr(link, which))
    return memo[key]


def _source_elements(ref: Reference, elements: Iterable[Any]) -> list[Any] | None:
    def numbers(value: Any) -> Any:
        return None if value is None else np.asarray(value, float).round(12).tolist()

    out: list[Any] = []
    for el in elements:
        g = el.geometry
        pose = numbers(el.origin)
        if g.mesh is not None:
            try:
                path = ref.resolve(g.mesh.filename)
                st = path.stat()
                digest = _file_digest(str(path), st.st_size, st.st_mtime)
            except Exception:  # unreadable: measured (and explained) every time
                return None
            out.append(["mesh", digest, numbers(g.mesh.scale), pose])
        elif g.box is not None:
            out.append(["box", numbers(g.box.size), pose])
        elif g.sphere is not None:
            out.append(["sphere", float(g.sphere.radius), pose])
        elif g.cylinder is not None:
            out.append(["cylinder", float(g.cylinder.radius), float(g.cylinder.length), pose])
        else:
            out.append(["none", pose])
    return out


def _figures_key(ref: Reference, link: Any, model: list[Any]) -> str | None:
    """The cache key of one link's figures: its source elements, the model's shapes
    (:func:`model_signature`), the sampling and the libraries; None when a file cannot
    be read."""
    elements = source_elements(ref, link)
    if elements is None:
        return None
    return stored.key(
        {
            "kind": "certificate-collision",
            "format": FIGURES_FORMAT,
            "samples": SAMPLES,
            "seed": SEED,
            "source": elements,
            "model": model,
        }
    )


_FIGURES = ("volume_ratio", "size_mm", "hausdorff_mm", "uncovered_mm", "reason")


def _cached_figures(root: Path, key: str) -> dict[str, Any] | None:
    """A link's stored figures, or None (absent, or anything but what we wrote)."""
    figures = stored.load(root, key)
    if not isinstance(figures, dict) or set(figures) - set(_FIGURES):
        return None
    for name in ("size_mm", "hausdorff_mm", "uncovered_mm"):
        if not stored.is_number(figures.get(name), low=0.0):
            return None
    ratio = figures.get("volume_ratio")
    if ratio is not None and not stored.is_number(ratio):
        return None
    reason = figures.get("reason")
    if reason is not None and not stored.is_short_text(reason):
        return None
    return figures


def _store_figures(root: Path, key: str, figures: dict[str, Any]) -> None:
    stored.store(root, key, {k: v for k, v in figures.items() if k in _FIGURES})


def collision_section(
    ref: Reference,
    m: mujoco.MjModel,
    *,
    hausdorff_mm: float = HAUSDORFF_MM,
    volume_ratio: tuple[float, float] = VOLUME_RATIO,
    hausdorff_rel: float = HAUSDORFF_REL,
    cache_root: Path | None = None,
) -> dict[str, Any]:
    """Per-link collision figures (see the module) and one failure line per link
    past a tolerance. A link's distance tolerance is the larger of ``hausdorff_mm``
    and ``hausdorff_rel`` times its source's size (bounding-box diagonal): a
    convex hull bridges recesses in proportion to the link. It applies to both
    directions; ``volume_ratio`` is (low, high). With ``cache_root`` (the conversion's
    cache folder), a link's figures are kept by content: a warm conversion measures
    nothing again (the sampling is seeded, so they are the same figures)."""
    geoms = colliding_geoms(m)
    owner = geom_links(ref, m, geoms)
    by_link: dict[str, list[int]] = {}
    for g in geoms:
        if g in owner:
            by_link.setdefault(owner[g], []).append(g)
    links: dict[str, dict[str, Any]] = {}
    failures: list[str] = []
    warnings: list[str] = []
    for link in ref.urdf.robot.links:
        name = link.name
        mine = by_link.get(name, [])
        entry: dict[str, Any] = {
            "geoms": len(mine),
            "source": _element_kind(link),
            "volume_ratio": None,
            "hausdorff_mm": None,
            "ok": True,
        }
        links[name] = entry
        key = None
        if cache_root is not None and mine and link.collisions:
            try:
                key = _figures_key(ref, link, model_signature(ref, m, name, mine))
            except (ValueError, KeyError):
                key = None
            cached = _cached_figures(cache_root, key) if key else None
            if cached is not None:
                entry.update(cached)
                _judge(name, entry, hausdorff_mm, hausdorff_rel, volume_ratio, failures)
                continue
        src = source_shape(ref, link)
        if src.zero_size:
            entry["zero_size"] = list(src.zero_size)
        if src.problems:
            entry["reason"] = "source not read: " + "; ".join(src.problems)
        if src.empty and not mine and src.zero_size:
            # the description's own flaw: said as a warning, not the conversion's failure
            what = "; ".join(src.zero_size)
            entry["reason"] = (
                f"the description's collision shape has zero size ({what}): the "
                "description's flaw, which MuJoCo cannot collide (it needs size > 0)"
            )
            warnings.append(
                f"collision {name}: no colliding geom because the description's collision "
                f"shape has zero size ({what}): the description's flaw, not the conversion's"
            )
            continue
        if src.empty and not mine:
            entry.setdefault("reason", "no collision geometry")
            continue
        if src.empty:
            entry.setdefault("reason", "the model collides where the description has no collision")
            continue
        if not mine:
            entry["ok"] = False
            entry["reason"] = "the description collides here, the model does not"
            failures.append(f"collision {name}: the model has no colliding geom for it")
            continue
        try:
            shapes = model_shapes(ref, m, name, mine)
        except (ValueError, KeyError) as exc:
            entry["reason"] = f"not measured: {exc}"
            continue
        try:
            figures = measure_link(src, shapes)
        except Exception as exc:  # a degenerate shape: this link says so, the rest go on
            log.info("collision figures of %s not measured", name, exc_info=True)
            entry["reason"] = f"not measured: {' '.join(str(exc).split())[:120]}"
            continue
        entry.update(figures)
        if key is not None and cache_root is not None:
            _store_figures(cache_root, key, figures)
        _judge(name, entry, hausdorff_mm, hausdorff_rel, volume_ratio, failures)
    return {"links": links, "failures": failures, "warnings": warnings}


def _judge(
    name: str,
    entry: dict[str, Any],
    hausdorff_mm: float,
    hausdorff_rel: float,
    volume_ratio: tuple[float, float],
    failures: list[str],
) -> None:
    """Set ``entry["ok"]`` and add one failure line per figure past its tolerance."""
    lo, hi = volume_ratio
    limit = max(hausdorff_mm, hausdorff_rel * entry["size_mm"])
    entry["tolerance_mm"] = round(limit, 3)
    h, u, r = entry["hausdorff_mm"], entry["uncovered_mm"], entry["volume_ratio"]
    if h > limit:
        failures.append(
            f"collision {name}: the model's collision surface sticks out {h:.1f} mm from "
            f"the source's (tolerance {limit:.1f} mm)"
        )
    if u > limit:
        failures.append(
            f"collision {name}: the source's surface lies {u:.1f} mm outside the model's "
            f"collision geoms (tolerance {limit:.1f} mm)"
        )
    if r is not None and not lo <= r <= hi:
        failures.append(
            f"collision {name}: the model's collision volume is {r:.3g} x the source's "
            f"(tolerance {lo:g}-{hi:g})"
        )
    entry["ok"] = h <= limit and u <= limit and (r is None or lo <= r <= hi)
