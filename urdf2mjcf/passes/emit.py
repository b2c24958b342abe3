"""The emit pass: :class:`~urdf2mjcf.ir.Model` -> an MJCF document in MuJoCo Menagerie's style.

The document stays in memory as an element tree (:class:`~urdf2mjcf.mjcf.document.
Document`): the passes after this one (extension, scene, the facility's fold and tags)
change a copy of it, and it becomes text once, when it is written
(:func:`urdf2mjcf.mjcf.document.mjcf_bytes`).

Every URDF link becomes a body of the same name and every joint keeps its
name (fixed links are kept unless ``fuse_fixed``). A root link named
``world`` is MuJoCo's own world body. Numbers are written with ``repr`` so
doubles round-trip; the output is a pure function of the model.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np
from lxml import etree

from ..errors import ValidationError
from ..fmt import set_attrs
from ..ir import Actuator, BodyInertial, Camera, Geom, Joint, Link, Model, Note, Quat, Site, Vec3
from ..mjcf.document import Document
from ..transforms import (
    IDENTITY_QUAT,
    mujoco_fullinertia,
    pose_quat,
    split_transform,
    transform,
    vec3,
)

log = logging.getLogger(__name__)

EmitResult = Document
"""The document's old name (before ``urdf2mjcf.mjcf``), kept for a release."""

_Placed = TypeVar("_Placed", Geom, Site, Camera)

WORLD = "world"
MAX_BODY_DEPTH = 496
"""Nested bodies MuJoCo reads from one MJCF file: its XML reader (tinyxml2) stops at
500 nested elements (mujoco > worldbody > bodies > geom). Its compiler stops at 1023
(measured with MuJoCo 4.0)."""
_SCALAR = ("revolute", "continuous", "prismatic")
"""Joint types with one qpos number: the only ones a joint equality can couple."""


@dataclass(frozen=True)
class EmitConfig:
    fuse_fixed: bool = False
    """Merge links attached by fixed joints into their parent (each leaves a site)."""
    floating_base: bool = False
    """Give the root link a free joint (legged robots, mobile bases)."""
    model_name: str | None = None
    """``<mujoco model=...>``; default: the URDF robot name."""
    meshdir: str = "assets"
    mimic_solref: tuple[float, float] = (0.005, 1.0)
    """Stiff equality so mimic followers track their leader closely."""
    mimic_solimp: tuple[float, float, float] = (0.95, 0.99, 0.001)


# -- body tree ---------------------------------------------------------------


@dataclass
class _Body:
    name: str
    pos: Vec3 = (0.0, 0.0, 0.0)
    quat: Quat = IDENTITY_QUAT
    joint: Joint | None = None
    inertial: BodyInertial | None = None
    geoms: list[Geom] = field(default_factory=list)
    sites: list[Site] = field(default_factory=list)
    cameras: list[Camera] = field(default_factory=list)
    gravcomp: float = 0.0
    children: list[_Body] = field(default_factory=list)


def _moved(item: _Placed, t: np.ndarray) -> _Placed:
    """A geom, site or camera moved by the transform ``t`` (fusing a fixed link)."""
    pos, quat = split_transform(t @ transform(item.pos, item.quat))
    return replace(item, pos=pos, quat=quat)


def _is_frame(link: Link, model: Model) -> bool:
    """A link that is only a frame: no inertial, no geometry (tool0, optical frames)."""
    return (
        model.inertials.get(link.name) is None
        and not model.visual_geoms.get(link.name)
        and not model.collision_geoms.get(link.name)
    )


def _combine(a: BodyInertial | None, b: BodyInertial | None, t: np.ndarray) -> BodyInertial | None:
    """Inertial of ``a`` plus ``b`` given in a frame placed at ``t`` (parallel axis theorem)."""
    if b is None:
        return a
    r = t[:3, :3]
    com_b = t[:3, :3] @ np.array(b.pos) + t[:3, 3]
    ib = r @ _mat(b.fullinertia) @ r.T
    if a is None:
        return BodyInertial(b.mass, vec3(com_b), mujoco_fullinertia(ib), b.source)
    m = a.mass + b.mass
    com = (a.mass * np.array(a.pos) + b.mass * com_b) / m

    def shifted(inertia: np.ndarray, mass: float, c: np.ndarray) -> np.ndarray:
        d = c - com
        return inertia + mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))

    total = shifted(_mat(a.fullinertia), a.mass, np.array(a.pos)) + shifted(ib, b.mass, com_b)
    return BodyInertial(
        m,
        vec3(com),
        mujoco_fullinertia(total),
        "urdf" if a.source == b.source == "urdf" else "repaired",
    )


def _mat(fi: tuple[float, ...]) -> np.ndarray:
    ixx, iyy, izz, ixy, ixz, iyz = fi
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def _build_tree(model: Model, cfg: EmitConfig) -> _Body:
    robot = model.robot
    world = _Body(WORLD)

    sites: dict[str, list[Site]] = {}
    for site in model.sites:
        sites.setdefault(site.body, []).append(site)
    cameras: dict[str, list[Camera]] = {}
    for camera in model.cameras:
        cameras.setdefault(camera.body, []).append(camera)
    named_sites = {site.name for site in model.sites}
    keep = model.sensor_bodies()  # fusing these would change what their sensors read

    def make(link: str) -> _Body:
        body = _Body(link)
        body.inertial = model.inertials.get(link)
        body.geoms = list(model.visual_geoms.get(link, ())) + list(
            model.collision_geoms.get(link, ())
        )
        body.sites = list(sites.get(link, ()))
        if link != WORLD and link not in named_sites and _is_frame(robot.link_map[link], model):
            body.sites.insert(0, Site(link, link))  # frames stay findable: tool0, optical frames
        body.cameras = list(cameras.get(link, ()))
        body.gravcomp = model.gravcomp.get(link, 0.0)
        return body

    if robot.root is None:
        return world
    # Without recursion, so a chain of any depth works, and in time linear in the links:
    # each fused link's geoms, sites and cameras are moved once, by the transform from its
    # frame to the body it ends up in (composed parents first), not once per level. The
    # bodies come out as a depth-first walk fusing children into parents makes them:
    # inertials combined children first, items in pre-order, children in document order.
    order = robot.topological_links()  # pre-order, siblings in document order
    bodies = {link: make(link) for link in order}
    parent: dict[str, str] = {}
    fused: set[str] = set()
    for link in order:
        for joint in robot.child_joints.get(link, ()):
            child = bodies[joint.child]
            child.pos, child.quat = vec3(joint.origin.xyz), pose_quat(joint.origin)
            child.joint = joint if joint.type != "fixed" else None
            parent[joint.child] = link
            if cfg.fuse_fixed and joint.type == "fixed" and joint.child not in keep:
                fused.add(joint.child)
    if fused:
        _fuse_all(order, bodies, parent, fused, robot.child_joints)
    else:
        for link in order[1:]:
            bodies[parent[link]].children.append(bodies[link])
    root = bodies[robot.root]
    if robot.root == WORLD:
        world.geoms, world.children = root.geoms, root.children
        world.sites, world.cameras = root.sites, root.cameras
    else:
        world.children.append(root)
    return world


def _fuse_all(
    order: tuple[str, ...],
    bodies: dict[str, _Body],
    parent: dict[str, str],
    fused: set[str],
    child_joints: Mapping[str, Sequence[Joint]],
) -> None:
    """Fuse every link of ``fused`` into its parent's body (``order``: pre-order)."""
    owner: dict[str, str] = {}
    to_owner: dict[str, np.ndarray] = {}  # a fused link's frame -> its owner body's frame
    for link in order:
        if link not in fused:
            owner[link] = link
            continue
        up, body = parent[link], bodies[link]
        owner[link] = owner[up]
        t = transform(body.pos, body.quat)
        to_owner[link] = t if up not in fused else to_owner[up] @ t
    for link in reversed(order):  # children first, as a depth-first fuse combines them
        body = bodies[link]
        for joint in child_joints.get(link, ()):
            if joint.child in fused:
                child = bodies[joint.child]
                t = transform(child.pos, child.quat)
                body.inertial = _combine(body.inertial, child.inertial, t)
                body.gravcomp = body.gravcomp or child.gravcomp
    # a fused link leaves a site of its name unless one in its fused subtree has it
    holders: dict[str, list[str]] = {}
    for link in order:
        for site in bodies[link].sites:
            holders.setdefault(site.name, []).append(link)
    span = _spans(order, parent)
    for link in order[1:]:
        body, up = bodies[link], parent[link]
        home = bodies[owner[up]]  # the body it joins (a moving link is its own owner)
        if link not in fused:
            if up in fused:  # a moving child of a fused link: placed in the owner's frame
                body.pos, body.quat = split_transform(to_owner[up] @ transform(body.pos, body.quat))
            home.children.append(body)
            continue
        t = to_owner[link]
        first, last = span[link]
        named = any(
            owner[k] == owner[link] and first <= span[k][0] < last for k in holders.get(link, ())
        )
        if not named:
            pos, quat = (body.pos, body.quat) if up not in fused else split_transform(t)
            home.sites.append(Site(link, up, pos, quat))
        home.geoms += [_moved(g, t) for g in body.geoms]
        home.sites += [_moved(site, t) for site in body.sites]
        home.cameras += [_moved(camera, t) for camera in body.cameras]


def _spans(order: tuple[str, ...], parent: dict[str, str]) -> dict[str, tuple[int, int]]:
    """Each link's subtree as a range of pre-order positions: ``k`` is in ``link``'s
    subtree when ``span[link][0] <= span[k][0] < span[link][1]``."""
    index = {link: i for i, link in enumerate(order)}
    end = {link: i + 1 for i, link in enumerate(order)}
    for link in reversed(order[1:]):
        up = parent[link]
        end[up] = max(end[up], end[link])
    return {link: (index[link], end[link]) for link in order}


# -- XML ---------------------------------------------------------------------


def _pose_attrs(pos: Vec3, quat: Quat) -> dict[str, object]:
    return {
        "pos": pos if any(pos) else None,
        "quat": quat if tuple(quat) != IDENTITY_QUAT else None,
    }


def _limits(joint: Joint, notes: list[Note]) -> tuple[float, float] | None:
    limit = joint.limit
    if joint.range is None and limit is not None and joint.type in ("revolute", "prismatic"):
        if (limit.lower or 0.0) == (limit.upper or 0.0):
            notes.append(
                Note(
                    "warning",
                    f"joint '{joint.name}'",
                    "limit has no range (lower == upper); joint left unlimited",
                )
            )
        # lower > upper: unlimited, as urdfdom reads it; parse has warned (or failed, --strict)
    return joint.range


def _joint_elements(
    body_el: etree._Element,
    body: _Body,
    model: Model,
    at_world: bool,
    notes: list[Note],
    actuators: dict[str, Actuator],
) -> list[tuple[str, str, float]]:
    """Write the joint(s) of ``body``; returns (name, kind, home value) per qpos block."""
    joint = body.joint
    if joint is None:
        return []
    axis = joint.axis
    dyn = joint.dynamics
    common: dict[str, object] = {}
    if dyn is not None:
        common["damping"] = dyn.damping or None
        common["frictionloss"] = dyn.friction or None
    tuning = model.joint_tuning.get(joint.name)
    if tuning is not None:
        common["armature"] = tuning.armature or None
        if tuning.damping is not None:
            common["damping"] = tuning.damping or None
        if tuning.frictionloss is not None:
            common["frictionloss"] = tuning.frictionloss or None
    if joint.type in ("revolute", "continuous", "prismatic"):
        rng = _limits(joint, notes)
        el = etree.SubElement(body_el, "joint")
        set_attrs(el, name=joint.name)
        if joint.type == "prismatic":
            el.set("type", "slide")
        set_attrs(el, axis=axis, range=rng, **common)
        actuator = actuators.get(joint.name)
        effort = joint.limit.effort if joint.limit is not None else None
        if actuator is not None and actuator.forcerange is not None:
            set_attrs(
                el, actuatorfrcrange=actuator.forcerange
            )  # a configured limit beats the URDF's
        elif effort is not None and effort > 0:
            set_attrs(el, actuatorfrcrange=(-effort, effort))
        if actuator is not None and model.gravcomp:
            # gravity compensation as the controller's feed-forward, within its force limit
            el.set("actuatorgravcomp", "true")
        home = 0.0 if rng is None else min(max(0.0, rng[0]), rng[1])
        return [(joint.name, "scalar", home)]
    if joint.type == "floating":
        if at_world:
            set_attrs(etree.SubElement(body_el, "freejoint"), name=joint.name)
            return [(joint.name, "free", 0.0)]
        # Free joints are only allowed on top-level bodies: three slides and a ball.
        out = []
        for suffix, unit in (("x", (1, 0, 0)), ("y", (0, 1, 0)), ("z", (0, 0, 1))):
            set_attrs(
                etree.SubElement(body_el, "joint"),
                name=f"{joint.name}_{suffix}",
                type="slide",
                axis=unit,
                **common,
            )
            out.append((f"{joint.name}_{suffix}", "scalar", 0.0))
        set_attrs(
            etree.SubElement(body_el, "joint"), name=f"{joint.name}_rot", type="ball", **common
        )
        return out + [(f"{joint.name}_rot", "ball", 0.0)]
    if joint.type == "spherical":
        upper = joint.limit.upper if joint.limit is not None else None
        # A ball's range bounds its rotation angle: MuJoCo wants "0 max".
        rng = (0.0, upper) if upper is not None and upper > 0 else None
        set_attrs(
            etree.SubElement(body_el, "joint"), name=joint.name, type="ball", range=rng, **common
        )
        return [(joint.name, "ball", 0.0)]
    if joint.type == "planar":
        n = np.array(axis)
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        out = []
        for suffix, direction, kind in (("x", u, "slide"), ("y", v, "slide"), ("rot", n, "hinge")):
            set_attrs(
                etree.SubElement(body_el, "joint"),
                name=f"{joint.name}_{suffix}",
                type=kind,
                axis=vec3(direction),
                **common,
            )
            out.append((f"{joint.name}_{suffix}", "scalar", 0.0))
        return out
    raise AssertionError(joint.type)


def _geom_element(parent: etree._Element, g: Geom) -> None:
    el = etree.SubElement(parent, "geom")
    set_attrs(el, name=g.name, **{"class": g.role})
    set_attrs(el, type=g.type if g.type != "sphere" else None)
    if g.type == "mesh":
        set_attrs(el, mesh=g.mesh)
    else:
        set_attrs(el, size=g.size)
    set_attrs(el, **_pose_attrs(g.pos, g.quat))
    set_attrs(el, material=g.material, rgba=g.rgba)


def _body_contents(el: etree._Element, body: _Body) -> None:
    """Geoms, sites and cameras of a body (or of the world body)."""
    for g in body.geoms:
        _geom_element(el, g)
    for site in body.sites:
        size = site.size if site.size != Site.size else None  # MuJoCo's default site size
        set_attrs(etree.SubElement(el, "site"), name=site.name, **_pose_attrs(site.pos, site.quat))
        set_attrs(el[-1], type=site.type if site.type != "sphere" else None, size=size)
    for cam in body.cameras:
        set_attrs(etree.SubElement(el, "camera"), name=cam.name, **_pose_attrs(cam.pos, cam.quat))
        set_attrs(
            el[-1],
            fovy=cam.fovy,
            resolution=cam.resolution,
            output="rgb depth" if cam.depth else None,
        )


def _inertial_element(parent: etree._Element, inertial: BodyInertial) -> None:
    el = etree.SubElement(parent, "inertial")
    ixx, iyy, izz, ixy, ixz, iyz = inertial.fullinertia
    set_attrs(el, pos=inertial.pos, mass=inertial.mass)
    if ixy == ixz == iyz == 0.0:
        set_attrs(el, diaginertia=(ixx, iyy, izz))
    else:
        set_attrs(el, fullinertia=inertial.fullinertia)


def _body_elements(
    worldbody: etree._Element, bodies: list[_Body], model: Model, qpos: list, notes: list[Note]
) -> None:
    """Write the world's child ``bodies`` and their subtrees in document order (an
    explicit stack, so any depth)."""
    actuators: dict[str, Actuator] = {}
    for a in model.actuators:
        actuators.setdefault(a.joint, a)  # the first actuator of a joint, looked up per joint
    stack = [(worldbody, body, True) for body in reversed(bodies)]
    while stack:
        parent, body, at_world = stack.pop()
        el = etree.SubElement(parent, "body")
        set_attrs(
            el, name=body.name, **_pose_attrs(body.pos, body.quat), gravcomp=body.gravcomp or None
        )
        if body.inertial is not None:
            _inertial_element(el, body.inertial)
        qpos.extend(
            (name, kind, home, body)
            for name, kind, home in _joint_elements(el, body, model, at_world, notes, actuators)
        )
        _body_contents(el, body)
        stack.extend((el, child, False) for child in reversed(body.children))


_ACTUATOR_ATTRS = {
    "position": ("kp", "kv", "forcerange"),
    "velocity": ("kv", "forcerange"),
    "motor": ("forcerange",),
}


def _actuator_attrs(a: Actuator) -> dict[str, object]:
    values = {"kp": a.kp, "kv": a.kv, "forcerange": a.forcerange}
    return {k: values[k] for k in _ACTUATOR_ATTRS[a.kind] if values[k] is not None}


def _actuator_section(mj: etree._Element, default: etree._Element, model: Model) -> None:
    """Actuators; those sharing a class take the class's gains from a default class."""
    if not model.actuators:
        return
    classes: dict[str, dict[str, dict[str, object]]] = {}
    for a in model.actuators:
        if a.actuator_class:
            classes.setdefault(a.actuator_class, {}).setdefault(a.kind, _actuator_attrs(a))
    for name, kinds in classes.items():
        cls = etree.SubElement(default, "default")
        cls.set("class", name)
        for kind, attrs in kinds.items():
            set_attrs(etree.SubElement(cls, kind), **attrs)
    section = etree.SubElement(mj, "actuator")
    for a in model.actuators:
        inherited = classes.get(a.actuator_class or "", {}).get(a.kind, {})
        attrs = {k: v for k, v in _actuator_attrs(a).items() if inherited.get(k) != v}
        el = etree.SubElement(section, a.kind)
        set_attrs(el, name=a.name, **({"class": a.actuator_class} if a.actuator_class else {}))
        set_attrs(el, joint=a.joint, ctrlrange=a.ctrlrange, **attrs)


def _sensor_section(mj: etree._Element, model: Model) -> None:
    if not model.sensors:
        return
    section = etree.SubElement(mj, "sensor")
    for sensor in model.sensors:
        set_attrs(
            etree.SubElement(section, sensor.type),
            name=sensor.name,
            site=sensor.site,
            joint=sensor.joint,
            objtype=sensor.objtype,
            objname=sensor.objname,
            noise=sensor.noise,
            cutoff=sensor.cutoff,
        )


ROS_TOPIC_TEXT = "ros2:{kind}:{key}"
"""A ``<custom><text>`` name: its ``data`` is the topic, then the frame (if named)."""


def _custom_section(mj: etree._Element, model: Model) -> None:
    """The description's ROS topics for its sensors, where a server reads them."""
    if not model.ros_topics:
        return
    section = etree.SubElement(mj, "custom")
    for t in model.ros_topics:
        data = t.topic if t.frame_id is None else f"{t.topic} {t.frame_id}"
        set_attrs(
            etree.SubElement(section, "text"),
            name=ROS_TOPIC_TEXT.format(kind=t.kind, key=t.key),
            data=data,
        )


def _scalar_qpos_index(entries: list) -> list[tuple[int, str]]:
    """(qpos address, joint name) of the one-number joints, in qpos order."""
    out, adr = [], 0
    for name, kind, _home, _body in entries:
        if kind == "scalar":
            out.append((adr, name))
        adr += {"free": 7, "ball": 4}.get(kind, 1)
    return out


def _home_qpos(entries: list, model: Model) -> tuple[float, ...]:
    """Joint zero clamped into its range; mimic followers satisfy their constraint."""
    values: dict[str, float] = {name: home for name, kind, home, _ in entries if kind == "scalar"}
    values.update({k: v for k, v in model.home.items() if k in values})
    for joint in model.robot.joints:
        if joint.name in model.home:
            continue
        if joint.mimic is not None and joint.name in values and joint.mimic.joint in values:
            values[joint.name] = (
                joint.mimic.multiplier * values[joint.mimic.joint] + joint.mimic.offset
            )
    out: list[float] = []
    for name, kind, _home, body in entries:
        if kind == "free":
            out += [*body.pos, *body.quat]
        elif kind == "ball":
            out += [1.0, 0.0, 0.0, 0.0]
        else:
            out.append(values[name])
    return tuple(out)


def _check_depth(world: _Body, model: Model, cfg: EmitConfig) -> None:
    """Fail with the limit named when MuJoCo could not read the body tree."""
    first, deepest = None, 0
    stack = [(body, 1) for body in reversed(world.children)]
    while stack:
        body, depth = stack.pop()
        deepest = max(deepest, depth)
        if depth > MAX_BODY_DEPTH and first is None:
            first = body.name
        stack.extend((child, depth + 1) for child in reversed(body.children))
    if first is None:
        return
    hint = ""
    if not cfg.fuse_fixed and any(j.type == "fixed" for j in model.robot.joints):
        hint = "; --fuse-fixed merges links attached by fixed joints into one body"
    raise ValidationError(
        f"is body {MAX_BODY_DEPTH + 1} of a kinematic tree {deepest} bodies deep; MuJoCo "
        f"reads at most {MAX_BODY_DEPTH} nested bodies from an MJCF file (its XML reader "
        f"stops at 500 nested elements, its compiler at 1023 nested bodies){hint}",
        file=model.robot.source,
        element=f"link '{first}'",
    )


def run(model: Model, cfg: EmitConfig) -> Document:
    robot = model.robot
    notes: list[Note] = []
    tree = _build_tree(model, cfg)
    _check_depth(tree, model, cfg)
    if (
        cfg.floating_base
        and robot.root not in (None, WORLD)
        and tree.children
        and tree.children[0].joint is None
    ):
        root = tree.children[0]
        root.joint = Joint(
            name=f"{root.name}_freejoint", type="floating", parent=WORLD, child=root.name
        )

    mj = etree.Element("mujoco", model=cfg.model_name or robot.name)
    set_attrs(
        etree.SubElement(mj, "compiler"),
        angle="radian",
        meshdir=cfg.meshdir,
        texturedir=cfg.meshdir,
        assetdir=cfg.meshdir,  # height fields: MuJoCo finds them through assetdir when included
        autolimits="true",
        inertiafromgeom="false",  # inertials are ours: from the URDF, repaired or estimated
    )
    set_attrs(etree.SubElement(mj, "option"), integrator="implicitfast")
    if model.cameras:  # offscreen buffers must hold the largest described image
        width = max(640, *(c.resolution[0] for c in model.cameras))
        height = max(480, *(c.resolution[1] for c in model.cameras))
        if (width, height) != (640, 480):
            visual = etree.SubElement(mj, "visual")
            set_attrs(etree.SubElement(visual, "global"), offwidth=width, offheight=height)

    default = etree.SubElement(mj, "default")
    set_attrs(
        etree.SubElement(etree.SubElement(default, "default"), "geom"),
        contype=0,
        conaffinity=0,
        group=2,
        density=0,
    )
    default[0].set("class", "visual")
    set_attrs(etree.SubElement(etree.SubElement(default, "default"), "geom"), group=3)
    default[1].set("class", "collision")

    files: dict[str, bytes] = {}
    if model.textures or model.materials or model.mesh_assets:
        asset = etree.SubElement(mj, "asset")
        for tex in model.textures:
            set_attrs(etree.SubElement(asset, "texture"), name=tex.name, type="2d", file=tex.file)
            files[f"{cfg.meshdir}/{tex.file}"] = tex.data
        for mat in model.materials:
            set_attrs(
                etree.SubElement(asset, "material"),
                name=mat.name,
                rgba=mat.rgba,
                texture=mat.texture,
            )
        for mesh in model.mesh_assets:
            # Body inertia never comes from meshes here (inertiafromgeom="false"),
            # and "shell" is the one mode MuJoCo accepts for flat and open meshes.
            set_attrs(
                etree.SubElement(asset, "mesh"), name=mesh.name, file=mesh.file, inertia="shell"
            )
            files[f"{cfg.meshdir}/{mesh.file}"] = mesh.data

    worldbody = etree.SubElement(mj, "worldbody")
    _body_contents(worldbody, tree)
    entries: list = []
    _body_elements(worldbody, tree.children, model, entries, notes)

    # The world link's geoms against its children: the contacts pass's (passes/contacts.py)

    mimics = []
    for j in robot.joints:
        if j.mimic is None:
            continue
        leader = robot.joint_map[j.mimic.joint]
        if j.type == "fixed" or leader.type == "fixed":
            message = (
                f"mimics '{leader.name}' ({leader.type}) but one of them is fixed; mimic ignored"
            )
            notes.append(Note("warning", f"joint '{j.name}'", message))
            continue
        if j.type not in _SCALAR or leader.type not in _SCALAR:
            message = (
                f"{j.type} joint mimics '{leader.name}' ({leader.type}); MuJoCo couples only "
                "one-number joints; mimic ignored"
            )
            notes.append(Note("warning", f"joint '{j.name}'", message))
            continue
        mimics.append(j)
    if mimics:
        equality = etree.SubElement(mj, "equality")
        for j in mimics:
            assert j.mimic is not None
            set_attrs(
                etree.SubElement(equality, "joint"),
                name=f"{j.name}_mimic",
                joint1=j.name,
                joint2=j.mimic.joint,
                polycoef=(j.mimic.offset, j.mimic.multiplier, 0, 0, 0),
                solref=cfg.mimic_solref,
                solimp=cfg.mimic_solimp,
            )

    _actuator_section(mj, default, model)
    _sensor_section(mj, model)
    _custom_section(mj, model)

    qpos = _home_qpos(entries, model)
    if qpos:
        key = set_attrs(
            etree.SubElement(etree.SubElement(mj, "keyframe"), "key"), name="home", qpos=qpos
        )
        if model.actuators:  # servos hold the home pose from the first step
            at = {name: qpos[i] for i, name in _scalar_qpos_index(entries)}
            ctrl = [at.get(a.joint, 0.0) if a.kind == "position" else 0.0 for a in model.actuators]
            set_attrs(key, ctrl=ctrl)

    return Document(root=mj, files=files, qpos_home=qpos, notes=tuple(notes))
