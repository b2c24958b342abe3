"""The parse pass: URDF text -> :class:`~urdf2mjcf.ir.Robot` in a new :class:`~urdf2mjcf.ir.Model`.

Checks the structure URDF requires (unique names, known joint types, one
root, a tree) and resolves every resource URI to an absolute path. Elements
that later passes map (``ros2_control``, ``transmission``, ``gazebo``,
``mujoco``) are kept verbatim as :class:`~urdf2mjcf.ir.Extension`.

Where urdfdom is strict but other simulators read a file anyway, so do we,
each liberty one warning naming file and element (an error with ``strict``):
extra numbers in a vector (the first N are used), ``lower > upper`` (the
joint is unlimited), ``spherical``/``ball`` joints, ``<plane>`` and unknown
geometry, zero-size shapes (dropped). Link frames are never changed.

The URDF version is read as urdfdom 6 reads ``<robot version="x.y">`` (1.0 when
absent; 1.0, 1.1 and 1.2 known, any other an error): from 1.1 on an origin may
give its rotation as ``quat_xyzw`` instead of ``rpy`` (both is an error), which a
1.0 file ignores with a warning; ``<capsule>`` is 1.1's (read in a 1.0 file too,
as other simulators do, with a warning); 1.2's ``acceleration``, ``deceleration``
and ``jerk`` joint limits are kept for the report (MuJoCo does not enforce them)
and ignored, with a warning, in an older file.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

from lxml import etree

from ..errors import InputError, PackageNotFoundError, URDFError
from ..ir import (
    JOINT_TYPES,
    Box,
    Capsule,
    Collision,
    Cylinder,
    Dynamics,
    Extension,
    Geometry,
    Inertial,
    Joint,
    Limit,
    Link,
    Material,
    MeshRef,
    Mimic,
    Model,
    Note,
    Plane,
    Pose,
    Robot,
    Sphere,
    UrdfDocument,
    Visual,
)
from ..packages import PackageResolver
from ..transforms import canonical_quat, quat_to_rpy
from ..untrusted import excerpt

EXTENSION_TAGS = ("ros2_control", "transmission", "gazebo", "mujoco")
SHAPES = ("box", "cylinder", "sphere", "capsule", "mesh", "plane")
MAX_MAGNITUDE = 1e12
"""Largest magnitude of a number in a URDF (a length, mass, inertia, gain, colour):
far beyond any robot, far below what overflows the arithmetic of later passes
(1e300 squared is inf). A bigger one is an error naming the element."""
LIMIT_MAGNITUDE = 1e30
"""Joint ``<limit>`` values may be larger: ``upper="1e+16"`` is a common way to say
'unlimited' (example-robot-data's iris)."""
WORLD = "world"
"""The parent link name Drake and Gazebo use for the world frame."""
JOINT_ALIASES = {"ball": "spherical"}
"""Joint type spellings other tools accept, read as ours (with a warning)."""
VERSIONS = ((1, 0), (1, 1), (1, 2))
"""The URDF versions urdfdom 6 reads, and so do we."""
MOTION_LIMITS = ("acceleration", "deceleration", "jerk")
"""URDF 1.2's joint limits beyond velocity (MuJoCo enforces none of them)."""


@dataclass(frozen=True)
class ParseConfig:
    strict: bool = False
    """Every liberty taken with the URDF is an error instead of a warning."""
    free_root: bool = False
    """The root link will get a free joint (``--floating-base``): it and every link
    fixed to it move, so they cannot hold a plane."""


class _Reader:
    """Helpers that turn attribute text into numbers with precise errors."""

    def __init__(
        self,
        source: Path,
        resolver: PackageResolver,
        cfg: ParseConfig = ParseConfig(),
        version: tuple[int, int] = (1, 0),
    ):
        self.source = source
        self.resolver = resolver
        self.cfg = cfg
        self.version = version
        """The file's URDF version: what 1.1 and 1.2 add is read from a file that declares it."""
        self.notes: list[Note] = []
        self.dropped_meshes = 0
        """Meshes dropped because their file could not be found (not with ``strict``)."""
        self.mesh_dirs: tuple[Path, ...] = ()
        self.texture_dirs: tuple[Path, ...] = ()
        """Folders the description's ``<mujoco><compiler>`` names for its meshes and
        textures, searched by file name as MuJoCo's URDF import does."""

    def fail(self, element: str, message: str) -> URDFError:
        return URDFError(message, file=self.source, element=element)

    def liberty(self, element: str, message: str) -> None:
        """Read past what urdfdom rejects: a warning, or with ``strict`` an error."""
        if self.cfg.strict:
            raise self.fail(element, f"{message} (not accepted with --strict)")
        self.notes.append(Note("warning", f"{self.source}: {element}", message))

    def floats(
        self,
        el: etree._Element,
        attr: str,
        n: int,
        where: str,
        default: tuple[float, ...] | None = None,
        limit: float = MAX_MAGNITUDE,
    ) -> tuple[float, ...]:
        text = el.get(attr)
        if text is None:
            if default is None:
                raise self.fail(where, f"<{el.tag}> is missing attribute '{attr}'")
            return default
        shown = excerpt(text, 60)  # the attribute is a stranger's: quoted short
        try:
            values = tuple(float(v) for v in text.split())
        except ValueError:
            raise self.fail(
                where, f"<{el.tag} {attr}='{shown}'> is not a list of numbers"
            ) from None
        if len(values) > n > 1:  # PyBullet and Gazebo read the first n; so do we
            self.liberty(
                f"{where} <{el.tag} {attr}>",
                f"'{shown}' has {len(values)} numbers where {n} are needed; the first {n} used",
            )
            values = values[:n]
        if len(values) != n:
            raise self.fail(
                where, f"<{el.tag} {attr}='{shown}'> needs {n} numbers, got {len(values)}"
            )
        if not all(math.isfinite(v) for v in values):
            raise self.fail(where, f"<{el.tag} {attr}='{shown}'> is not finite")
        if any(abs(v) > limit for v in values):
            raise self.fail(
                where,
                f"<{el.tag} {attr}='{shown}'> is out of range (at most {limit:g} in magnitude)",
            )
        return values

    def optional(
        self, el: etree._Element, attr: str, where: str, limit: float = MAX_MAGNITUDE
    ) -> float | None:
        """An optional number: None when the attribute is absent."""
        if el.get(attr) is None:
            return None
        return self.floats(el, attr, 1, where, limit=limit)[0]

    def scalar(
        self, el: etree._Element, attr: str, where: str, default: float | None = None
    ) -> float:
        """A number: ``default`` when absent, else an error naming the missing attribute."""
        if el.get(attr) is None and default is not None:
            return default
        return self.floats(el, attr, 1, where)[0]

    def pose(self, el: etree._Element | None, where: str) -> Pose:
        if el is None:
            return Pose()
        xyz = self.floats(el, "xyz", 3, where, (0.0, 0.0, 0.0))
        xyz = tuple(v + 0.0 for v in xyz)
        if el.get("quat_xyzw") is not None:
            if self.version < (1, 1):
                message = (
                    "quat_xyzw is URDF 1.1 and this file declares version "
                    f"{_version_text(self.version)}; ignored, as urdfdom ignores it "
                    '(declare <robot version="1.1"> to use it)'
                )
                self.notes.append(Note("warning", f"{self.source}: {where} <origin>", message))
            elif el.get("rpy") is not None:
                raise self.fail(where, "<origin> has both rpy and quat_xyzw; give one of them")
            else:
                return Pose(xyz=xyz, rpy=quat_to_rpy(q := self.quaternion(el, where)), quat=q)  # type: ignore[arg-type]
        rpy = self.floats(el, "rpy", 3, where, (0.0, 0.0, 0.0))
        return Pose(xyz=xyz, rpy=tuple(v + 0.0 for v in rpy))  # type: ignore[arg-type]

    def quaternion(self, el: etree._Element, where: str) -> tuple[float, float, float, float]:
        """``quat_xyzw`` as a unit (w, x, y, z), normalised as urdfdom normalises it."""
        x, y, z, w = self.floats(el, "quat_xyzw", 4, where)
        if (x, y, z, w) == (0.0, 0.0, 0.0, 0.0):
            self.liberty(
                f"{where} <origin quat_xyzw>", "is zero; read as no rotation, as urdfdom reads it"
            )
            return (1.0, 0.0, 0.0, 0.0)
        return canonical_quat((w, x, y, z))

    def geometry(self, el: etree._Element | None, where: str) -> Geometry | None:
        """The shape, or None when it is dropped (unknown or of zero size, with a warning)."""
        if el is None or len([c for c in el if isinstance(c.tag, str)]) == 0:
            raise self.fail(where, "<geometry> is missing or empty")
        shape = next(c for c in el if isinstance(c.tag, str))
        kind = shape.tag
        if kind not in SHAPES:  # <cdf>, <heightmap>, ...: simulator-specific
            self.liberty(
                f"{where} <{kind}>",
                f"unknown geometry <{kind}> dropped; supported: {', '.join(SHAPES)}",
            )
            return None
        geometry = self._shape(shape, where)
        if geometry is not None and _zero_size(geometry):
            self.liberty(f"{where} <{kind}>", "has zero size; dropped (MuJoCo needs size > 0)")
            return None
        if isinstance(geometry, Capsule) and self.version < (1, 1):
            self.liberty(
                f"{where} <{kind}>",
                "<capsule> is URDF 1.1 and this file declares version "
                f"{_version_text(self.version)} (urdfdom drops it); read as a capsule, as "
                "other simulators read it",
            )
        if isinstance(geometry, Capsule) and geometry.length == 0.0 and geometry.radius > 0.0:
            self.liberty(f"{where} <{kind}>", "capsule of length 0 read as a sphere")
            return Sphere(radius=geometry.radius)
        return geometry

    def _shape(self, shape: etree._Element, where: str) -> Geometry | None:
        kind = shape.tag
        if kind == "box":
            return Box(size=self.floats(shape, "size", 3, where))  # type: ignore[arg-type]
        if kind == "cylinder":
            return Cylinder(
                radius=self.scalar(shape, "radius", where),
                length=self.scalar(shape, "length", where),
            )
        if kind == "sphere":
            return Sphere(radius=self.scalar(shape, "radius", where))
        if kind == "capsule":
            return Capsule(
                radius=self.scalar(shape, "radius", where),
                length=self.scalar(shape, "length", where),
            )
        if kind == "plane":
            normal = self.floats(shape, "normal", 3, where, (0.0, 0.0, 1.0))
            norm = math.sqrt(sum(v * v for v in normal))
            if norm == 0.0:
                raise self.fail(where, "<plane> has a zero-length normal")
            size = self.floats(shape, "size", 2, where, (0.0, 0.0))
            return Plane(  # warned about (or dropped) by _link: _plane_allowed
                normal=tuple(v / norm + 0.0 for v in normal),  # type: ignore[arg-type]
                size=tuple(abs(v) + 0.0 for v in size),  # type: ignore[arg-type]
            )
        if kind == "mesh":
            filename = shape.get("filename")
            if not filename:
                raise self.fail(where, "<mesh> is missing attribute 'filename'")
            scale_text = shape.get("scale")
            if scale_text is not None and len(scale_text.split()) == 1:
                s = self.floats(shape, "scale", 1, where)[
                    0
                ]  # a single number is used by some tools
                scale = (s, s, s)
            else:
                scale = self.floats(shape, "scale", 3, where, (1.0, 1.0, 1.0))  # type: ignore[assignment]
            if 0.0 in scale:
                return MeshRef(filename=filename, path=None, scale=scale)  # dropped by the caller
            try:
                path = self.resolver.resolve(
                    filename, element=f"{where} mesh '{filename}'", asset_dirs=self.mesh_dirs
                )
            except PackageNotFoundError as exc:
                if self.cfg.strict:
                    raise
                # as urdfdom and RViz do: the robot without this mesh (the mesh pass does
                # the same for a file that is missing or unreadable)
                element = f"{where} mesh '{excerpt(filename, 120)}'"
                self.notes.append(Note("warning", element, f"{exc.detail}; dropped"))
                self.dropped_meshes += 1
                return None
            return MeshRef(filename=filename, path=path, scale=tuple(v + 0.0 for v in scale))  # type: ignore[arg-type]
        raise AssertionError(kind)

    def material(self, el: etree._Element, where: str, named: dict[str, Material]) -> Material:
        name = el.get("name", "")
        color = el.find("color")
        texture = el.find("texture")
        if color is None and (texture is None or not texture.get("filename")):
            if name in named:
                return named[name]
            return Material(name=name)
        rgba = self.floats(color, "rgba", 4, where) if color is not None else None
        tex_path = None
        if texture is not None and texture.get("filename"):
            tex_path = self.resolver.resolve(
                texture.get("filename"), element=f"{where} texture", asset_dirs=self.texture_dirs
            )
        return Material(name=name, rgba=rgba, texture=tex_path)  # type: ignore[arg-type]


def _link(el: etree._Element, r: _Reader, named: dict[str, Material], moves: bool) -> Link:
    name = el.get("name")
    where = f"link '{name}'"
    inertial = None
    iel = el.find("inertial")
    if iel is not None:
        mel = iel.find("mass")
        if mel is None:
            r.liberty(f"{where} <inertial>", "has no <mass>; read as mass 0, as urdfdom reads it")
        tel = iel.find("inertia")
        if tel is None:
            inertia = (0.0,) * 6
        else:
            inertia = tuple(  # type: ignore[assignment]  # six names, six numbers
                r.scalar(tel, k, where, 0.0) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
            )
        inertial = Inertial(
            origin=r.pose(iel.find("origin"), where),
            mass=r.scalar(mel, "value", where) if mel is not None else 0.0,
            inertia=inertia,
        )  # type: ignore[arg-type]
    visuals = []
    for i, vel in enumerate(el.findall("visual")):
        vwhere = f"{where} visual {i}"
        mat_el = vel.find("material")
        material = r.material(mat_el, vwhere, named) if mat_el is not None else None
        origin = r.pose(vel.find("origin"), vwhere)
        geometry = r.geometry(vel.find("geometry"), vwhere)
        if isinstance(geometry, Plane) and not _plane_allowed(r, vwhere, moves):
            continue
        if geometry is not None:
            visuals.append(Visual(origin, geometry, material=material, name=vel.get("name")))
    collisions = []
    dropped_before = r.dropped_meshes
    for i, cel in enumerate(el.findall("collision")):
        cwhere = f"{where} collision {i}"
        origin = r.pose(cel.find("origin"), cwhere)
        geometry = r.geometry(cel.find("geometry"), cwhere)
        if isinstance(geometry, Plane) and not _plane_allowed(r, cwhere, moves):
            continue
        if geometry is not None:
            collisions.append(Collision(origin, geometry, name=cel.get("name")))
    if not collisions and r.dropped_meshes > dropped_before:
        message = "has no collision geometry left: its collision meshes were dropped"
        r.notes.append(Note("warning", where, message))
    return Link(name=name, inertial=inertial, visuals=tuple(visuals), collisions=tuple(collisions))  # type: ignore[arg-type]


def _joint(el: etree._Element, r: _Reader) -> Joint:
    name = el.get("name")
    where = f"joint '{name}'"
    jtype = el.get("type")
    if jtype in JOINT_ALIASES:
        r.liberty(where, f"type '{jtype}' is not URDF; read as '{JOINT_ALIASES[jtype]}'")
        jtype = JOINT_ALIASES[jtype]
    elif jtype == "spherical":
        r.liberty(where, "type 'spherical' is not in urdfdom's URDF; written as a MuJoCo ball")
    if jtype not in JOINT_TYPES:
        shown = excerpt(str(jtype), 40)
        raise r.fail(where, f"has type '{shown}'; supported: {', '.join(JOINT_TYPES)}")
    parent, child = el.find("parent"), el.find("child")
    if parent is None or not parent.get("link") or child is None or not child.get("link"):
        raise r.fail(where, "needs <parent link=...> and <child link=...>")
    axis = (1.0, 0.0, 0.0)
    axis_el = el.find("axis")
    if axis_el is not None and jtype not in ("fixed", "floating", "spherical"):
        a = r.floats(axis_el, "xyz", 3, where)
        norm = math.sqrt(sum(v * v for v in a))
        if norm == 0.0:
            raise r.fail(where, "has a zero-length <axis>")
        axis = tuple(v / norm + 0.0 for v in a)  # type: ignore[assignment]
    limit = None
    lel = el.find("limit")
    if lel is not None:
        limit = Limit(
            lower=r.optional(lel, "lower", where, LIMIT_MAGNITUDE),
            upper=r.optional(lel, "upper", where, LIMIT_MAGNITUDE),
            effort=r.optional(lel, "effort", where, LIMIT_MAGNITUDE),
            velocity=r.optional(lel, "velocity", where, LIMIT_MAGNITUDE),
            **_motion_limits(lel, r, where),
        )
        motion = [
            f"{k} {getattr(limit, k):g}" for k in MOTION_LIMITS if getattr(limit, k) is not None
        ]
        if motion:
            message = (
                f"{', '.join(motion)} (URDF 1.2 limits) kept in the report's motion_limits; "
                "MuJoCo does not enforce them"
            )
            r.notes.append(Note("info", where, message))
        if (
            r.version >= (1, 2)
            and jtype in ("revolute", "prismatic")
            and (limit.lower is None or limit.upper is None)
        ):
            r.liberty(
                f"{where} <limit>",
                "URDF 1.2 needs both lower and upper for a revolute or prismatic joint "
                "(urdfdom refuses it); the missing one read as 0, as URDF 1.0 reads it",
            )
        lo, hi = limit.lower or 0.0, limit.upper or 0.0  # URDF's defaults
        if jtype in ("revolute", "prismatic") and lo > hi:
            r.liberty(
                f"{where} <limit>",
                f"lower {lo!r} > upper {hi!r}; joint left unlimited, as urdfdom reads it",
            )
    dynamics = None
    del_ = el.find("dynamics")
    if del_ is not None:
        dynamics = Dynamics(
            damping=r.scalar(del_, "damping", where, 0.0),
            friction=r.scalar(del_, "friction", where, 0.0),
        )  # type: ignore[arg-type]
    mimic = None
    mel = el.find("mimic")
    if mel is not None:
        if not mel.get("joint"):
            raise r.fail(where, "<mimic> is missing attribute 'joint'")
        mimic = Mimic(
            joint=mel.get("joint"),
            multiplier=r.scalar(mel, "multiplier", where, 1.0),
            offset=r.scalar(mel, "offset", where, 0.0),
        )  # type: ignore[arg-type]
    return Joint(
        name=name,
        type=jtype,  # type: ignore[arg-type]
        parent=parent.get("link"),
        child=child.get("link"),
        origin=r.pose(el.find("origin"), where),
        axis=axis,
        limit=limit,
        dynamics=dynamics,
        mimic=mimic,
    )


def _motion_limits(lel: etree._Element, r: _Reader, where: str) -> dict[str, float | None]:
    """URDF 1.2's acceleration, deceleration (urdfdom: the acceleration when absent) and
    jerk limits, each >= 0; in an older file ignored with a warning, as urdfdom does."""
    given = [k for k in MOTION_LIMITS if lel.get(k) is not None]
    if r.version < (1, 2):
        if given:
            them = "it" if len(given) == 1 else "them"
            message = (
                f"{', '.join(given)} {'is' if len(given) == 1 else 'are'} URDF 1.2 and this file "
                f"declares version {_version_text(r.version)}; ignored, as urdfdom ignores "
                f'{them} (declare <robot version="1.2"> to keep {them})'
            )
            r.notes.append(Note("warning", f"{r.source}: {where} <limit>", message))
        return {}
    out: dict[str, float | None] = {}
    for key in MOTION_LIMITS:
        value = r.optional(lel, key, where, LIMIT_MAGNITUDE)
        if value is not None and value < 0:
            raise r.fail(where, f"<limit {key}='{excerpt(lel.get(key), 40)}'> is negative")
        out[key] = value
    if out["deceleration"] is None:
        out["deceleration"] = out["acceleration"]
    return out


def _version(root: etree._Element, source: Path) -> tuple[int, int]:
    """``<robot version>`` as urdfdom 6 reads it: "MAJOR.MINOR" (each a C integer,
    ``strtol``'s way), 1.0 when absent; a version it does not know is an error."""
    text = root.get("version")
    if text is None:
        return (1, 0)
    shown = excerpt(text, 40)

    def fail(why: str) -> URDFError:
        return URDFError(f"version '{shown}' {why}", file=source, element="robot")

    # urdfdom's split on '.': empty pieces are kept, but not a trailing one
    parts = text.split(".")
    if parts and parts[-1] == "":
        parts.pop()
    if len(parts) != 2:
        raise fail("is not of the form MAJOR.MINOR")
    numbers = []
    for part in parts:
        match = re.fullmatch(r"[ \t\n\v\f\r]*([+-]?[0-9]+)", part)
        if not part:
            raise fail("has an empty field")
        if match is None:
            raise fail("is not of the form MAJOR.MINOR (two whole numbers)")
        value = int(match.group(1))
        if value < 0:
            raise fail("is negative")
        numbers.append(value)
    version = (numbers[0], numbers[1])
    if version not in VERSIONS:
        known = ", ".join(_version_text(v) for v in VERSIONS)
        raise fail(f"is not a URDF version urdfdom reads ({known})")
    return version


def _version_text(version: tuple[int, int]) -> str:
    return f"{version[0]}.{version[1]}"


def _zero_size(g: Geometry) -> bool:
    """Shapes MuJoCo rejects for a zero size (a capsule of length 0 is a sphere)."""
    if isinstance(g, Box):
        return 0.0 in g.size
    if isinstance(g, Cylinder):
        return g.radius == 0.0 or g.length == 0.0
    if isinstance(g, Sphere | Capsule):
        return g.radius == 0.0
    if isinstance(g, MeshRef):
        return 0.0 in g.scale
    return False


def _moving_links(root: etree._Element, cfg: ParseConfig) -> set[str]:
    """Links some non-fixed joint moves, read before the tree is checked (cycle-safe)."""
    parent: dict[str, tuple[str, bool]] = {}
    for el in root.findall("joint"):
        p, c = el.find("parent"), el.find("child")
        if p is not None and c is not None and p.get("link") and c.get("link"):
            parent.setdefault(c.get("link"), (p.get("link"), el.get("type") != "fixed"))
    out = set()
    # (moves, where the walk stopped) per link walked through: every link on a walk
    # up shares its answer, so a long welded chain is walked once, not once per link.
    known: dict[str, tuple[bool, str]] = {}
    for el in root.findall("link"):
        link, seen, moves, path = el.get("name"), set(), False, []
        while link in parent and link not in seen and not moves and link not in known:
            seen.add(link)
            path.append(link)
            link, moves = parent[link]
        if not moves and link in known:
            moves, link = known[link]
        if moves or link not in seen:  # a cycle is not remembered: parse rejects it
            known.update(dict.fromkeys(path, (moves, link)))
        if moves or (cfg.free_root and link != "world"):  # emit frees a root not named world
            out.add(el.get("name"))
    return out


def _plane_allowed(r: _Reader, where: str, moves: bool) -> bool:
    """A plane is kept in a static link, dropped from a moving one (MuJoCo's rule)."""
    if moves:
        r.liberty(
            f"{where} <plane>",
            "plane in a moving link (MuJoCo allows planes only in static bodies); dropped",
        )
        return False
    r.liberty(f"{where} <plane>", "<plane> is Gazebo's, not URDF; written as a MuJoCo plane")
    return True


def _world_link(links: list[Link], joints: list[Joint], r: _Reader) -> list[Link]:
    """A parent link ``world`` that no ``<link>`` defines is the world frame (Drake's and
    Gazebo's convention): an empty root link of that name, which emit writes as the
    world body. Any other undefined parent stays an error (:func:`_check_tree`)."""
    if any(link.name == WORLD for link in links):
        return links
    to_world = [j for j in joints if j.parent == WORLD]
    if not to_world:
        return links
    for j in to_world:
        how = (
            "is welded to the world at the joint's origin"
            if j.type == "fixed"
            else f"is attached to the world by this {j.type} joint at its origin"
        )
        r.liberty(
            f"joint '{j.name}'",
            f"parent link 'world' is not defined; read as the world frame (Drake's and "
            f"Gazebo's convention): link '{j.child}' {how}",
        )
    return [Link(name=WORLD), *links]


def _check_tree(robot_links: list[Link], joints: list[Joint], r: _Reader) -> None:
    names = set()
    for link in robot_links:
        if not link.name:
            raise r.fail("link", "a <link> has no name")
        if link.name in names:
            raise r.fail(f"link '{link.name}'", "is defined twice; link names must be unique")
        names.add(link.name)
    joint_names: set[str] = set()
    parent_of: dict[str, str] = {}
    for j in joints:
        if not j.name:
            raise r.fail("joint", "a <joint> has no name")
        if j.name in joint_names:
            raise r.fail(f"joint '{j.name}'", "is defined twice; joint names must be unique")
        joint_names.add(j.name)
        for role, end in (("parent", j.parent), ("child", j.child)):
            if end not in names:
                raise r.fail(f"joint '{j.name}'", f"{role} link '{end}' does not exist")
        if j.child in parent_of:
            raise r.fail(
                f"joint '{j.name}'",
                f"link '{j.child}' already has parent joint '{parent_of[j.child]}'; "
                "a URDF must be a tree",
            )
        parent_of[j.child] = j.name
    for j in joints:
        if j.mimic is not None and j.mimic.joint == j.name:
            raise r.fail(f"joint '{j.name}'", "mimics itself")
    if not robot_links:
        return
    roots = [link.name for link in robot_links if link.name not in parent_of]
    if len(roots) > 1:
        raise r.fail(
            "robot",
            f"has {len(roots)} root links ({', '.join(roots[:5])}); a URDF needs exactly one",
        )
    child_of = {j.child: j.parent for j in joints}
    if not roots:
        # Every link has a parent: walk up from any link until we loop.
        start = robot_links[0].name
        seen = [start]
        while child_of[seen[-1]] not in seen:
            seen.append(child_of[seen[-1]])
        cycle = seen[seen.index(child_of[seen[-1]]) :]
        raise r.fail("robot", f"joints form a cycle through links {' -> '.join(cycle)}")
    # One root, each link one parent: any link not reachable from the root is on a cycle.
    reachable = {roots[0]}
    frontier = [roots[0]]
    children: dict[str, list[str]] = {}
    for j in joints:
        children.setdefault(j.parent, []).append(j.child)
    while frontier:
        for c in children.get(frontier.pop(), []):
            if c not in reachable:
                reachable.add(c)
                frontier.append(c)
    lost = [link.name for link in robot_links if link.name not in reachable]
    if lost:
        raise r.fail("robot", f"joints form a cycle through links {', '.join(lost[:6])}")


def _drop_dangling_mimics(joints: list[Joint]) -> tuple[list[Joint], list[Note]]:
    """A mimic of a joint that does not exist is dropped with a warning.

    Real descriptions contain this (a renamed leader); the follower then moves
    on its own, which is what robot_state_publisher and pinocchio do too.
    """
    names = {j.name for j in joints}
    out, notes = [], []
    for j in joints:
        if j.mimic is not None and j.mimic.joint not in names:
            notes.append(
                Note(
                    "warning",
                    f"joint '{j.name}'",
                    f"mimics joint '{j.mimic.joint}', which does not exist; mimic ignored",
                )
            )
            j = replace(j, mimic=None)
        out.append(j)
    return out, notes


def _compiler_dirs(root: etree._Element, source: Path) -> tuple[tuple[Path, ...], ...]:
    """The mesh and texture folders a description's ``<mujoco><compiler>`` names
    (``meshdir``/``texturedir``, else ``assetdir``; relative to the source's folder), as
    MuJoCo's own URDF import reads them."""
    mesh: list[Path] = []
    texture: list[Path] = []
    for compiler in root.findall("mujoco/compiler"):
        asset = compiler.get("assetdir")
        for out, attr in ((mesh, "meshdir"), (texture, "texturedir")):
            folder = compiler.get(attr) or asset
            if folder:
                path = Path(folder)
                out.append(path if path.is_absolute() else source.parent / path)
    return tuple(dict.fromkeys(mesh)), tuple(dict.fromkeys(texture))


def run(doc: UrdfDocument, cfg: ParseConfig = ParseConfig()) -> Model:
    try:
        root = etree.fromstring(doc.xml, parser=etree.XMLParser(remove_comments=True))
    except etree.XMLSyntaxError as exc:
        line = exc.position[0] if exc.position else "?"
        raise InputError(f"malformed XML at line {line}: {exc.msg}", file=doc.source) from None
    if root.tag != "robot":
        raise URDFError(f"root element is <{root.tag}>, expected <robot>", file=doc.source)
    r = _Reader(doc.source, doc.resolver, cfg, _version(root, doc.source))
    r.mesh_dirs, r.texture_dirs = _compiler_dirs(root, doc.source)
    named: dict[str, Material] = {}
    for mel in root.findall("material"):
        mat = r.material(mel, f"material '{mel.get('name')}'", named)
        named.setdefault(mat.name, mat)
    moving = _moving_links(root, cfg)
    links = [_link(el, r, named, el.get("name") in moving) for el in root.findall("link")]
    if not links:  # urdfdom refuses it; an empty model would hide a wrong file
        message = "has no <link>; a URDF describes at least one"
        raise URDFError(message, file=doc.source, element="robot")
    joints = [_joint(el, r) for el in root.findall("joint")]
    links = _world_link(links, joints, r)
    _check_tree(links, joints, r)
    joints, notes = _drop_dangling_mimics(joints)
    notes = [Note("warning", "xacro", w) for w in doc.warnings] + list(doc.notes) + r.notes + notes
    # package fallbacks guessed while expanding xacro and resolving URIs above
    notes += [Note("warning", element, message) for element, message in doc.resolver.notes]
    extensions = tuple(
        Extension(tag=el.tag, xml=etree.tostring(el, encoding="unicode"))
        for el in root
        if el.tag in EXTENSION_TAGS
    )
    robot = Robot(
        name=root.get("name") or doc.source.name.split(".")[0],
        source=doc.source,
        links=tuple(links),
        joints=tuple(joints),
        materials=tuple(named.values()),
        extensions=extensions,
        version=r.version,
    )
    return Model(robot=robot, notes=tuple(notes))
