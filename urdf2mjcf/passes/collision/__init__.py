"""Collision pass: URDF collision elements -> MuJoCo collision geoms.

Primitives stay primitives. A mesh whose convex hull fits it closely (hull gap
at most :attr:`CollisionConfig.max_hull_gap`, see :mod:`.convexity`, and a hull
the certificate's own figures pass: :class:`~.convexity.HullFigures`) becomes
that hull; any other is split by CoACD into convex parts, one geom each, all
placed at the element's origin like the mesh itself (a hollow one, a tube or an
open shell, cut finer: :attr:`CollisionConfig.coacd_hollow`). A flat mesh (no
volume) becomes a thin box, which MuJoCo can collide with.

That is the ``decompose`` collision shape, the default. The others, chosen for
the whole robot (:attr:`CollisionConfig.shape`) or per link:

* ``hull``: every mesh becomes its convex hull;
* ``primitive``: the best fitted primitive (or set of primitives, see
  :mod:`.primitives`); the hull when nothing fits (a degenerate mesh);
* ``auto``: the cheapest primitive fit within :attr:`CollisionConfig.primitive_tolerance_mm`
  and :attr:`CollisionConfig.primitive_volume_ratio`, else what ``decompose`` gives.

A link's shape is, first found: :attr:`CollisionConfig.link_shapes` (the
command line), the URDF's ``<mujoco><collision link= shape=/></mujoco>``, the
actuator file's ``collision: links``, its ``collision: default``, then
:attr:`CollisionConfig.shape`. Fit candidates are cached by mesh content like
hull gaps, so a warm conversion does not fit again.

Decompositions run in worker processes (:mod:`.worker`), so that
CoACD crashing (a C++ assertion aborts the process) or hanging costs only
that mesh: it gets its convex hull and a warning. Results are kept in a disk
cache (:mod:`.decompositions`) and applied in document order
whatever order they finish in, so the output does not depend on ``workers``.

Determinism: CoACD 1.0.14 with a fixed ``seed`` returns bit-identical parts
across runs, processes, concurrent threads and OpenMP thread counts
(measured with 1, 2 and 4 threads on 20 corpus meshes).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import logging
import os
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from lxml import etree

from ...assets import merge_assets, mesh_asset, safe_stem
from ...errors import InputError, MeshError, URDFError
from ...geometry import primitive_geom
from ...ir import (
    COLLISION_SHAPES,
    CONTACTS,
    Collision,
    CollisionShape,
    Geom,
    LoadedMesh,
    MeshAsset,
    MeshData,
    MeshRef,
    Model,
    Note,
    Robot,
    Visual,
)
from ...mesh_distance import SAMPLES, SEED
from ...transforms import pose_matrix, quat_from_rpy, split_transform, transform, vec3
from ...untrusted import excerpt
from ..actuators import config as actuator_file
from . import primitives
from .convexity import (
    CANDIDATES,
    HULL_SAMPLES,
    MESH_SAMPLES,
    HullFigures,
    HullFit,
    as_trimesh,
    convex_hull,
    flat_box,
    hull_figures,
    hull_fit,
)
from .decompositions import DecompositionCache, array_digest, cache_key, default_cache_dir
from .worker import decompose_all

logger = logging.getLogger(__name__)

MeshKey = tuple[Path, tuple[float, float, float]]
"""Key of ``Model.meshes``: (resolved path, scale)."""

FLAT_THICKNESS = 1e-3
"""Full thickness, metres, of the box that stands in for a flat mesh."""


@dataclass(frozen=True)
class CoacdParams:
    """Keyword arguments of ``coacd.run_coacd``, passed on whole.

    Chosen for speed on robot links. On 20 concave example-robot-data meshes,
    threshold 0.1 with 50 MCTS iterations of depth 2, resolution 1000 and up
    to 16 hulls took 9.5 s a mesh on average (CoACD's defaults take longer
    still), most of it in merging hulls down to the cap and in cutting the
    dense manifold remesh of open meshes. These settings take 0.1-4.5 s,
    1.9 s on average, on one core, giving 2-12 parts.
    """

    threshold: float = 0.15
    """Target concavity of each part (CoACD's normalised Hausdorff measure)."""
    max_convex_hull: int = 12
    """At most this many parts (CoACD merges down to it)."""
    preprocess_mode: str = "auto"
    """Remesh to a manifold only when the input is not one."""
    preprocess_resolution: int = 20
    """Voxel resolution of that remeshing."""
    resolution: int = 300
    """Samples for the concavity measure."""
    mcts_nodes: int = 20
    mcts_iterations: int = 20
    mcts_max_depth: int = 1
    seed: int = 0
    """Fixed: the same mesh always gives the same parts."""


Source = Literal["collision", "visual", "none"]


@dataclass(frozen=True)
class CollisionConfig:
    source: Source = "collision"
    """Which URDF elements give the collision geometry; ``none`` gives no collision geoms."""
    max_hull_gap: float = 0.02
    """Meshes whose hull gap (mean hull-to-mesh surface distance / bounding-box
    diagonal, see :mod:`.convexity`) exceeds this are decomposed; the
    rest become their convex hull. 0.02 sends 92 of the 374 distinct collision
    meshes of example-robot-data to CoACD (brackets, U shapes, forks, frames,
    L-shaped links) and keeps ordinary links as hulls; a U bracket with mesh /
    hull volume 0.625 measures 0.023."""
    coacd: CoacdParams = CoacdParams()
    coacd_hollow: CoacdParams = CoacdParams(threshold=0.05, preprocess_mode="off")
    """For a closed mesh whose hull encloses more than the certificate's largest volume
    ratio (a tube, an open shell: :meth:`~.convexity.HullFigures.hollow`). The default
    remesh fills walls thinner than its voxels, which leaves a tube's parts as full
    as its hull (stretch's telescoping arm: 8.3 x the tube's volume in 4 parts); the
    mesh is closed, so it is cut as it is, to a finer concavity (12 parts, 2.8 x)."""
    cache_dir: Path | None = None
    """None: ``$URDF2MJCF_CACHE``, else ``$XDG_CACHE_HOME/urdf2mjcf``, else
    ``~/.cache/urdf2mjcf``."""
    use_cache: bool = True
    workers: int = 0
    """Decompositions run at once (worker processes); 0: one per available CPU."""
    timeout: float = 120.0
    """Seconds one decomposition may take (0: no limit); past it the worker is
    killed and the mesh gets its convex hull, with a warning. Robot links take
    0.1-5 s; triangle soups can keep CoACD busy for many minutes."""
    progress: Callable[[int, int, str], None] | None = None
    """Called with (done, total, label) each time a decomposition finishes."""
    shape: CollisionShape = "decompose"
    """What collision meshes become (see the module's docstring); ``decompose`` is
    the behaviour described above. Primitive geometry in the URDF stays as it is."""
    link_shapes: Mapping[str, str] = field(default_factory=dict)
    """Link name -> shape; above every other route (the command line's ``--link-collision``).
    An unknown shape or link is an :class:`~urdf2mjcf.errors.InputError`."""
    primitive_tolerance_mm: float = primitives.TOLERANCE_MM
    """``auto``: largest Hausdorff distance (mm) of an accepted primitive fit."""
    primitive_volume_ratio: float = primitives.MAX_VOLUME_RATIO
    """``auto``: largest fit volume / mesh volume of an accepted primitive fit."""
    config_file: Path | None = None
    """The actuator file (``--actuator-config``), whose ``collision`` section gives
    shapes (see :mod:`urdf2mjcf.passes.actuators.config`)."""
    mujoco_extension: bool = True
    """Read ``<collision link= shape=>`` in the URDF's ``<mujoco>`` elements."""


# ---------------------------------------------------------------------------
# Per-mesh plans
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Plan:
    """What one distinct mesh turns into."""

    kind: Literal["hull", "parts", "box", "fits", "none"]
    label: str
    """``mesh '<filename>'`` as first written in the URDF."""
    stem: str
    """Asset name stem: the mesh file's stem."""
    pieces: tuple[MeshData, ...] = ()
    """The hull (one) or the convex parts (several)."""
    box: tuple[np.ndarray, np.ndarray] | None = None
    """(4, 4) pose in the mesh frame and (3,) full sizes, for flat meshes."""
    fits: tuple[primitives.Fit, ...] = ()
    """The fitted primitives, in the mesh frame."""


@dataclass(frozen=True, eq=False)
class _Job:
    """A mesh to decompose (not in the cache)."""

    key: str
    """Cache key."""
    label: str
    stem: str
    name: str
    """File name, for progress reports."""
    why: str
    """Why the hull was not kept: ``hull gap 0.035``, or the certificate's figure it fails."""
    hull: MeshData
    """Fallback when CoACD fails."""
    vertices: np.ndarray
    faces: np.ndarray
    params: CoacdParams = CoacdParams()
    """CoACD's parameters for this mesh."""


def run(model: Model, cfg: CollisionConfig) -> Model:
    """Build ``collision_geoms`` for every link and add the hull and part meshes."""
    links = model.robot.links
    elements: dict[str, tuple[Collision | Visual, ...]] = {}
    for link in links:
        if cfg.source == "collision":
            elements[link.name] = link.collisions
        elif cfg.source == "visual":
            elements[link.name] = link.visuals
        else:
            elements[link.name] = ()

    notes: list[Note] = []
    shapes = link_shapes(model.robot, cfg, notes)
    plans = _plan_meshes(model, cfg, elements, shapes, notes)

    new_assets: list[MeshAsset] = []
    geoms_by_link: dict[str, list[tuple[Geom, str | None, int]]] = {}
    for link in links:
        geoms: list[tuple[Geom, str | None, int]] = []
        for el in elements[link.name]:
            geometry = el.geometry
            if not isinstance(geometry, MeshRef):
                pieces = [primitive_geom("collision", el.origin, geometry)]
            else:
                mesh_key = (geometry.path, geometry.scale)
                plan = plans.get((mesh_key, shapes[link.name]))  # type: ignore[arg-type]
                if plan is None:  # a visual mesh whose file was missing
                    continue
                pieces = _plan_geoms(plan, el, new_assets)
            geoms += [(g, el.name, len(pieces)) for g in pieces]
        geoms_by_link[link.name] = geoms

    mesh_assets, renamed = merge_assets(model.mesh_assets, new_assets)
    collision_geoms: dict[str, tuple[Geom, ...]] = {}
    unique = _unique_element_names(elements)
    for name, geoms in geoms_by_link.items():
        named, seen = [], Counter[str]()
        for k, (g, element_name, count) in enumerate(geoms):
            if element_name in unique:  # the description's own name, where it is unambiguous
                geom_name = element_name if count == 1 else f"{element_name}_{seen[element_name]}"
                seen[element_name] += 1
            else:
                geom_name = f"{name}_collision" if len(geoms) == 1 else f"{name}_collision_{k}"
            mesh = renamed[g.mesh] if g.mesh is not None else None
            named.append(dataclasses.replace(g, name=geom_name, mesh=mesh))
        collision_geoms[name] = tuple(named)

    return dataclasses.replace(
        model,
        collision_geoms=collision_geoms,
        mesh_assets=mesh_assets,
        notes=model.notes + tuple(notes),
    )


def link_shapes(robot: Robot, cfg: CollisionConfig, notes: list[Note]) -> dict[str, CollisionShape]:
    """Each link's collision shape: the first of :attr:`CollisionConfig.link_shapes`, the
    URDF's ``<mujoco><collision>``, the actuator file's ``collision: links``, its
    ``collision: default``, :attr:`CollisionConfig.shape`."""
    links = robot.link_map
    if cfg.shape not in COLLISION_SHAPES:
        raise InputError(
            f"unknown collision shape '{excerpt(str(cfg.shape), 20)}'; "
            f"valid: {', '.join(COLLISION_SHAPES)}"
        )
    for link, shape in cfg.link_shapes.items():  # the command line's: checked first
        where = f"--link-collision {excerpt(link, 60)}={excerpt(shape, 20)}"
        if shape not in COLLISION_SHAPES:
            raise InputError(
                f"unknown collision shape; valid: {', '.join(COLLISION_SHAPES)}", element=where
            )
        if link not in links:
            raise InputError(f"no link '{excerpt(link, 60)}' in the robot", element=where)
    default: CollisionShape = cfg.shape
    from_file: dict[str, CollisionShape] = {}
    if cfg.config_file is not None:
        file = actuator_file.load(cfg.config_file)
        if file.collision_default is not None:
            default = file.collision_default  # type: ignore[assignment]  # checked on reading
        for link, shape in file.collision_links.items():
            if link in links:
                from_file[link] = shape  # type: ignore[assignment]
            else:  # as for joint patterns: one file may serve variants of a robot
                notes.append(
                    Note(
                        "warning",
                        f"link '{excerpt(link, 60)}'",
                        f"{cfg.config_file}: collision: links names a link that does not exist",
                    )
                )
    from_urdf = _extension_shapes(robot) if cfg.mujoco_extension else {}
    return {
        name: cfg.link_shapes.get(name)  # type: ignore[misc]
        or from_urdf.get(name)
        or from_file.get(name)
        or default
        for name in links
    }


def _extension_shapes(robot: Robot) -> dict[str, CollisionShape]:
    """``<mujoco><collision link="NAME" shape="SHAPE"/></mujoco>``, in document order
    (a later one for the same link wins). The extension pass skips these elements."""
    out: dict[str, CollisionShape] = {}
    parser = etree.XMLParser(remove_blank_text=True, remove_comments=True, remove_pis=True)
    for ext in robot.extensions:
        if ext.tag != "mujoco":
            continue
        for el in etree.fromstring(ext.xml.strip(), parser):
            if el.tag != "collision" or "contacts" in el.attrib:
                continue  # <collision contacts=...>: extension_contacts reads it
            link, shape = el.get("link"), el.get("shape")
            where = f"mujoco collision link='{excerpt(link or '', 60)}'"
            if set(el.attrib) != {"link", "shape"} or len(el):
                raise URDFError(
                    'takes exactly link="LINK" shape="SHAPE" and no content',
                    file=robot.source,
                    element=where,
                )
            if shape not in COLLISION_SHAPES:
                raise URDFError(
                    f"unknown shape '{excerpt(shape or '', 20)}'; "
                    f"valid: {', '.join(COLLISION_SHAPES)}",
                    file=robot.source,
                    element=where,
                )
            if link not in robot.link_map:
                raise URDFError("no such link in the robot", file=robot.source, element=where)
            out[link] = shape  # type: ignore[assignment]
    return out


def extension_contacts(robot: Robot) -> str | None:
    """``<mujoco><collision contacts="keep|resolve"/></mujoco>``, the last one in document
    order (None: not said). The extension pass skips these elements too."""
    out: str | None = None
    parser = etree.XMLParser(remove_blank_text=True, remove_comments=True, remove_pis=True)
    for ext in robot.extensions:
        if ext.tag != "mujoco":
            continue
        for el in etree.fromstring(ext.xml.strip(), parser):
            if el.tag != "collision" or "contacts" not in el.attrib:
                continue
            value = el.get("contacts") or ""
            where = f"mujoco collision contacts='{excerpt(value, 20)}'"
            if set(el.attrib) != {"contacts"} or len(el):
                raise URDFError(
                    'takes either link="LINK" shape="SHAPE" or contacts="keep|resolve" alone, '
                    "and no content",
                    file=robot.source,
                    element=where,
                )
            if value not in CONTACTS:
                raise URDFError(
                    f"unknown value; valid: {', '.join(CONTACTS)}", file=robot.source, element=where
                )
            out = value
    return out


def _unique_element_names(elements: dict[str, tuple[Collision | Visual, ...]]) -> set[str]:
    """Element names given once in the whole robot (``<collision name="collision">``
    in every link is common in the wild and cannot name a geom)."""
    counts = Counter(el.name for els in elements.values() for el in els if el.name)
    link_names = set(elements)
    return {n for n, c in counts.items() if c == 1 and n not in link_names}


def _plan_geoms(plan: _Plan, el: Collision | Visual, new_assets: list[MeshAsset]) -> list[Geom]:
    if plan.kind == "none":
        return []
    if plan.kind == "fits":
        origin = pose_matrix(el.origin)
        fits = []
        for fit in plan.fits:
            pos, quat = split_transform(origin @ transform(fit.pos, fit.quat))
            fits.append(Geom(role="collision", type=fit.type, pos=pos, quat=quat, size=fit.size))
        return fits
    if plan.kind == "box":
        assert plan.box is not None
        box_pose, sizes = plan.box
        pos, quat = split_transform(pose_matrix(el.origin) @ box_pose)
        return [
            Geom(
                role="collision",
                type="box",
                pos=pos,
                quat=quat,
                size=tuple(float(s) * 0.5 for s in sizes),
            )
        ]
    pos, quat = vec3(el.origin.xyz), quat_from_rpy(el.origin.rpy)
    out = []
    for i, piece in enumerate(plan.pieces):
        suffix = "hull" if plan.kind == "hull" else f"part{i}"
        asset = mesh_asset(f"{plan.stem}_{suffix}", piece)
        new_assets.append(asset)
        out.append(Geom(role="collision", type="mesh", pos=pos, quat=quat, mesh=asset.name))
    return out


def _plan_meshes(
    model: Model,
    cfg: CollisionConfig,
    elements: dict[str, tuple[Collision | Visual, ...]],
    shapes: Mapping[str, CollisionShape],
    notes: list[Note],
) -> dict[tuple[MeshKey, CollisionShape], _Plan]:
    """Decide hull / parts / box / primitives for each distinct mesh and shape and
    produce its pieces.

    Meshes with the same content (``LoadedMesh.sha256``) and shape share one plan.
    """
    cache = _open_cache(cfg)
    by_content: dict[tuple[str, CollisionShape], _Plan | _Job] = {}
    mesh_notes: dict[tuple[str, CollisionShape], list[Note]] = {}  # (content, shape) -> notes
    users: dict[tuple[str, CollisionShape], list[MeshKey]] = {}  # -> mesh keys using it
    jobs: list[_Job] = []
    job_keys: set[str] = set()

    for link_name, els in elements.items():
        for el in els:
            ref = el.geometry
            if not isinstance(ref, MeshRef):
                continue
            key: MeshKey = (ref.path, ref.scale)  # type: ignore[assignment]
            loaded = model.meshes.get(key) if ref.path is not None else None
            if loaded is None:
                if isinstance(el, Visual):
                    continue  # the meshes pass already reported the missing file
                raise MeshError(
                    "collision mesh was not loaded",
                    file=ref.path or ref.filename,
                    element=f"link '{link_name}' collision mesh '{ref.filename}'",
                )
            content = (loaded.sha256, shapes[link_name])
            if content not in by_content:
                mesh_notes[content] = []
                outcome = _classify(loaded, ref, content[1], cfg, cache, mesh_notes[content])
                by_content[content] = outcome
                # one CoACD run for a mesh that two shapes (decompose, auto) both decompose
                if isinstance(outcome, _Job) and outcome.key not in job_keys:
                    jobs.append(outcome)
                    job_keys.add(outcome.key)
            users.setdefault(content, [])
            if key not in users[content]:
                users[content].append(key)

    results = _run_jobs(jobs, cfg, cache)
    plans: dict[tuple[MeshKey, CollisionShape], _Plan] = {}
    for content, outcome in by_content.items():  # document order, whatever the completion order
        if isinstance(outcome, _Job):
            outcome = _job_plan(outcome, *results[outcome.key], mesh_notes[content])
        notes.extend(mesh_notes[content])
        for key in users[content]:
            plans[(key, content[1])] = outcome
    return plans


def _open_cache(cfg: CollisionConfig) -> DecompositionCache | None:
    if not cfg.use_cache:
        return None
    try:
        return DecompositionCache(cfg.cache_dir or default_cache_dir())
    except RuntimeError as exc:  # no home directory to keep it in: work without one
        logger.warning("no decomposition cache: %s", exc)
        return None


def _job_plan(job: _Job, parts: list[MeshData] | None, failure: str, notes: list[Note]) -> _Plan:
    if parts is not None:
        notes.append(Note("decomposed", job.label, f"{len(parts)} convex parts ({job.why})"))
        return _Plan("parts", job.label, job.stem, pieces=tuple(parts))
    notes.append(
        Note("warning", job.label, f"convex decomposition {failure}; using the convex hull")
    )
    return _Plan("hull", job.label, job.stem, pieces=(job.hull,))


GAP_PARAMS = {
    "hull_samples": HULL_SAMPLES,
    "mesh_samples": MESH_SAMPLES,
    "candidates": CANDIDATES,
    "hull_figures": f"samples {SAMPLES}, seed {SEED}, enclosed volume",
}
"""What a cached hull gap and the hull's figures stored with it depend on besides the mesh."""


def _classify(
    loaded: LoadedMesh,
    ref: MeshRef,
    shape: CollisionShape,
    cfg: CollisionConfig,
    cache: DecompositionCache | None,
    notes: list[Note],
) -> _Plan | _Job:
    """A finished plan (hull, cached parts, box, primitives, nothing) or a job for CoACD."""
    label = f"mesh '{ref.filename}'"
    name = ref.filename.replace("\\", "/").rsplit("/", 1)[-1]
    stem = safe_stem(Path(name).stem or "mesh")
    # Keyed by the mesh as loaded (the file, its scale and the face limit all shape it),
    # not by the file alone: a decimated mesh has its own gap and hull.
    merged = array_digest(loaded.merged.vertices, loaded.merged.faces)
    gap_key = cache_key(loaded.sha256, f"hull-gap:{merged}", GAP_PARAMS)
    hull_key = cache_key(loaded.sha256, f"convex-hull:{merged}", _hull_params())
    if shape in ("primitive", "auto"):
        cands = _fit_candidates(loaded, merged, cache)
        chosen: primitives.Candidate | None
        if shape == "primitive":
            chosen = primitives.best(cands) if cands else None
        else:
            tolerance = cfg.primitive_tolerance_mm * 1e-3
            chosen = primitives.choose(cands, tolerance, cfg.primitive_volume_ratio)
        if chosen is not None:
            notes.append(Note("primitive", label, fit_message(chosen)))
            return _Plan("fits", label, stem, fits=chosen.fits)
        if shape == "primitive":
            notes.append(Note("info", label, "no primitive fits this mesh; using the convex hull"))
    if shape in ("hull", "primitive"):
        return _hull_plan(loaded, label, stem, hull_key, shape, cache, notes)
    cached_gap = cache.load_gap(gap_key) if cache is not None else None
    cached_figures = (
        cache.load_hull_figures(gap_key) if cache is not None and cached_gap is not None else None
    )
    if (
        cached_gap is not None
        and cached_gap <= cfg.max_hull_gap
        and cached_figures is not None
        and cached_figures.failure() is None
    ):
        # A warm run's usual case: no trimesh, no qhull (the stored hull is bit-exact).
        stored = cache.load_hull(hull_key) if cache is not None else None
        if stored is not None:
            return _hull(label, stem, stored, _hull_why(cached_gap, cached_figures), notes)
    mesh = as_trimesh(loaded.merged)
    if len(mesh.faces) == 0:
        notes.append(Note("warning", label, "mesh has no triangles; no collision geom"))
        return _Plan("none", label, stem)
    if cached_gap is not None:  # the hull is computed where it is used, below
        fit = HullFit(hull=None, gap=cached_gap, diagonal=0.0)
    else:
        fit = hull_fit(mesh)
        if fit.hull is None:
            return _flat(label, stem, mesh.vertices, notes)
    hull = fit.hull if fit.hull is not None else convex_hull(mesh.vertices)
    if hull is None:  # a stored gap for what is flat after all (a corrupt entry)
        return _flat(label, stem, mesh.vertices, notes)
    # The hull is kept when the gap passes and the certificate's figures would too.
    figures = cached_figures if cached_figures is not None else hull_figures(mesh, hull)
    if cache is not None and cached_figures is None:
        cache.store_gap(gap_key, fit.gap, figures)
    why = f"hull gap {fit.gap:.3f}" if fit.gap > cfg.max_hull_gap else figures.failure()
    if why is None:
        hull_why = _hull_why(fit.gap, figures)
        return _new_hull(label, stem, mesh.vertices, hull, hull_key, cache, hull_why, notes)
    if figures.hollow and fit.gap > cfg.max_hull_gap:
        why += f", hull volume {figures.volume_ratio:.3g} x the mesh's: a hollow part"
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    params = cfg.coacd_hollow if figures.hollow else cfg.coacd
    key = cache_key(loaded.sha256, array_digest(vertices, faces), asdict(params))
    parts = cache.load(key) if cache is not None else None
    if parts is not None:
        notes.append(Note("cached", label, f"{len(parts)} convex parts from the cache"))
        return _Plan("parts", label, stem, pieces=tuple(parts))
    return _Job(key, label, stem, name, why, hull, vertices, faces, params)


def _hull_why(gap: float, figures: HullFigures) -> str:
    """What a kept hull measured: ``hull gap 0.012, Hausdorff 3.1 mm, volume ratio 1.80``."""
    why = f"hull gap {gap:.3f}, Hausdorff {figures.hausdorff_m * 1e3:.1f} mm"
    if figures.volume_ratio is not None:
        why += f", volume ratio {figures.volume_ratio:.2f}"
    return why


def fit_message(chosen: primitives.Candidate) -> str:
    """``capsule+box (Hausdorff 1.2 mm, volume ratio 1.08)``: what the report's
    summary counts (the types before the first space) and the deviation."""
    kinds = "+".join(f.type for f in chosen.fits)
    dev = chosen.deviation
    mm = dev.hausdorff_m * 1e3
    return f"{kinds} (Hausdorff {mm:.1f} mm, volume ratio {dev.volume_ratio:.2f})"


def _fit_candidates(
    loaded: LoadedMesh, merged: str, cache: DecompositionCache | None
) -> list[primitives.Candidate]:
    """Every primitive-fit candidate of the mesh, from the cache when it has them."""
    key = cache_key(loaded.sha256, f"primitive-fits:{merged}", _fit_params())
    if cache is not None:
        stored = cache.load_fits(key)
        if stored is not None:
            return stored
    vertices = np.ascontiguousarray(loaded.merged.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(loaded.merged.faces, dtype=np.int64)
    # plain floats, as the cache gives them back: a warm run writes the same bytes
    cands = [_plain(c) for c in primitives.candidates(vertices, faces, sets=True)]
    if cache is not None:
        cache.store_fits(key, cands)
    return cands


def _plain(c: primitives.Candidate) -> primitives.Candidate:
    def floats(values: tuple[float, ...]) -> tuple[float, ...]:
        return tuple(float(v) for v in values)

    fits = tuple(
        primitives.Fit(
            type=f.type,
            pos=floats(f.pos),  # type: ignore[arg-type]
            quat=floats(f.quat),  # type: ignore[arg-type]
            size=floats(f.size),
        )
        for f in c.fits
    )
    dev = primitives.Deviation(
        hausdorff_m=float(c.deviation.hausdorff_m),
        uncovered_m=float(c.deviation.uncovered_m),
        volume_ratio=float(c.deviation.volume_ratio),
    )
    return primitives.Candidate(fits=fits, deviation=dev, cost=float(c.cost))


@functools.cache
def _fit_params() -> dict[str, str]:
    """What stored fit candidates depend on besides the mesh: the fitting code itself
    (any change to it refits) and scipy's version (the other libraries are in every key)."""
    import hashlib

    import scipy

    source = Path(primitives.__file__).read_bytes()
    return {"fitting": hashlib.sha256(source).hexdigest(), "scipy": scipy.__version__}


def _hull_plan(
    loaded: LoadedMesh,
    label: str,
    stem: str,
    hull_key: str,
    shape: CollisionShape,
    cache: DecompositionCache | None,
    notes: list[Note],
) -> _Plan:
    """The convex hull, whatever the hull gap (shapes ``hull`` and ``primitive``)."""
    why = f"collision shape {shape}"
    stored = cache.load_hull(hull_key) if cache is not None else None
    if stored is not None:
        return _hull(label, stem, stored, why, notes)
    mesh = as_trimesh(loaded.merged)
    if len(mesh.faces) == 0:
        notes.append(Note("warning", label, "mesh has no triangles; no collision geom"))
        return _Plan("none", label, stem)
    return _new_hull(label, stem, mesh.vertices, None, hull_key, cache, why, notes)


def _hull(label: str, stem: str, hull: MeshData, why: str, notes: list[Note]) -> _Plan:
    notes.append(Note("hull", label, f"convex hull ({why})"))
    return _Plan("hull", label, stem, pieces=(hull,))


def _new_hull(
    label: str,
    stem: str,
    vertices: np.ndarray,
    hull: MeshData | None,
    hull_key: str,
    cache: DecompositionCache | None,
    why: str,
    notes: list[Note],
) -> _Plan:
    """The plan of the hull of ``vertices`` (``hull`` where already computed), stored in
    the cache; a flat mesh (no hull) becomes a thin box."""
    if hull is None:
        hull = convex_hull(vertices)
    if hull is None:  # flat, or a stored gap for what is flat after all (a corrupt entry)
        return _flat(label, stem, vertices, notes)
    if cache is not None:
        cache.store_hull(hull_key, hull)
    return _hull(label, stem, hull, why, notes)


def _flat(label: str, stem: str, vertices: np.ndarray, notes: list[Note]) -> _Plan:
    notes.append(
        Note("warning", label, f"mesh is flat; using a {FLAT_THICKNESS * 1e3:g} mm thick box")
    )
    return _Plan("box", label, stem, box=flat_box(vertices, FLAT_THICKNESS))


@functools.cache
def _hull_params() -> dict[str, str]:
    """What a stored convex hull depends on besides the mesh: qhull's version."""
    import scipy

    return {"scipy": scipy.__version__}


# ---------------------------------------------------------------------------
# Running CoACD
# ---------------------------------------------------------------------------


def _available_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def _run_jobs(
    jobs: list[_Job], cfg: CollisionConfig, cache: DecompositionCache | None
) -> dict[str, tuple[list[MeshData] | None, str]]:
    """Decompose every job: its parts, or None and why not."""
    results: dict[str, tuple[list[MeshData] | None, str]] = {}
    if not jobs:
        return results  # start no worker when the cache answered everything
    _require_coacd()
    total = len(jobs)
    workers = min(cfg.workers if cfg.workers > 0 else _available_cpus(), total)
    logger.info("decomposing %d meshes with CoACD (%d workers)", total, workers)

    def finish(index: int, raw: list[np.ndarray] | None, failure: str) -> None:
        job = jobs[index]
        parts = _solid_parts(raw) if raw is not None else None
        if raw is not None and parts is None:
            failure = "gave no solid parts"
        if parts is None:
            logger.debug("CoACD on %s: %s", job.label, failure)
        elif cache is not None:
            cache.store(job.key, parts)
        results[job.key] = (parts, failure)
        if cfg.progress is not None:
            cfg.progress(len(results), total, job.name)

    tasks = [(j.vertices, j.faces, asdict(j.params)) for j in jobs]
    decompose_all(tasks, workers, cfg.timeout, finish)
    return results


def _require_coacd() -> None:
    if importlib.util.find_spec("coacd") is None:  # pragma: no cover - coacd is a dependency
        raise MeshError(
            "convex decomposition needs coacd: pip install coacd "
            "(or use source='none' / a larger max_hull_gap)"
        )


def _solid_parts(raw: list[np.ndarray]) -> list[MeshData] | None:
    """CoACD's parts (their vertices), each replaced by its exact outward-facing hull;
    flat parts dropped."""
    parts = []
    for v in raw:
        hull = convex_hull(np.asarray(v, dtype=np.float64))
        if hull is not None:
            parts.append(hull)
    return parts or None
