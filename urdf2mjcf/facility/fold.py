"""Fold the facility's static fixture geoms into the body they are welded to.

A mockup's static parts (a bench's panels, a frame's posts) are links joined by
fixed joints: each becomes a body of its own, and each body with a collision
geom costs MuJoCo's broad phase every step (it bounds the body over all its
geoms, sorts and sweeps it), though a part welded to its neighbours can only
ever move with them. Moving such a geom into the body it is welded to changes
no contact: MuJoCo filters pairs by weld body, and the geom keeps its name,
size, classes and pose in the world. The bodies stay where they were, with
their names, frames, sites and visual geoms, so every name the runner and the
demo files use still resolves; only a contact's body changes, and
``facility.json`` lists each moved geom with the link it was described on
(``"folded_geoms"``), which the runner reports instead.

What moves: a named collision geom that is a fixture (its class cannot touch its
own class: ``contype & conaffinity == 0``; the parts that collide with everything,
the robot and the bag, never move), out of a body without joints, into the
nearest ancestor that has a joint or stands on the world body (a component's
root, which the Gymnasium environments move on reset). It never goes into the
world body itself, never out of or into a body named by an ``<exclude>`` or a
sensor (a touch sensor sums the contacts of its site's body), and never across a
``childclass``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ValidationError
from ..fmt import fmt_vec
from ..mjcf.compile import compile_home
from ..mjcf.document import Document

MANIFEST_KEY = "folded_geoms"
_ORIENTATIONS = ("euler", "axisangle", "xyaxes", "zaxis", "fromto")
_SHAPE = ("type", "size", "mesh", "hfield", "pos", "quat", *_ORIENTATIONS)


def _pose(el: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """An element's pos and unit quat (w x y z), None when given any other way."""
    if any(el.get(key) is not None for key in _ORIENTATIONS):
        return None
    pos = np.array([float(v) for v in el.get("pos", "0 0 0").split()])
    quat = np.array([float(v) for v in el.get("quat", "1 0 0 0").split()])
    return pos, quat / np.linalg.norm(quat)


def _compose(
    parent: tuple[np.ndarray, np.ndarray], child: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """``child`` given in ``parent``'s frame, in the frame ``parent`` is given in."""
    import mujoco

    rotated, quat = np.zeros(3), np.zeros(4)
    mujoco.mju_rotVecQuat(rotated, child[0], parent[1])
    mujoco.mju_mulQuat(quat, parent[1], child[1])
    return parent[0] + rotated, quat / np.linalg.norm(quat)


def _pinned(m: Any) -> set[int]:
    """Bodies whose geoms must stay: named by an exclude or by a sensor."""
    import mujoco

    obj = mujoco.mjtObj
    out = set()
    for signature in m.exclude_signature:
        out |= {int(signature) >> 16, int(signature) & 0xFFFF}
    for s in range(m.nsensor):
        for kind, ident in (
            (m.sensor_objtype[s], m.sensor_objid[s]),
            (m.sensor_reftype[s], m.sensor_refid[s]),
        ):
            if ident < 0:
                continue
            if kind == obj.mjOBJ_SITE:
                out.add(int(m.site_bodyid[ident]))
            elif kind in (obj.mjOBJ_BODY, obj.mjOBJ_XBODY):
                out.add(int(ident))
            elif kind == obj.mjOBJ_GEOM:
                out.add(int(m.geom_bodyid[ident]))
    return out


def _target(m: Any, body: int, pinned: set[int]) -> list[int]:
    """The bodies from ``body`` up to where its fixtures go (last), ``[body]`` when
    they stay."""
    path = [body]
    while True:
        parent = int(m.body_parentid[path[-1]])
        if parent == 0 or parent in pinned:
            return path
        path.append(parent)
        if m.body_jntnum[parent] > 0:
            return path


@dataclass
class Folded:
    moved: dict[str, str] = field(default_factory=dict)
    """Each geom moved into its weld body -> the body (link) it was described on."""
    merged: list[str] = field(default_factory=list)
    """Fixtures that took over their visual twin (same shape and pose): drawn themselves."""


def _visual_group(root: Any) -> str | None:
    """The group of the scene's ``visual`` default class, when it says one."""
    for default in root.iter("default"):
        if default.get("class") == "visual":
            geom = default.find("geom")
            if geom is not None and geom.get("contype") == geom.get("conaffinity") == "0":
                return geom.get("group")
    return None


def _twin(geom: Any, group: str | None) -> Any | None:
    """An unnamed visual geom beside ``geom`` with the same shape and pose."""
    if group is None:
        return None
    for other in geom.getparent():
        if (
            other.tag == "geom"
            and other is not geom
            and other.get("class") == "visual"
            and other.get("name") is None
            and not any(other.get(k) is not None for k in ("group", "contype", "conaffinity"))
            and all(other.get(k) == geom.get(k) for k in _SHAPE)
        ):
            return other
    return None


class Fold:
    """The fold as a pass on the facility's document in memory (``api.ModelPass``): it
    compiles a copy to learn the bodies, welds and contact classes, and returns the
    folded document; what it did is left in :attr:`folded`."""

    def __init__(self, recipe: Path | None = None) -> None:
        self.folded = Folded()
        self.recipe = recipe
        """Named by the error when MuJoCo rejects the model (a --set path to a file that
        is no height field, say)."""

    def __call__(self, result: Document) -> Document:
        try:
            m, _ = compile_home(result.root, result.files)
        except ValueError as exc:  # MuJoCo's: bad input, not a bug of ours
            message = " ".join(str(exc).split())
            raise ValidationError(
                f"MuJoCo rejected the built facility: {message}", file=self.recipe
            ) from None
        root = result.edit()
        self.folded = fold_fixtures(root, m)
        if not (self.folded.moved or self.folded.merged):
            return result
        return replace(result, root=root)


def fold_fixtures(root: Any, m: Any) -> Folded:
    """Move the static fixture geoms of the MJCF document ``root`` (an element tree,
    compiled as ``m``; changed in place) into their weld bodies, in document order. A
    fixture whose visual twin (an unnamed geom of the ``visual`` class with the same
    shape and pose on the same body) exists takes over its material and group and the
    twin goes: one geom to pose and bound instead of two, drawn the same."""
    elements = {b.get("name"): b for b in root.iter("body") if b.get("name")}
    pinned = _pinned(m)
    group = _visual_group(root)
    out = Folded()
    for geom in list(root.iter("geom")):
        name = geom.get("name")
        owner = geom.getparent()
        if not name or owner is None or owner.tag != "body":
            continue
        g = m.geom(name).id
        contype, conaffinity = int(m.geom_contype[g]), int(m.geom_conaffinity[g])
        body = int(m.geom_bodyid[g])
        if not (contype | conaffinity) or contype & conaffinity:
            continue  # visual, or colliding with its own kind (robot, bag)
        twin = _twin(geom, group)
        if twin is not None:
            for key in ("material", "rgba"):
                if twin.get(key) is not None:
                    geom.set(key, twin.get(key))
            geom.set("group", group)
            _remove(owner, twin)
            out.merged.append(name)
        if body in pinned or m.body_jntnum[body] > 0:
            continue
        path = _target(m, body, pinned)
        found = [elements.get(m.body(b).name) for b in path]
        if len(path) == 1 or any(el is None or el.get("childclass") for el in found):
            continue
        chain: list[Any] = found
        if any(el.getparent() is not chain[i + 1] for i, el in enumerate(chain[:-1])):
            continue  # a <frame> between them
        pose = _pose(geom)
        frames = [_pose(el) for el in chain[:-1]]
        if pose is None or any(f is None for f in frames):
            continue
        for frame in frames:
            assert frame is not None
            pose = _compose(frame, pose)
        geom.set("pos", fmt_vec(pose[0]))
        if np.array_equal(pose[1], [1.0, 0.0, 0.0, 0.0]):
            geom.attrib.pop("quat", None)
        else:
            geom.set("quat", fmt_vec(pose[1]))
        target = chain[-1]
        _remove(owner, geom)
        target.insert(_after_geoms(target), geom)
        out.moved[name] = owner.get("name")
    return out


def _after_geoms(body: Any) -> int:
    """Index after the body's last geom (before its sites and child bodies)."""
    last = max((i for i, el in enumerate(body) if el.tag in ("inertial", "geom")), default=-1)
    return last + 1


def _remove(parent: Any, child: Any) -> None:
    parent.remove(child)  # lxml would keep its tail; the writer indents anyway
