"""The contacts pass: contacts the conversion itself creates at home, resolved the way
Menagerie's authors resolve them by hand. It runs after ``extension``, on the
finished document.

Two kinds of contact push at a simulation's first step although the description
never asked for them:

* **The fixed base against its children.** A fixed-base robot's root is welded to
  the world, and MuJoCo filters no contact of the world's welded bodies with their
  children (it filters every other parent-child pair), so the root, and what is
  fixed to it, collides with the links its joints move. URDF users never expect
  that: MoveIt's setup disables adjacent links, as MuJoCo does below the base. Each
  pair of a body welded to the world and a child moved by a joint gets an
  ``<exclude>``, whether or not they touch at home, where MuJoCo could collide them
  (their ``contype``/``conaffinity`` allow it). A ``<pair>`` the description's
  ``<mujoco>`` writes still collides them: MuJoCo applies no exclusion to pairs.
* **A hull reaching into a neighbour.** A pair of bodies whose collision geoms
  MuJoCo finds more than :data:`~urdf2mjcf.solids.PENETRATION_M` deep in each other
  at home, while the description's ``<collision>`` shapes of the links concerned
  overlap by no more than that there (:func:`~urdf2mjcf.solids.overlap_depth`, the
  certificate's own measure and attribution, judged like it geom pair by geom
  pair: one such geom pair is enough), gets an ``<exclude>``. The collision
  pass has already cut what a finer decomposition fixes, a hollow part that its
  hull would fill (a tube of a telescoping arm); what remains is convex hulls of
  concave links, bridging a joint's clearance. An overlap the description's own
  shapes have is the description's: left, and listed by the certificate as such.

Each exclusion is a note of kind ``excluded`` (a change the certificate lists),
saying why and the depth it removes at home. Exclusions follow the description's
own ``<contact>`` content, the fixed base's first (in body order), then the
others (in body order): the same document gives the same bytes. An exclusion the
document already has is not written again. ``keep`` (``--keep-contacts``; the
URDF's ``<mujoco><collision contacts="keep"/></mujoco>``; the ``--actuator-config``
file's ``collision: contacts: keep``) writes none and compiles nothing.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from ..ir import Box, Capsule, Cylinder, Link, MeshRef, Model, Note, Sphere
from ..mjcf.compile import HomeCompiles, compile_home
from ..mjcf.document import Document, section
from ..solids import PENETRATION_M, Hull, Placed, Primitive, geom_solid, overlap_depth
from ..transforms import pose_matrix
from . import collision
from .actuators import config as actuator_file

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ContactsConfig:
    keep: bool = False
    """Write no exclusion (``--keep-contacts``); also said by the URDF's ``<mujoco>``
    and the actuator file (see the module)."""
    penetration_m: float = PENETRATION_M
    """Deeper than this at home, and the description's shapes not: the conversion's."""
    config_file: Path | None = None
    """The actuator file, whose ``collision: contacts`` may say ``keep``."""
    mujoco_extension: bool = True
    """Read ``<mujoco><collision contacts=.../>`` in the URDF."""


@dataclass(frozen=True)
class _Exclusion:
    bodies: tuple[int, int]
    """Body ids, the lower first."""
    depth_m: float
    """The deepest contact between the two at home (0: none)."""
    source_m: float | None
    """How deep the description's shapes overlap there (None: not measured)."""
    base: bool
    """A body welded to the world and its child."""
    moved: int = -1
    """The body a joint moves (a fixed base's pair): named in the note."""


def keeps(model: Model, cfg: ContactsConfig) -> bool:
    """Whether the contacts are kept as converted: the command line, else the URDF's
    ``<mujoco>``, else the actuator file (else resolved)."""
    if cfg.keep:
        return True
    said = collision.extension_contacts(model.robot) if cfg.mujoco_extension else None
    if said is None and cfg.config_file is not None:
        said = actuator_file.load(cfg.config_file).collision_contacts
    return said == "keep"


def run(
    result: Document, model: Model, cfg: ContactsConfig, compiles: HomeCompiles | None = None
) -> Document:
    """``result`` with an ``<exclude>`` for each contact the conversion created (see the
    module), and a note for each."""
    if keeps(model, cfg) or not any(model.collision_geoms.values()):
        return result
    import mujoco

    try:
        m, d = compile_home(
            result.root, result.files, shape_only=True, collision_only=True, compiles=compiles
        )
    except ValueError:  # validation reports what MuJoCo rejects, against the file written
        return result
    mujoco.mj_forward(m, d)
    found = _exclusions(model, m, d, _excluded(result.root, m), cfg.penetration_m)
    if not found:
        return result
    root = result.edit()
    contact = section(root, "contact")
    notes = []
    for ex in found:
        a, b = (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i) for i in ex.bodies)
        el = etree.SubElement(contact, "exclude")
        el.set("body1", a)
        el.set("body2", b)
        moved = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, ex.moved) if ex.moved >= 0 else b
        notes.append(Note("excluded", f"contact link '{a}' / link '{b}'", _message(ex, moved)))
    return replace(result, root=root, notes=result.notes + tuple(notes))


def _message(ex: _Exclusion, child: str) -> str:
    depth = (
        f"removes a contact {ex.depth_m * 1e3:.1f} mm deep at home"
        if ex.depth_m > 0
        else "no contact at home"
    )
    if ex.base:
        return (
            f"excluded: '{child}' is a child of the fixed base, whose contacts MuJoCo does "
            f"not filter as it does other parents' (MoveIt disables adjacent links); {depth}"
        )
    source = (
        "" if ex.source_m is None else f" (the description's shapes: {ex.source_m * 1e3:.1f} mm)"
    )
    return f"excluded: the conversion's collision geoms overlap at home; {depth}{source}"


def _excluded(root: etree._Element, m: Any) -> set[tuple[int, int]]:
    """Body pairs the document already excludes."""
    import mujoco

    out = set()
    for el in root.iterfind("contact/exclude"):
        ids = [
            mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, el.get(k) or "")
            for k in ("body1", "body2")
        ]
        if min(ids) >= 0:
            out.add((min(ids), max(ids)))
    return out


def _exclusions(
    model: Model, m: Any, d: Any, excluded: set[tuple[int, int]], penetration: float
) -> list[_Exclusion]:
    """The fixed base's pairs (in body order), then the other pairs the conversion
    created (in body order)."""
    owner = _geom_links(model, m)
    deepest: dict[tuple[int, int], float] = {}
    # body pair -> geom pair -> its deepest contact: (depth, normal from the first geom to
    # the second), the geoms in body order, as the certificate judges each geom pair
    by_geoms: dict[tuple[int, int], dict[tuple[int, int], tuple[float, np.ndarray]]] = {}
    for i in range(d.ncon):
        c = d.contact[i]
        g1, g2 = int(c.geom1), int(c.geom2)
        if g1 not in owner or g2 not in owner:
            continue  # a geom the description's <mujoco> added: its own business
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        if b1 == b2:
            continue
        normal = np.array(c.frame[:3], dtype=np.float64)  # from geom1 to geom2
        if b1 > b2:
            (b1, g1), (b2, g2), normal = (b2, g2), (b1, g1), -normal
        depth = -float(c.dist)
        deepest[(b1, b2)] = max(deepest.get((b1, b2), 0.0), depth)
        geoms = by_geoms.setdefault((b1, b2), {})
        if (g1, g2) not in geoms or depth > geoms[(g1, g2)][0]:
            geoms[(g1, g2)] = (depth, normal)
    out = []
    base_pairs = _base_pairs(model, m, owner)
    for pair, moved in base_pairs:
        if pair not in excluded:
            out.append(
                _Exclusion(pair, max(deepest.get(pair, 0.0), 0.0), None, base=True, moved=moved)
            )
    done = excluded | {pair for pair, _ in base_pairs}
    frames: dict[str, np.ndarray] | None = None
    placed: dict[str, Placed | None] = {}
    for pair in sorted(deepest):
        if pair in done or deepest[pair] <= penetration:
            continue
        if frames is None:
            frames = _link_frames(model, m, d)
        # The certificate fails a geom pair deeper than penetration whose links' shapes
        # are not: one such pair, and the body pair is the conversion's to resolve.
        ranked = sorted(by_geoms[pair].items(), key=lambda kv: (-kv[1][0], kv[0]))
        for (g1, g2), (depth, normal) in ranked:
            l1, l2 = owner[g1], owner[g2]
            if depth <= penetration:
                break
            near = (geom_solid(m, d, g1), geom_solid(m, d, g2))
            source = _source_overlap(model, (l1, l2), frames, placed, (normal, depth, near))
            if source is not None and source <= penetration:
                out.append(_Exclusion(pair, deepest[pair], source, base=False))
                break
    return out


def _geom_links(model: Model, m: Any) -> dict[int, str]:
    """Colliding geoms of the robot's links (by the names the collision pass gave them)
    -> their link."""
    names = {g.name: link for link, geoms in model.collision_geoms.items() for g in geoms}
    return {
        g: names[m.geom(g).name]
        for g in range(m.ngeom)
        if m.geom(g).name in names and (m.geom_contype[g] or m.geom_conaffinity[g])
    }


def _base_pairs(
    model: Model, m: Any, owner: Mapping[int, str]
) -> list[tuple[tuple[int, int], int]]:
    """(welded, child) body pairs of a fixed base that MuJoCo could collide, each with
    the body moved: a link moved by a joint whose parent link is welded to the world,
    and each link adjacent to it as MoveIt takes adjacency (its parent, and through
    links without collision geometry what lies beyond them) that is welded to the world
    too; both bodies with colliding geoms. A floating joint's child is no neighbour of
    anything: a free body falls onto the floor beside it and must meet it."""
    import mujoco

    robot = model.robot
    body_of: dict[str, int] = {}
    for link in robot.links:
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, link.name)
        if b < 0:  # fused into its parent's body (--fuse-fixed), which carries its site
            site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, link.name)
            b = int(m.site_bodyid[site]) if site >= 0 else -1
        if b >= 0:
            body_of[link.name] = b
    geoms: dict[int, list[int]] = {}
    for g in owner:
        geoms.setdefault(int(m.geom_bodyid[g]), []).append(g)
    neighbours: dict[str, set[str]] = {link.name: set() for link in robot.links}
    for j in robot.joints:
        if j.parent in neighbours and j.child in neighbours:
            neighbours[j.parent].add(j.child)
            neighbours[j.child].add(j.parent)

    def welded(name: str) -> bool:
        return name in body_of and int(m.body_weldid[body_of[name]]) == 0

    out = set()
    for j in robot.joints:
        if j.type in ("fixed", "floating") or not welded(j.parent) or welded(j.child):
            continue
        if j.child not in body_of:
            continue
        child = body_of[j.child]
        for other in _adjacent(j.child, neighbours, model):
            if welded(other) and _can_collide(
                m, geoms.get(body_of[other], []), geoms.get(child, [])
            ):
                out.add(((min(body_of[other], child), max(body_of[other], child)), child))
    return sorted(out)


def _adjacent(link: str, neighbours: Mapping[str, set[str]], model: Model) -> set[str]:
    """The links adjacent to ``link``: its neighbours in the tree, and through a neighbour
    without collision geometry (a frame, a bare mount) the links beyond it."""
    out: set[str] = set()
    seen, todo = {link}, [link]
    while todo:
        for n in sorted(neighbours[todo.pop()]):
            if n in seen:
                continue
            seen.add(n)
            out.add(n)
            if not model.collision_geoms.get(n):
                todo.append(n)
    return out


def _can_collide(m: Any, a: list[int], b: list[int]) -> bool:
    return any(
        (m.geom_contype[g1] & m.geom_conaffinity[g2])
        or (m.geom_contype[g2] & m.geom_conaffinity[g1])
        for g1 in a
        for g2 in b
    )


def _link_frames(model: Model, m: Any, d: Any) -> dict[str, np.ndarray]:
    """Each link's frame in the world at home: its body's, or (fused) its site's."""
    import mujoco

    out: dict[str, np.ndarray] = {}
    for link in model.robot.links:
        frame = np.eye(4)
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, link.name)
        if body >= 0:
            frame[:3, :3], frame[:3, 3] = d.xmat[body].reshape(3, 3), d.xpos[body]
        else:
            site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, link.name)
            if site < 0:
                continue
            frame[:3, :3], frame[:3, 3] = d.site_xmat[site].reshape(3, 3), d.site_xpos[site]
        out[link.name] = frame
    return out


def _source_overlap(
    model: Model,
    links: tuple[str, str],
    frames: Mapping[str, np.ndarray],
    placed: dict[str, Placed | None],
    contact: tuple[np.ndarray, float, tuple[Primitive | Hull | None, Primitive | Hull | None]],
) -> float | None:
    """How deep the two links' ``<collision>`` shapes overlap at home, also along the
    model's contact (its normal, depth and two geoms: :func:`~urdf2mjcf.solids.overlap_depth`,
    as the certificate measures it); None when one cannot be placed or measured."""
    l1, l2 = links
    for name in links:
        if name not in placed:
            link = model.robot.link_map.get(name)
            placed[name] = (
                _placed(model, link, frames[name]) if link is not None and name in frames else None
            )
    a, b = placed[l1], placed[l2]
    if a is None or b is None:
        return None
    try:
        normal, depth, (near_a, near_b) = contact
        near = (near_a, near_b) if near_a is not None and near_b is not None else None
        return overlap_depth(a, b, along=normal, limit=depth, near=near)
    except Exception:  # a mesh trimesh cannot test: not measured, so not excluded
        log.info("overlap of %s / %s not measured", l1, l2, exc_info=True)
        return None


def _placed(model: Model, link: Link, pose: np.ndarray) -> Placed | None:
    """The link's ``<collision>`` shapes (its meshes as loaded) placed at ``pose``."""
    import trimesh

    prims: list[Primitive] = []
    meshes: list[trimesh.Trimesh] = []
    for el in link.collisions:
        origin = pose_matrix(el.origin)
        g = el.geometry
        if isinstance(g, Box):
            prims.append(Primitive("box", np.asarray(g.size, float) / 2, origin))
        elif isinstance(g, Sphere):
            prims.append(Primitive("sphere", np.array([g.radius], float), origin))
        elif isinstance(g, Cylinder | Capsule):
            kind = "cylinder" if isinstance(g, Cylinder) else "capsule"
            prims.append(Primitive(kind, np.array([g.radius, g.length / 2], float), origin))
        elif isinstance(g, MeshRef):
            loaded = model.meshes.get((g.path, g.scale)) if g.path is not None else None  # type: ignore[arg-type]
            if loaded is None:
                return None
            mesh = trimesh.Trimesh(loaded.merged.vertices, loaded.merged.faces, process=True)
            mesh.apply_transform(origin)
            meshes.append(mesh)
    return Placed.of(prims, meshes, pose)
