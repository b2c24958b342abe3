"""Collision pass: URDF collision elements -> MuJoCo collision geoms.

Primitives stay primitives. A mesh whose convex hull fits it closely (hull gap
at most :attr:`CollisionConfig.max_hull_gap`, see :mod:`.convexity`)
becomes that hull; a clearly concave one is split by CoACD into convex parts,
one geom each, all placed at the element's origin like the mesh itself. A flat
mesh (no volume) becomes a thin box, which MuJoCo can collide with.

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
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from ...assets import merge_assets, mesh_asset, safe_stem
from ...errors import MeshError
from ...geometry import primitive_geom
from ...ir import Collision, Geom, LoadedMesh, MeshAsset, MeshData, MeshRef, Model, Note, Visual
from ...transforms import pose_matrix, quat_from_rpy, split_transform, vec3
from .convexity import (
    CANDIDATES,
    HULL_SAMPLES,
    MESH_SAMPLES,
    HullFit,
    as_trimesh,
    convex_hull,
    flat_box,
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


# ---------------------------------------------------------------------------
# Per-mesh plans
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Plan:
    """What one distinct mesh turns into."""

    kind: Literal["hull", "parts", "box", "none"]
    label: str
    """``mesh '<filename>'`` as first written in the URDF."""
    stem: str
    """Asset name stem: the mesh file's stem."""
    pieces: tuple[MeshData, ...] = ()
    """The hull (one) or the convex parts (several)."""
    box: tuple[np.ndarray, np.ndarray] | None = None
    """(4, 4) pose in the mesh frame and (3,) full sizes, for flat meshes."""


@dataclass(frozen=True, eq=False)
class _Job:
    """A mesh to decompose (not in the cache)."""

    key: str
    """Cache key."""
    label: str
    stem: str
    name: str
    """File name, for progress reports."""
    gap: float
    hull: MeshData
    """Fallback when CoACD fails."""
    vertices: np.ndarray
    faces: np.ndarray


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
    plans = _plan_meshes(model, cfg, elements, notes)

    new_assets: list[MeshAsset] = []
    geoms_by_link: dict[str, list[tuple[Geom, str | None, int]]] = {}
    for link in links:
        geoms: list[tuple[Geom, str | None, int]] = []
        for el in elements[link.name]:
            geometry = el.geometry
            if not isinstance(geometry, MeshRef):
                pieces = [primitive_geom("collision", el.origin, geometry)]
            else:
                plan = plans.get((geometry.path, geometry.scale))  # type: ignore[arg-type]
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


def _unique_element_names(elements: dict[str, tuple[Collision | Visual, ...]]) -> set[str]:
    """Element names given once in the whole robot (``<collision name="collision">``
    in every link is common in the wild and cannot name a geom)."""
    counts = Counter(el.name for els in elements.values() for el in els if el.name)
    link_names = set(elements)
    return {n for n, c in counts.items() if c == 1 and n not in link_names}


def _plan_geoms(plan: _Plan, el: Collision | Visual, new_assets: list[MeshAsset]) -> list[Geom]:
    if plan.kind == "none":
        return []
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
    notes: list[Note],
) -> dict[MeshKey, _Plan]:
    """Decide hull / parts / box for each distinct mesh and produce its pieces.

    Meshes with the same content (``LoadedMesh.sha256``) share one plan.
    """
    cache = _open_cache(cfg)
    by_content: dict[str, _Plan | _Job] = {}
    mesh_notes: dict[str, list[Note]] = {}  # content hash -> its notes
    users: dict[str, list[MeshKey]] = {}  # content hash -> mesh keys using it
    jobs: list[_Job] = []

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
            if loaded.sha256 not in by_content:
                mesh_notes[loaded.sha256] = []
                outcome = _classify(loaded, ref, cfg, cache, mesh_notes[loaded.sha256])
                by_content[loaded.sha256] = outcome
                if isinstance(outcome, _Job):
                    jobs.append(outcome)
            users.setdefault(loaded.sha256, [])
            if key not in users[loaded.sha256]:
                users[loaded.sha256].append(key)

    results = _run_jobs(jobs, cfg, cache)
    plans: dict[MeshKey, _Plan] = {}
    for sha, outcome in by_content.items():  # document order, whatever the completion order
        if isinstance(outcome, _Job):
            outcome = _job_plan(outcome, *results[outcome.key], mesh_notes[sha])
        notes.extend(mesh_notes[sha])
        for key in users[sha]:
            plans[key] = outcome
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
        notes.append(
            Note("decomposed", job.label, f"{len(parts)} convex parts (hull gap {job.gap:.3f})")
        )
        return _Plan("parts", job.label, job.stem, pieces=tuple(parts))
    notes.append(
        Note("warning", job.label, f"convex decomposition {failure}; using the convex hull")
    )
    return _Plan("hull", job.label, job.stem, pieces=(job.hull,))


GAP_PARAMS = {"hull_samples": HULL_SAMPLES, "mesh_samples": MESH_SAMPLES, "candidates": CANDIDATES}
"""What a cached hull gap depends on besides the mesh."""


def _classify(
    loaded: LoadedMesh,
    ref: MeshRef,
    cfg: CollisionConfig,
    cache: DecompositionCache | None,
    notes: list[Note],
) -> _Plan | _Job:
    """A finished plan (hull, cached parts, box, nothing) or a job for CoACD."""
    label = f"mesh '{ref.filename}'"
    name = ref.filename.replace("\\", "/").rsplit("/", 1)[-1]
    stem = safe_stem(Path(name).stem or "mesh")
    # Keyed by the mesh as loaded (the file, its scale and the face limit all shape it),
    # not by the file alone: a decimated mesh has its own gap and hull.
    merged = array_digest(loaded.merged.vertices, loaded.merged.faces)
    gap_key = cache_key(loaded.sha256, f"hull-gap:{merged}", GAP_PARAMS)
    hull_key = cache_key(loaded.sha256, f"convex-hull:{merged}", _hull_params())
    cached_gap = cache.load_gap(gap_key) if cache is not None else None
    if cache is not None and cached_gap is not None and cached_gap <= cfg.max_hull_gap:
        # A warm run's usual case: no trimesh, no qhull (the stored hull is bit-exact).
        stored = cache.load_hull(hull_key)
        if stored is not None:
            notes.append(Note("hull", label, f"convex hull (hull gap {cached_gap:.3f})"))
            return _Plan("hull", label, stem, pieces=(stored,))
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
        if cache is not None:
            cache.store_gap(gap_key, fit.gap)
    if fit.gap <= cfg.max_hull_gap:
        hull = fit.hull if fit.hull is not None else convex_hull(mesh.vertices)
        if hull is None:  # a stored gap for what is flat after all (a corrupt entry)
            return _flat(label, stem, mesh.vertices, notes)
        if cache is not None:
            cache.store_hull(hull_key, hull)
        notes.append(Note("hull", label, f"convex hull (hull gap {fit.gap:.3f})"))
        return _Plan("hull", label, stem, pieces=(hull,))
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    key = cache_key(loaded.sha256, array_digest(vertices, faces), asdict(cfg.coacd))
    parts = cache.load(key) if cache is not None else None
    if parts is not None:
        notes.append(Note("cached", label, f"{len(parts)} convex parts from the cache"))
        return _Plan("parts", label, stem, pieces=tuple(parts))
    hull = fit.hull if fit.hull is not None else convex_hull(mesh.vertices)
    if hull is None:  # a stored gap for what is flat after all (a corrupt entry)
        return _flat(label, stem, mesh.vertices, notes)
    return _Job(key, label, stem, name, fit.gap, hull, vertices, faces)


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
    params = asdict(cfg.coacd)
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

    decompose_all([(j.vertices, j.faces, params) for j in jobs], workers, cfg.timeout, finish)
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
