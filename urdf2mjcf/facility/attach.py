"""Attach compiled components into the facility's world: MJCF's attach, on our own tree.

Each component is converted once, on its own, into ``components/<name>/``; the
document written there is the one attached here. Attaching copies the component's
world body into the scene's, moved to its placement, and brings along everything
its bodies name:

* ``asset``: textures, materials and meshes by name. Our names carry a hash of their
  content (``steel_3fb0ffebc3``), so two components sharing one share the element;
  the same name with other content is an error.
* ``default``: classes the scene lacks are added. A class the scene defines is the
  scene's: the world's ``collision`` class is the facility's contact filtering
  (``docs/facility.md``, "Contact classes"), which a component compiled on its own
  does not have. Any other difference is an error.
* ``contact``, ``equality``, ``tendon``, ``actuator``, ``sensor``: appended in order.
* the ``home`` key: the component's positions (a free root body's moved with it) and
  controls after the scene's, the order MuJoCo gives its joints and actuators.

The scene keeps its own ``compiler`` (which must match the component's: the same
angles and folders), ``option``, ``size``, ``visual`` and ``statistic``.

``MjSpec.attach`` does the same for a compiled spec; we attach trees because the
facility is written by our byte-stable writer (``docs/architecture.md``, "One model
in memory from emit to disk").
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from ..errors import InputError
from ..fmt import fmt_vec
from ..ir import Quat
from ..mjcf.document import Document, section
from ..mjcf.joints import joint_qpos0, joint_width, joints
from ..transforms import canonical_quat, quat_mul, quat_to_matrix

APPENDED = ("contact", "equality", "tendon", "actuator", "sensor")
"""Sections whose children are appended in the component's order."""
KEPT = ("option", "size", "visual", "statistic")
"""Sections the scene keeps as they are."""
PLACED = ("body", "geom", "site", "camera", "light", "frame")
"""Elements that may sit in the world body; each is moved to the placement."""
_ORIENTATIONS = ("euler", "axisangle", "xyaxes", "zaxis", "fromto")
_NAMED = ("body", "joint", "freejoint", "geom", "site", "camera", "light")


@dataclass(frozen=True)
class Part:
    """A component's document and where its world frame goes in the scene."""

    name: str
    """The component's name in the recipe (errors name it)."""
    result: Document
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    """w x y z."""


def yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2)))


def _vec(el: Any, key: str, default: str) -> np.ndarray:
    return np.array([float(v) for v in el.get(key, default).split()])


@dataclass
class _Placement:
    pos: np.ndarray
    quat: Quat
    name: str
    file: Path | str | None

    def point(self, p: np.ndarray) -> np.ndarray:
        return self.pos + quat_to_matrix(self.quat) @ p

    def rotation(self, q: np.ndarray) -> np.ndarray:
        # w >= 0, as our writer gives every quat
        unit = q / np.linalg.norm(q)
        return np.array(canonical_quat(quat_mul(self.quat, (unit[0], unit[1], unit[2], unit[3]))))

    def move(self, el: Any) -> None:
        """Place a world-body element (its pose given in the component's world)."""
        given = [k for k in _ORIENTATIONS if el.get(k) is not None]
        if given:
            raise InputError(
                f"cannot place <{el.tag}> given by {given[0]}: attach needs pos and quat",
                file=self.file,
                element=f"components.{self.name}",
            )
        # as our writer: a zero position and the identity rotation are left out
        pos = self.point(_vec(el, "pos", "0 0 0"))
        _set(el, "pos", pos, not pos.any())
        if el.tag == "light":
            if el.get("dir") is not None:
                rotated = quat_to_matrix(self.quat) @ _vec(el, "dir", "0 0 -1")
                el.set("dir", fmt_vec(rotated.tolist()))
        else:
            quat = self.rotation(_vec(el, "quat", "1 0 0 0"))
            _set(el, "quat", quat, quat[0] == 1.0)


def _set(el: Any, key: str, value: np.ndarray, default: bool) -> None:
    if default:
        el.attrib.pop(key, None)
    else:
        el.set(key, fmt_vec(value.tolist()))


def _same(a: Any, b: Any) -> bool:
    return bool(etree.tostring(a, method="c14n") == etree.tostring(b, method="c14n"))


def _home(root: Any) -> tuple[list[float] | None, list[float] | None]:
    key = next((k for k in root.iterfind("keyframe/key") if k.get("name") == "home"), None)
    if key is None:
        return None, None
    qpos = [float(v) for v in key.get("qpos", "").split()] or None
    ctrl = [float(v) for v in key.get("ctrl", "").split()] or None
    return qpos, ctrl


@dataclass
class Attach:
    """Attach ``parts`` into the scene's document (an ``api.ModelPass``)."""

    parts: Sequence[Part]
    recipe: Path | str | None = None
    attached: list[str] = field(default_factory=list)
    """The components attached, in order (after the pass has run)."""

    def __call__(self, scene: Document) -> Document:
        if not self.parts:
            return scene
        root = scene.edit()
        files = dict(scene.files)
        # the scene's own joints and actuators come first, as MuJoCo orders them
        home_qpos, home_ctrl = _home(root)
        qpos = home_qpos or [v for el in joints(root) for v in joint_qpos0(el)]
        ctrl = home_ctrl or [0.0] * len(section(root, "actuator"))
        names = _names(root)
        for part in self.parts:
            part_qpos, part_ctrl = self._attach(root, files, part, names)
            qpos += part_qpos
            ctrl += part_ctrl
            self.attached.append(part.name)
        keyframe = section(root, "keyframe")
        key = next((k for k in keyframe if k.get("name") == "home"), None)
        if key is None:
            key = etree.SubElement(keyframe, "key", name="home")
        if qpos:
            key.set("qpos", fmt_vec(qpos))
        if any(ctrl):
            key.set("ctrl", fmt_vec(ctrl))
        if not len(key.attrib) > 1:
            keyframe.remove(key)
        if not len(keyframe):
            root.remove(keyframe)
        for tag in APPENDED:  # no empty sections
            found = root.find(tag)
            if found is not None and not len(found):
                root.remove(found)
        return replace(scene, root=root, files=files, qpos_home=tuple(qpos))

    def _error(self, part: Part, message: str) -> InputError:
        return InputError(message, file=self.recipe, element=f"components.{part.name}")

    def _attach(
        self, root: Any, files: dict[str, bytes], part: Part, names: dict[str, set[str]]
    ) -> tuple[list[float], list[float]]:
        child = part.result.root
        mine, theirs = root.find("compiler"), child.find("compiler")
        if (mine is None) != (theirs is None) or (
            mine is not None and dict(mine.attrib) != dict(theirs.attrib)
        ):
            raise self._error(part, "its <compiler> differs from the scene's")
        self._defaults(root, child, part)
        self._assets(root, files, child, part)
        place = _Placement(np.array(part.pos), part.quat, part.name, self.recipe)
        child_world = child.find("worldbody")
        moved = copy.deepcopy(child_world) if child_world is not None else etree.Element("w")
        moved_joints = list(moved.iter("joint", "freejoint"))
        qpos = _home(child)[0] or [v for el in moved_joints for v in joint_qpos0(el)]
        if len(qpos) != sum(joint_width(el) for el in moved_joints):
            raise self._error(part, "its home key does not match its joints")
        at = 0
        for el in moved_joints:
            width = joint_width(el)
            if width == 7:
                if el.getparent().getparent() is not moved:
                    raise self._error(part, "a free joint below its root bodies")
                p = place.point(np.array(qpos[at : at + 3]))
                q = place.rotation(np.array(qpos[at + 3 : at + 7]))
                qpos[at : at + 7] = p.tolist() + q.tolist()
            at += width
        self._check_names(moved, names, part)
        world = section(root, "worldbody")
        for el in list(moved):
            if not isinstance(el.tag, str):
                continue
            if el.tag not in PLACED:
                raise self._error(part, f"cannot place <{el.tag}> of its world body")
            place.move(el)
            world.append(el)
        for tag in APPENDED:
            found = child.find(tag)
            if found is None or not len(found):
                continue
            target = section(root, tag)
            for el in found:
                target.append(copy.deepcopy(el))
        actuators = child.find("actuator")
        ctrl = _home(child)[1] or [0.0] * (len(actuators) if actuators is not None else 0)
        return qpos, ctrl

    def _defaults(self, root: Any, child: Any, part: Part) -> None:
        theirs = child.find("default")
        if theirs is None:
            return
        mine = section(root, "default")
        classes = {d.get("class"): d for d in mine.iterfind("default")}
        for el in theirs:
            if not isinstance(el.tag, str):
                continue
            if el.tag != "default":  # the main class: one for the whole scene
                same = [m for m in mine if m.tag == el.tag]
                if not same or not _same(same[0], el):
                    raise self._error(part, f"its main default <{el.tag}> differs from the scene's")
                continue
            name = el.get("class")
            if name not in classes:
                mine.append(copy.deepcopy(el))
                classes[name] = el
            # else the scene's class stands (the world's contact classes)

    def _assets(self, root: Any, files: dict[str, bytes], child: Any, part: Part) -> None:
        theirs = child.find("asset")
        if theirs is None:
            return
        mine = section(root, "asset")
        have = {(el.tag, el.get("name")): el for el in mine}
        for el in theirs:
            if not isinstance(el.tag, str):
                continue
            key = (el.tag, el.get("name"))
            if key in have:
                if not _same(have[key], el):
                    raise self._error(
                        part, f"its {el.tag} '{el.get('name')}' differs from the scene's"
                    )
                continue
            mine.append(copy.deepcopy(el))
            have[key] = el
        for path, data in part.result.files.items():
            if files.setdefault(path, data) != data:
                raise self._error(part, f"its file {path} differs from the scene's")

    def _check_names(self, moved: Any, names: dict[str, set[str]], part: Part) -> None:
        for el in moved.iter(*_NAMED):
            name = el.get("name")
            if name is None:
                continue
            kind = "joint" if el.tag == "freejoint" else el.tag
            if name in names.setdefault(kind, set()):
                raise self._error(part, f"its {kind} '{name}' is already in the scene")
            names[kind].add(name)


def _names(root: Any) -> dict[str, set[str]]:
    out: dict[str, set[str]] = {}
    world = root.find("worldbody")
    if world is not None:
        for el in world.iter(*_NAMED):
            if el.get("name") is not None:
                kind = "joint" if el.tag == "freejoint" else el.tag
                out.setdefault(kind, set()).add(el.get("name"))
    return out
