"""The checks single-model linters (mjcf-doctor, simcheck) run, made against the source.

Each check reports ``ok``, a one-line ``detail`` and its figures; a failing one
adds one line per offending link, geom pair or joint to ``failures`` (to ``warnings`` for
the inertia and passive-energy checks: what they flag can be the description's own).

``inertia``
    The description's declared inertia against its own geometry: the link's
    collision shape (its visuals when it has none; a mesh that is not watertight
    counts as its convex hull) filled uniformly to the declared mass, both
    tensors about their centres of mass in link axes. Flagged: a principal
    moment ``inertia_factor`` or more off, or principal axes swapped (the
    geometry's clearly smallest axis carries the clearly largest declared
    moment). Links without ``<inertial>`` are not checked: the conversion
    estimated theirs from this very geometry.
``interpenetration``
    Pairs of colliding geoms of different bodies that MuJoCo's collision
    detection reports at home (so neither excluded nor parent-child filtered)
    deeper than ``penetration_m``, each attributed: ``description`` when the
    two links' source shapes overlap by that much too at the same pose (the
    reference's frames; :func:`~urdf2mjcf.solids.overlap_depth`: the deepest
    sampled point inside the other, or how far they must move apart along the
    contact's normal, whichever is larger), else ``conversion`` (a hull filling a
    cavity, a shape moved). The contacts pass excludes the conversion's by the
    same measure. Only overlaps the conversion added fail the check; the
    description's own are listed.
``home_in_limits``
    The home pose (``d_home``, else the keyframe ``home``, else ``qpos0``)
    inside every joint's limits, the description's and the model's.
``collision_matrix``
    At least one robot geom collides with a floor of MuJoCo's default
    ``contype=1 conaffinity=1``.
``visual_massless``
    Visual geoms (group 2) collide with nothing and weigh nothing: the model
    compiled again without them has the same body masses and inertias
    (measured when ``model_path`` is given).
``passive_energy``
    From home, actuation disabled, one second of simulation (at most
    ``mjcf.compile.MAX_PASSIVE_STEPS`` steps) with MuJoCo's energy enabled: kinetic plus potential
    energy never exceeds its start by more than ``energy_growth`` of the
    robot's energy scale (total mass x gravity x model extent) plus 1 mJ.
    Gravity, damping and contacts only take energy away.
"""

from __future__ import annotations

import copy
import logging
from concurrent.futures import Future
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..mesh_distance import SEED
from ..solids import (
    OVERLAP_SAMPLES,
    PENETRATION_M,
    Hull,
    Placed,
    Primitive,
    geom_solid,
    overlap_depth,
)
from . import stored
from .collision import colliding_geoms, geom_links, source_elements, source_shape, zero_size

if TYPE_CHECKING:
    import mujoco
    import trimesh

    from ..mjcf.compile import PassiveRun
    from .reference import Reference

log = logging.getLogger(__name__)

INERTIA_FACTOR = 10.0
ENERGY_GROWTH = 0.01
"""Allowed growth over a passive second, as a fraction of mass x gravity x extent."""
ENERGY_FLOOR_J = 1e-3
AXIS_SEPARATION = 4.0
"""Principal moments at least this far apart make an axis "clearly" the smallest or
the largest; the declared moment about it must be this far off to call the axes
swapped. (2 flags the misaligned but plausible identified inertias of Panda's
links 1-3 and hand; 4 still flags talos's rgbd_link, 15x about the wrong axis.)"""
LIMIT_TOLERANCE = 1e-9


def _check(ok: bool, detail: str, **figures: Any) -> dict[str, Any]:
    return {"ok": bool(ok), "detail": detail, **figures}


# -- inertia ------------------------------------------------------------------


def _solid(src: Any) -> tuple[trimesh.Trimesh | None, bool]:
    """One closed mesh standing for the shape (parts concatenated) and whether a
    part had to be replaced by its convex hull."""
    import trimesh

    parts: list[trimesh.Trimesh] = []
    hulled = False
    for p in src.primitives:
        parts.append(trimesh.convex.convex_hull(p.cloud()))
    for mesh in src.meshes:
        if mesh.is_watertight and mesh.volume > 0:
            parts.append(mesh)
        else:
            parts.append(mesh.convex_hull)
            hulled = True
    parts = [p for p in parts if p.volume > 0]
    if not parts:
        return None, hulled
    solid = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
    return (solid if isinstance(solid, trimesh.Trimesh) else None), hulled


def _inertia_of(mesh: trimesh.Trimesh, mass: float) -> np.ndarray:
    """Inertia tensor about the centre of mass, link axes, uniform density at ``mass``."""
    props = mesh.mass_properties
    return np.asarray(props["inertia"]) * (mass / props["mass"])


INERTIA_FORMAT = 1
"""Bumped whenever what :func:`geometry_inertia` stores changes."""
NO_VOLUME = "no geometry with a volume"
_SHAPES = tuple(s + h for s in ("collision", "visual") for h in ("", " (convex hull)"))
"""What a link's inertia is measured on (an entry naming anything else is a miss)."""


def _geometry_inertia(ref: Reference, link: Any) -> tuple[str, np.ndarray] | str:
    """(which shape, the inertia tensor per kilogram about its centre of mass in link
    axes) of the link's geometry filled uniformly, or why there is none."""
    src = source_shape(ref, link)
    shape = "collision"
    if src.empty:
        src, shape = source_shape(ref, link, "visuals"), "visual"
    solid, hulled = _solid(src) if not src.empty else (None, False)
    if solid is None:
        return NO_VOLUME
    per_kg = _inertia_of(solid, 1.0)
    if np.linalg.eigvalsh(per_kg)[0] <= 0:
        return NO_VOLUME
    return shape + (" (convex hull)" if hulled else ""), per_kg


def geometry_inertia(
    ref: Reference, link: Any, cache_root: Path | None = None
) -> tuple[str, np.ndarray] | str:
    """:func:`_geometry_inertia`, kept by content under ``cache_root`` (the source
    elements, mesh files by content: a warm conversion loads no mesh for it)."""
    key = None
    if cache_root is not None:
        # a link with collision elements is measured on them (its visuals only when
        # none of them loads: then nothing is kept, so no visual file is missed)
        which = "collisions" if link.collisions else "visuals"
        elements = source_elements(ref, link, which)
        if elements is not None:
            key = stored.key(
                {"kind": "certificate-inertia", "format": INERTIA_FORMAT, which: elements}
            )
            kept = stored.load(cache_root, key)
            if kept == NO_VOLUME:
                return NO_VOLUME
            if (
                isinstance(kept, list)
                and len(kept) == 2
                and kept[0] in _SHAPES
                and isinstance(kept[1], list)
                and len(kept[1]) == 9
                and all(stored.is_number(x) for x in kept[1])
            ):
                return str(kept[0]), np.array(kept[1], float).reshape(3, 3)
    result = _geometry_inertia(ref, link)
    if key is not None and cache_root is not None:
        fell_back = link.collisions and not isinstance(result, str) and "visual" in result[0]
        if not fell_back:
            value = result if isinstance(result, str) else [result[0], result[1].ravel().tolist()]
            stored.store(cache_root, key, value)
    return result


def inertia_link(
    link: Any, ref: Reference, factor: float, cache_root: Path | None = None
) -> dict[str, Any] | str:
    """The inertia comparison of one link, or why there is none."""
    inertial = link.inertial
    if inertial is None:
        return "estimated by the conversion"
    if inertial.mass is None or inertial.mass <= 0 or inertial.inertia is None:
        return "no mass"
    rot = np.eye(3) if inertial.origin is None else np.asarray(inertial.origin)[:3, :3]
    declared = rot @ np.asarray(inertial.inertia, float) @ rot.T
    dec = np.sort(np.linalg.eigvalsh(declared))
    if dec[0] <= 1e-12 * max(dec[2], 1e-300) or dec[0] + dec[1] < dec[2] * (1 - 1e-6):
        return "declared inertia not physical: the conversion repaired it"
    measured = geometry_inertia(ref, link, cache_root)
    if isinstance(measured, str):
        return measured
    shape, per_kg = measured
    lam, axes = np.linalg.eigh(per_kg * float(inertial.mass))
    ratios = dec / lam
    off = float(max(ratios.max(), 1 / ratios.min()))
    # Swapped axes: where the geometry clearly has its smallest (largest) moment, the
    # declared tensor has one clearly above its smallest (below its largest).
    along = np.array([a @ declared @ a for a in axes.T])  # declared moment on each mesh axis
    sep = AXIS_SEPARATION
    swapped = bool(
        (lam[1] / lam[0] >= sep and along[0] / dec[0] >= sep)
        or (lam[2] / lam[1] >= sep and dec[2] / along[2] >= sep)
    )
    return {
        "shape": shape,
        "declared": [float(x) for x in dec],
        "geometry": [float(x) for x in lam],
        "factor": round(off, 3),
        "swapped": swapped,
        "ok": off < factor and not swapped,
    }


def check_inertia(
    ref: Reference, factor: float, cache_root: Path | None = None
) -> tuple[dict[str, Any], list[str]]:
    links: dict[str, dict[str, Any]] = {}
    skipped: dict[str, str] = {}
    failures: list[str] = []
    for link in ref.urdf.robot.links:
        try:
            entry = inertia_link(link, ref, factor, cache_root)
        except Exception as exc:  # a degenerate mesh: said, not fatal
            skipped[link.name] = f"not measured: {' '.join(str(exc).split())[:100]}"
            continue
        if isinstance(entry, str):
            skipped[link.name] = entry
            continue
        links[link.name] = entry
        if not entry["ok"]:
            what = (
                "principal axes swapped"
                if entry["swapped"]
                else f"principal moments {entry['factor']:.3g}x off"
            )
            failures.append(
                f"inertia {link.name}: declared inertia against its {entry['shape']} "
                f"at the declared mass: {what}"
            )
    worst = max((e["factor"] for e in links.values()), default=None)
    detail = (
        f"{len(links)} links against their geometry, worst factor {worst:.3g}"
        if links
        else "no link with both an inertial and geometry"
    )
    if failures:
        detail = f"{len(failures)} of {len(links)} links implausible"
    check = _check(
        not failures, detail, checked=len(links), worst_factor=worst, links=links, skipped=skipped
    )
    return check, failures


# -- home pose ----------------------------------------------------------------


def home_data(m: mujoco.MjModel, d_home: mujoco.MjData | None) -> mujoco.MjData:
    """A fresh MjData at home, forward-computed (the caller's data is left alone)."""
    import mujoco

    from ..mjcf.compile import data_from

    if d_home is not None:
        d = data_from(m, d_home)
    else:
        d = mujoco.MjData(m)
        if m.nkey:
            key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")
            mujoco.mj_resetDataKeyframe(m, d, key if key >= 0 else 0)
    mujoco.mj_forward(m, d)
    return d


def _scalar_joints(m: mujoco.MjModel) -> dict[str, int]:
    """Hinge and slide joints by name: their qpos address."""
    import mujoco

    kinds = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
    return {
        m.joint(j).name: int(m.jnt_qposadr[j])
        for j in range(m.njnt)
        if int(m.jnt_type[j]) in kinds and m.joint(j).name
    }


def home_cfg(ref: Reference, m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """yourdfpy's configuration at the model's home (joints matched by name; 0 else)."""
    adr = _scalar_joints(m)
    return np.array([float(d.qpos[adr[n]]) if n in adr else 0.0 for n in ref.actuated_joints])


def check_home(
    ref: Reference, m: mujoco.MjModel, d: mujoco.MjData
) -> tuple[dict[str, Any], list[str]]:
    adr = _scalar_joints(m)
    failures: list[str] = []
    outside: list[dict[str, Any]] = []
    zero_outside: list[str] = []
    for joint in ref.urdf.robot.joints:
        if joint.type not in ("revolute", "prismatic") or joint.limit is None:
            continue
        lo, hi = joint.limit.lower, joint.limit.upper
        if lo is None or hi is None or lo >= hi:
            continue  # no range: the conversion leaves it unlimited
        if not lo <= 0.0 <= hi:
            zero_outside.append(joint.name)
        if joint.name not in adr or joint.mimic is not None:
            continue
        q = float(d.qpos[adr[joint.name]])
        if not lo - LIMIT_TOLERANCE <= q <= hi + LIMIT_TOLERANCE:
            outside.append({"joint": joint.name, "home": q, "range": [lo, hi], "of": "description"})
    for j in range(m.njnt):
        name = m.joint(j).name
        if not m.jnt_limited[j] or name not in adr:
            continue
        lo, hi = (float(x) for x in m.jnt_range[j])
        q = float(d.qpos[adr[name]])
        if not lo - LIMIT_TOLERANCE <= q <= hi + LIMIT_TOLERANCE:
            if not any(o["joint"] == name for o in outside):
                outside.append({"joint": name, "home": q, "range": [lo, hi], "of": "model"})
    for o in outside:
        failures.append(
            f"home {o['joint']}: home position {o['home']:.6g} outside the {o['of']}'s "
            f"limits [{o['range'][0]:.6g}, {o['range'][1]:.6g}]"
        )
    detail = (
        "home inside every joint's limits"
        if not outside
        else f"{len(outside)} joints at home outside their limits"
    )
    if zero_outside and not outside:
        detail += f" ({len(zero_outside)} of the description's zero positions are not: clamped)"
    return _check(not outside, detail, outside=outside, zero_outside=zero_outside), failures


# -- collisions ---------------------------------------------------------------


def check_collision_matrix(m: mujoco.MjModel, ref: Reference) -> dict[str, Any]:
    geoms = colliding_geoms(m)
    owner = geom_links(ref, m, geoms)
    robot = [g for g in geoms if m.geom_bodyid[g] != 0 or g in owner]  # not the scene's
    floor = [g for g in robot if (m.geom_contype[g] & 1) or (m.geom_conaffinity[g] & 1)]
    figures = {"floor_geoms": len(floor), "colliding_geoms": len(robot)}
    if floor:
        detail = f"{len(floor)} of {len(robot)} colliding geoms can touch a default floor"
        return _check(True, detail, **figures)
    elements = [el for link in ref.urdf.robot.links for el in link.collisions]
    if not elements:
        detail = "the description has no collision geometry, nor has the model"
        return _check(True, detail, **figures)
    if all(zero_size(el.geometry) is not None for el in elements):
        detail = (
            "the description's only collision shapes have zero size (its flaw: MuJoCo needs "
            "size > 0), and the model has none"
        )
        return _check(True, detail, **figures)
    if all(zero_size(el.geometry) is not None or _unknown(el.geometry) for el in elements):
        detail = (
            "the description's only collision shapes are of kinds URDF does not define (a "
            "simulator's own, such as <plane> or <cdf>: the conversion warned it dropped "
            "them) or of zero size, and the model has none: the description's choice"
        )
        return _check(True, detail, **figures)
    if all(
        zero_size(el.geometry) is not None
        or _unknown(el.geometry)
        or _missing_mesh(ref, el.geometry)
        for el in elements
    ):
        detail = (
            "the description's collision meshes were not found or not readable (its flaw: "
            "the conversion warned it dropped them), its other shapes are of zero size or "
            "of kinds URDF does not define, and the model has none left"
        )
        return _check(True, detail, **figures)
    return _check(False, "no geom can touch a floor of contype=1 conaffinity=1", **figures)


def _missing_mesh(ref: Reference, g: Any) -> bool:
    """A mesh shape whose file the conversion's resolver cannot find as a regular file."""
    if g.mesh is None:
        return False
    try:
        return not ref.resolve(g.mesh.filename).is_file()
    except Exception:  # unresolvable (an unknown package): missing as far as anyone can tell
        return True


def _unknown(g: Any) -> bool:
    """A geometry the reference has no shape for: a kind URDF does not define."""
    kinds = ("box", "sphere", "cylinder", "mesh", "capsule")
    return all(getattr(g, k, None) is None for k in kinds)


def _geom_label(m: mujoco.MjModel, g: int) -> str:
    import mujoco

    name = m.geom(g).name
    if name:
        return name
    body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g])) or "world"
    k = g - int(m.body_geomadr[m.geom_bodyid[g]])
    return f"{body} geom #{k}"


def _signature(solid: Primitive | Hull) -> list[Any]:
    """A placed geom as a cache key's part: a hull by its points' hash, a primitive whole."""
    import hashlib

    if isinstance(solid, Hull):
        return ["hull", hashlib.sha256(np.asarray(solid.points).round(12).tobytes()).hexdigest()]
    return [solid.kind, solid.size.round(12).tolist(), solid.pose.round(12).tolist()]


def _root_frame(ref: Reference, m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """4x4 world <- the description's root link, where ``d`` has it (the frame the
    reference's link frames are given in)."""
    import mujoco

    frame = np.eye(4)
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, str(ref.urdf.base_link))
    if body > 0:
        frame[:3, :3], frame[:3, 3] = np.asarray(d.xmat[body]).reshape(3, 3), d.xpos[body]
    return frame


def _overlap_key(
    ref: Reference,
    links: tuple[Any, Any],
    poses: tuple[Any, Any],
    along: tuple[np.ndarray, float, list[Any] | None],
) -> str | None:
    """The cache key of :func:`~urdf2mjcf.solids.overlap_depth` of two links' source shapes
    at these poses, along a contact's normal up to its depth within its two geoms
    (:func:`_signature`; None when a mesh file cannot be read)."""
    parts = []
    for link, pose in zip(links, poses, strict=True):
        elements = source_elements(ref, link)
        if elements is None:
            return None
        parts.append([elements, np.asarray(pose, float).round(12).tolist()])
    payload = {"kind": "certificate-overlap", "format": 4, "samples": OVERLAP_SAMPLES, "seed": SEED}
    normal, limit, geoms = along
    separation = [np.asarray(normal, float).round(9).tolist(), round(float(limit), 9), geoms]
    return stored.key({**payload, "links": parts, "along": separation})


def check_interpenetration(
    ref: Reference,
    m: mujoco.MjModel,
    d: mujoco.MjData,
    penetration: float,
    cache_root: Path | None = None,
) -> tuple[dict[str, Any], list[str]]:
    import mujoco

    ground = (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD)
    deepest: dict[tuple[int, int], float] = {}
    normals: dict[tuple[int, int], np.ndarray] = {}  # of the deepest, from the first to the second
    for i in range(d.ncon):
        c = d.contact[i]
        g1, g2 = sorted((int(c.geom1), int(c.geom2)))
        if int(m.geom_type[g1]) in ground or int(m.geom_type[g2]) in ground:
            continue
        if m.geom_bodyid[g1] == m.geom_bodyid[g2]:
            continue
        depth = -float(c.dist)
        if depth > deepest.get((g1, g2), -np.inf):
            deepest[(g1, g2)] = depth
            normal = np.array(c.frame[:3], dtype=np.float64)
            normals[(g1, g2)] = normal if g1 == int(c.geom1) else -normal
    deep = {k: v for k, v in deepest.items() if v > penetration}
    owner = geom_links(ref, m, sorted({g for pair in deep for g in pair}))
    links = {link.name: link for link in ref.urdf.robot.links}
    frames: dict[str, np.ndarray] | None = None
    root: np.ndarray | None = None
    placed: dict[str, Any] = {}
    pairs: list[dict[str, Any]] = []
    failures: list[str] = []
    for (g1, g2), depth in sorted(deep.items(), key=lambda kv: -kv[1]):
        l1, l2 = owner.get(g1, ""), owner.get(g2, "")
        src_depth: float | None = None
        if l1 in links and l2 in links and l1 != l2:
            if frames is None:
                frames = ref.frames(home_cfg(ref, m, d))
            along = normals[(g1, g2)]
            if root is None:
                root = _root_frame(ref, m, d)
            near_a, near_b = geom_solid(m, d, g1, root), geom_solid(m, d, g2, root)
            near = (near_a, near_b) if near_a is not None and near_b is not None else None
            key = _overlap_key(
                ref,
                (links[l1], links[l2]),
                (frames[l1], frames[l2]),
                (along, depth, None if near is None else [_signature(x) for x in near]),
            )
            kept = stored.load(cache_root, key) if cache_root and key else None
            if kept is not None and stored.is_number(kept, low=0.0):
                src_depth = float(kept)
            else:
                for name in (l1, l2):
                    if name not in placed:
                        src = source_shape(ref, links[name])
                        placed[name] = Placed.of(src.primitives, src.meshes, frames[name])
                try:
                    src_depth = overlap_depth(
                        placed[l1], placed[l2], along=along, limit=depth, near=near
                    )
                except Exception:  # a mesh trimesh cannot test: not compared, said so
                    log.info("source overlap of %s / %s not measured", l1, l2, exc_info=True)
                if cache_root and key and src_depth is not None:
                    stored.store(cache_root, key, src_depth)
        by = "description" if src_depth is not None and src_depth > penetration else "conversion"
        labels = [_geom_label(m, g1), _geom_label(m, g2)]
        pair: dict[str, Any] = {
            "geoms": labels,
            "links": [l1 or None, l2 or None],
            "depth_m": round(depth, 6),
            "source_depth_m": None if src_depth is None else round(src_depth, 6),
            "by": by,
        }
        pairs.append(pair)
        if by == "conversion":
            failures.append(
                f"interpenetration {labels[0]} / {labels[1]}: {depth * 1e3:.1f} mm "
                f"deep at home, added by the conversion (the description's shapes: "
                + (f"{src_depth * 1e3:.1f} mm)" if src_depth is not None else "not compared)")
            )
    added = sum(p["by"] == "conversion" for p in pairs)
    if not pairs:
        detail = f"no colliding pair deeper than {penetration * 1e3:g} mm at home"
    else:
        detail = (
            f"{len(pairs)} pairs deeper than {penetration * 1e3:g} mm at home: "
            f"{added} added by the conversion, {len(pairs) - added} in the description"
        )
    worst = max(deepest.values(), default=0.0)
    return _check(not added, detail, pairs=pairs, max_depth_m=round(max(worst, 0.0), 6)), failures


# -- visual geoms ---------------------------------------------------------------


def _visual_geoms(m: mujoco.MjModel) -> list[int]:
    return [g for g in range(m.ngeom) if m.geom_group[g] == 2]


def _visual_mass_free(path: Path, m: mujoco.MjModel) -> list[int] | None:
    """Bodies whose mass or inertia changes when the visual geoms (group 2) weigh
    nothing; None where that cannot be told. A model whose compiler takes inertia
    from ``<inertial>`` only (``inertiafromgeom="false"``, as we write) has none;
    otherwise the file is compiled again with those geoms' mass and density zeroed."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(path))
    if spec.compiler.inertiafromgeom == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE:
        return []
    for g in spec.geoms:
        if g.group == 2:
            g.mass, g.density = 0.0, 0.0
    bare = spec.compile()
    if bare.nbody != m.nbody:
        return None
    out = []
    for b in range(1, m.nbody):
        dm = abs(float(m.body_mass[b] - bare.body_mass[b]))
        di = float(np.abs(m.body_inertia[b] - bare.body_inertia[b]).max())
        if dm > 1e-9 * max(1.0, float(m.body_mass[b])) or di > 1e-12:
            out.append(b)
    return out


def check_visuals(m: mujoco.MjModel, model_path: Path | None) -> tuple[dict[str, Any], list[str]]:
    visual = _visual_geoms(m)
    failures: list[str] = []
    colliding = [g for g in visual if m.geom_contype[g] or m.geom_conaffinity[g]]
    for g in colliding:
        failures.append(f"visual {_geom_label(m, g)}: a visual geom (group 2) collides")
    heavy: list[str] = []
    measured = False
    if model_path is not None and visual:
        try:
            bodies = _visual_mass_free(Path(model_path), m)
        except Exception as exc:  # the file changed or cannot be read again: say so
            log.info("visual geoms' mass not measured: %s", exc)
            bodies = None
        measured = bodies is not None
        for b in bodies or []:
            heavy.append(m.body(b).name)
            failures.append(
                f"visual {m.body(b).name}: its visual geoms weigh (body mass "
                f"{float(m.body_mass[b]):.6g} kg with them)"
            )
    if failures:
        detail = f"{len(colliding)} visual geoms collide, {len(heavy)} bodies weighed by visuals"
    elif not visual:
        detail = "no visual geom (group 2)"
    else:
        detail = f"{len(visual)} visual geoms collide with nothing" + (
            " and weigh nothing" if measured else " (mass not measured: no model file)"
        )
    figures = {
        "visual_geoms": len(visual),
        "colliding": len(colliding),
        "heavy_bodies": heavy,
        "mass_measured": measured,
    }
    return _check(not failures, detail, **figures), failures


# -- energy ---------------------------------------------------------------------


def check_energy(
    m: mujoco.MjModel, d_home: mujoco.MjData, growth: float, run: PassiveRun | None = None
) -> tuple[dict[str, Any], list[str]]:
    """``run``: the passive second from the same home, stepped elsewhere (on a model
    of the same robot); None: stepped here."""
    from ..mjcf.compile import passive_second, warnings_into

    if run is None:
        with warnings_into([]):  # a divergence is in the figures
            run = passive_second(copy.copy(m), d_home)
    mass = float(m.body_mass[1:].sum())
    scale = mass * float(np.linalg.norm(m.opt.gravity)) * float(m.stat.extent)
    allowed = growth * scale + ENERGY_FLOOR_J
    rise = run.peak_j - run.start_j
    diverged = run.diverged_at is not None
    ok = not diverged and rise <= allowed
    seconds = run.steps * run.timestep
    figures = {
        "steps": run.steps,
        "seconds": round(seconds, 6),
        "start_j": run.start_j,
        "max_growth_j": rise,
        "allowed_j": allowed,
        "diverged": diverged,
    }
    if run.diverged_at is not None:
        at = run.diverged_at
        detail = f"simulation diverged after {at} steps ({at * run.timestep:.3g} s)"
    else:
        detail = (
            f"energy rose {rise:.3g} J at most over {seconds:.3g} s passive "
            f"(allowed {allowed:.3g} J)"
        )
    failures = [] if ok else [f"passive_energy: {detail}"]
    return _check(ok, detail, **figures), failures


# -- the section ------------------------------------------------------------------


def lint_section(
    ref: Reference,
    m: mujoco.MjModel,
    d_home: mujoco.MjData | None = None,
    *,
    inertia_factor: float = INERTIA_FACTOR,
    penetration_m: float = PENETRATION_M,
    energy_growth: float = ENERGY_GROWTH,
    model_path: str | Path | None = None,
    cache_root: Path | None = None,
    passive: Future[PassiveRun] | None = None,
) -> dict[str, Any]:
    """Every check of the module; ``model_path`` (the file ``m`` was compiled from)
    lets the visual geoms be weighed; ``cache_root`` keeps the geometric figures
    (inertia of the geometry, overlap of source shapes) by content; ``passive``: the
    passive second validation already stepped (:func:`check_energy`)."""
    d = home_data(m, d_home)
    checks: dict[str, dict[str, Any]] = {}
    failures: list[str] = []
    warnings: list[str] = []

    def add(name: str, result: tuple[dict[str, Any], list[str]]) -> None:
        checks[name] = result[0]
        failures.extend(result[1])

    # Implausible declared inertia is the description's (UR5's wrists, panda's link1 as
    # published): said, never a failure of the conversion's certificate
    inertia, implausible = check_inertia(ref, inertia_factor, cache_root)
    inertia["severity"] = "warning"
    checks["inertia"] = inertia
    warnings.extend(implausible)
    add("interpenetration", check_interpenetration(ref, m, d, penetration_m, cache_root))
    add("home_in_limits", check_home(ref, m, d))
    matrix = check_collision_matrix(m, ref)
    add("collision_matrix", (matrix, [] if matrix["ok"] else [f"collision: {matrix['detail']}"]))
    add("visual_massless", check_visuals(m, Path(model_path) if model_path else None))
    energy, energy_failures = check_energy(
        m, d, energy_growth, passive.result() if passive is not None else None
    )
    pairs = len(checks["interpenetration"]["pairs"])
    if not energy["ok"] and pairs:  # the likely cause, said where it shows
        note = f" ({pairs} geom pairs interpenetrate at home)"
        energy["detail"] += note
        energy_failures = [f + note for f in energy_failures]
    # Energy that grows in a passive second is said, not failed: the description's
    # own dynamics (or an overlap it has) can do it; an overlap the conversion added
    # already fails the interpenetration check
    energy["severity"] = "warning"
    checks["passive_energy"] = energy
    warnings.extend(energy_failures)
    return {"checks": checks, "failures": failures, "warnings": warnings}
