"""The description as independent implementations of URDF read it: urdfdom and yourdfpy.

The certificate compares what we wrote with what the description says, and that
comparison is only worth something when the description is read by code that
is not ours. Two readers, after xacro (the description's own language):

* **urdfdom** (URDF's reference parser, the one ROS uses), through pinocchio where it
  is installed (``pip install 'mjcf-forge[verify]'``): the reference for link frames,
  pinocchio's forward kinematics of urdfdom's model, mimic joints coupled by
  pinocchio. What urdfdom prints from C++ is held back (:func:`urdfdom_quiet`).
* **yourdfpy**, always installed: the description's parts (links, inertials,
  geometry, joints, limits) for every section, and the frames where urdfdom is not
  installed or cannot read the file. yourdfpy reads URDF 1.0; what URDF 1.1 adds
  (``quat_xyzw`` origins, ``<capsule>``) is read beside it from the same elements,
  with urdfdom's rules (from version 1.1 on; both ``rpy`` and ``quat_xyzw`` is
  unreadable), quaternions by trimesh's transformations. A geometry yourdfpy does
  not know (``<plane>``, a simulator's own) is a part without a shape; a box, sphere
  or cylinder of zero size is set aside while yourdfpy loads (it has no volume) and
  put back as written, so the figures can say it is the description's flaw.

Where both read the file their frames are compared (:meth:`Reference.agreement`):
they disagree only by a bug of one of them, and urdfdom, the spec's reference, is
believed (yourdfpy 0.0.60 reads a mimic joint's leader from the wrong slot of its
configuration after a planar or floating joint). Only the file lookups are ours
(``package://`` through the conversion's resolver), since the reference must read
the same mesh files the conversion read.
"""

from __future__ import annotations

import logging
import math
import os
import sys
import tempfile
import threading
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConversionError, InputError
from ..ir import UrdfDocument

log = logging.getLogger(__name__)


@dataclass
class Reference:
    """A URDF read by yourdfpy (and urdfdom where it reads it), with the conversion's
    way of finding its files."""

    document: UrdfDocument
    """The xacro pass's output: the expanded URDF bytes and the package resolver."""
    urdf: Any
    """The ``yourdfpy.URDF`` (collision meshes loaded on first use)."""
    memo: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    """What the sections compute once per reference (by section)."""
    urdfdom: UrdfdomReading | None = None
    """urdfdom's reading through pinocchio: the reference for frames (None: pinocchio is
    not installed, or urdfdom cannot read the file: :attr:`urdfdom_why`)."""
    urdfdom_why: str | None = None
    """Why there is no urdfdom reading (None when there is one)."""

    @property
    def source(self) -> Path:
        return self.document.source

    @property
    def name(self) -> str:
        return str(self.urdf.robot.name)

    @property
    def implementation(self) -> str:
        """``urdfdom X.Y.Z`` or ``yourdfpy X.Y.Z``: what the certificate names as its
        reference (the reader of the frames)."""
        if self.urdfdom is not None:
            return self.urdfdom.implementation
        return yourdfpy_implementation()

    def readers(self) -> dict[str, Any]:
        """Who read what, for the certificate's ``references`` section."""
        from .stored import version_of

        pin = version_of("pin")
        return {
            "frames": self.implementation,
            "parts": yourdfpy_implementation(),
            "urdfdom": (
                f"{self.urdfdom.implementation} (through pinocchio {pin})"
                if self.urdfdom is not None
                else None
            ),
            "urdfdom_why_not": self.urdfdom_why,
        }

    def resolve(self, uri: str) -> Path:
        """A mesh URI as the conversion resolved it (``package://``, relative, ...)."""
        return self.document.resolver.resolve(uri)

    @cached_property
    def link_names(self) -> list[str]:
        return [link.name for link in self.urdf.robot.links]

    @cached_property
    def actuated_joints(self) -> list[str]:
        """Joints that move, mimic followers excluded (yourdfpy's configuration order)."""
        return list(self.urdf.actuated_joint_names)

    def frames(self, cfg: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Every link's 4x4 pose in the root link's frame at ``cfg`` (yourdfpy's
        actuated-joint order; None: all zeros), mimic joints following their leader:
        urdfdom's where it reads the file, else yourdfpy's."""
        if self.urdfdom is None:
            return self.yourdfpy_frames(cfg)
        q = np.zeros(len(self.actuated_joints)) if cfg is None else np.asarray(cfg, float)
        memo = self.memo.setdefault("urdfdom_frames", {})
        if q.tobytes() not in memo:
            values = dict(zip(self.actuated_joints, (float(v) for v in q), strict=True))
            poses = self.urdfdom.frames(values, self.follower_values(values))
            for pose in poses.values():
                pose.flags.writeable = False
            memo[q.tobytes()] = {name: poses[name] for name in self.link_names if name in poses}
        return dict(memo[q.tobytes()])

    def follower_values(self, values: Mapping[str, float]) -> dict[str, float]:
        """Each mimic follower's value from its leader's, as the description couples them
        (for a urdfdom reading whose mimics pinocchio does not couple)."""
        out = {}
        for joint in self.urdf.robot.joints:
            if joint.mimic is not None:
                mult = 1.0 if joint.mimic.multiplier is None else float(joint.mimic.multiplier)
                off = 0.0 if joint.mimic.offset is None else float(joint.mimic.offset)
                out[joint.name] = mult * values.get(joint.mimic.joint, 0.0) + off
        return out

    def agreement(self, configs: list[np.ndarray], position_m: float, rotation_rad: float) -> dict:
        """urdfdom's frames against yourdfpy's at ``configs`` (yourdfpy's order): the worst
        difference, and where they disagree, which is believed and why."""
        if self.urdfdom is None:
            return {"compared": False, "why": self.urdfdom_why}
        worst_p, worst_r = 0.0, 0.0
        where: tuple[str | None, int] = (None, 0)
        for k, q in enumerate(configs):
            ours, theirs = self.frames(q), self.yourdfpy_frames(q)
            for link, a in ours.items():
                b = theirs.get(link)
                if b is None:
                    continue
                p = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
                chord = float(np.linalg.norm(a[:3, :3] - b[:3, :3]))
                r = 2 * math.asin(min(1.0, chord / (2 * math.sqrt(2))))
                if p > worst_p or (p == worst_p and r > worst_r):
                    where = (link, k)
                worst_p, worst_r = max(worst_p, p), max(worst_r, r)
        out: dict[str, Any] = {
            "compared": True,
            "configurations": len(configs),
            "max_position_difference_m": worst_p,
            "max_rotation_difference_rad": worst_r,
            "agree": worst_p <= position_m and worst_r <= rotation_rad,
        }
        if not out["agree"]:
            out["link"], out["configuration"] = where
            out["believed"] = self.urdfdom.implementation
            out["why"] = self._why_urdfdom()
        return out

    def _why_urdfdom(self) -> str:
        """Why urdfdom's frames are believed where yourdfpy's differ: a known bug of
        yourdfpy's named where the description has it, else the spec's word."""
        urdf = self.urdf
        names = self.actuated_joints
        for joint in urdf.robot.joints:
            leader = joint.mimic.joint if joint.mimic is not None else None
            if leader not in names:
                continue
            slot, dofs = names.index(leader), urdf.actuated_dof_indices[names.index(leader)]
            if [slot] != list(dofs):
                before = next(
                    (n for n in names[:slot] if urdf.joint_map[n].type in ("planar", "floating")),
                    None,
                )
                return (
                    f"yourdfpy {_yourdfpy_version()} reads mimic joint '{joint.name}'s leader "
                    f"'{leader}' from configuration slot {slot}, which after the "
                    f"{urdf.joint_map[before].type if before else 'multi-dof'} joint "
                    f"'{before}' holds another joint's value (its slot is {dofs[0]}); urdfdom, "
                    "URDF's reference parser, couples it as the description says"
                )
        return (
            "urdfdom is URDF's reference parser (the one ROS uses): where another reader "
            "differs from it, the other is wrong"
        )

    def yourdfpy_frames(self, cfg: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """:meth:`frames` as yourdfpy computes them."""
        q = np.zeros(len(self.actuated_joints)) if cfg is None else np.asarray(cfg, float)
        # the sections ask for the same poses (zeros, home) more than once
        memo = self.memo.setdefault("frames", {})
        if q.tobytes() in memo:
            return dict(memo[q.tobytes()])
        matrices = self._joint_matrices(q)
        # yourdfpy's joint transforms composed down the tree: what its scene graph's
        # get_transform returns, without building the graph (its update is half of
        # update_cfg) or trimesh's per-call path search
        out = {str(self.urdf.base_link): np.eye(4)}
        for parent, child, joint in self._tree_edges:
            out[child] = out[parent] @ matrices[joint]
        for pose in out.values():
            pose.flags.writeable = False  # shared by every section that asks
        memo[q.tobytes()] = {name: out[name] for name in self.link_names if name in out}
        return dict(memo[q.tobytes()])

    def _joint_matrices(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Each joint's transform at ``q`` as yourdfpy's ``update_cfg`` computes it:
        its per-joint forward kinematics for the actuated joints in order (which sets the
        configuration mimics read), then for the mimic joints, then the others' origins."""
        urdf = self.urdf
        if len(q) != len(self.actuated_joints):
            raise ValueError(f"{len(q)} values for {len(self.actuated_joints)} joints")
        fk = urdf._forward_kinematics_joint
        out: dict[str, np.ndarray] = {}
        with quiet_yourdfpy():
            for joint, value, dofs in zip(
                urdf.actuated_joints, q, urdf.actuated_dof_indices, strict=True
            ):
                out[joint.name], urdf._cfg[dofs] = fk(joint, q=float(value))
            for joint in urdf.robot.joints:
                if joint.mimic is not None:
                    out[joint.name] = fk(joint, q=0.0)[0]
                elif joint.name not in out:  # fixed, floating, planar: the origin
                    out[joint.name] = fk(joint)[0]
        return out

    @cached_property
    def _tree_edges(self) -> list[tuple[str, str, str]]:
        """(parent, child, joint) of every joint, parents before children, from the root."""
        children: dict[str, list[tuple[str, str]]] = {}
        for joint in self.urdf.robot.joints:
            children.setdefault(joint.parent, []).append((joint.child, joint.name))
        order, edges = [str(self.urdf.base_link)], []
        for link in order:  # grows as it goes: breadth first
            for child, joint in children.get(link, ()):
                edges.append((link, child, joint))
                order.append(child)
        return edges


@contextmanager
def quiet_yourdfpy() -> Iterator[None]:
    """yourdfpy's warnings held back: it warns on every update of a mimic of a joint
    that does not move (the conversion's notes say it once)."""
    logger = logging.getLogger("yourdfpy")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def yourdfpy_implementation() -> str:
    return f"yourdfpy {_yourdfpy_version()}"


def _yourdfpy_version() -> str | None:
    from .stored import version_of

    return version_of("yourdfpy")


# -- urdfdom, through pinocchio ----------------------------------------------------

_NATIVE_STDERR = threading.Lock()
"""One capture of file descriptor 2 at a time: it is the process's, not a thread's."""
_URDFDOM_LINE = ("Error:", "Warning:", "Info:", "Debug:", "at line ")


@contextmanager
def urdfdom_quiet() -> Iterator[list[str]]:
    """What urdfdom's console bridge writes to file descriptor 2 (from C++, past
    ``sys.stderr``) while inside, held back and yielded as lines (after the block).

    File descriptor 2 is the whole process's: captures are serialised, and whatever
    another thread wrote meanwhile that is not urdfdom's is written back to stderr."""
    lines: list[str] = []
    with _NATIVE_STDERR:
        sys.stderr.flush()
        saved = os.dup(2)
        try:
            with tempfile.TemporaryFile() as tmp:
                os.dup2(tmp.fileno(), 2)
                try:
                    yield lines
                finally:
                    sys.stderr.flush()
                    os.dup2(saved, 2)
                    tmp.seek(0)
                    text = tmp.read().decode("utf-8", errors="replace")
                    others = []
                    for line in text.splitlines(keepends=True):
                        if line.strip().startswith(_URDFDOM_LINE):
                            lines.append(line.strip())
                        else:
                            others.append(line)
                    if others:  # another thread's, written while we held the descriptor
                        os.write(2, "".join(others).encode("utf-8", errors="replace"))
        finally:
            os.close(saved)


def urdfdom_error(lines: list[str], exc: BaseException | None = None) -> str:
    """urdfdom's first error (its cause; the later ones say where it stopped)."""
    for line in lines:
        if line.startswith("Error:"):
            return " ".join(line[len("Error:") :].split())
    text = " ".join(str(exc).split()) if exc is not None else ""
    return text or "it cannot read it"


@dataclass
class UrdfdomReading:
    """The description as urdfdom reads it, as pinocchio's kinematic model."""

    model: Any
    """``pinocchio.Model`` (no root joint); mimic followers coupled when ``coupled``."""
    coupled: bool
    """pinocchio couples the mimic joints itself (False: urdfdom's model has mimics it
    cannot couple, a leader of another type; the followers get their values given)."""
    implementation: str
    """``urdfdom X.Y.Z``."""

    _data_lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    @cached_property
    def _data(self) -> Any:
        """One ``pinocchio.Data``, reused by every :meth:`frames` (under ``_data_lock``):
        making it is quadratic in the chain's length (6 s for 400 links), the forward
        kinematics that fill it are not."""
        return self.model.createData()

    @cached_property
    def _plan(self) -> tuple[list[tuple[str, int, int]], list[tuple[str, int]]]:
        """(joint, first q index, nq) of each joint with a configuration, and
        (link, frame id) of each link frame."""
        import pinocchio as pin

        m = self.model
        joints = [
            (str(m.names[i]), int(m.joints[i].idx_q), int(m.joints[i].nq))
            for i in range(1, m.njoints)
        ]
        links = [(str(f.name), i) for i, f in enumerate(m.frames) if f.type == pin.FrameType.BODY]
        return joints, links

    def frames(
        self, values: Mapping[str, float], followers: Mapping[str, float]
    ) -> dict[str, np.ndarray]:
        """Every link's 4x4 pose in the root link's frame with the one-number joints at
        ``values`` (others at zero displacement); ``followers``: the mimic followers'
        values, used where pinocchio does not couple them."""
        import pinocchio as pin

        m = self.model
        q = pin.neutral(m)
        joints, links = self._plan
        for name, idx, nq in joints:
            value = values.get(name)
            if value is None and not self.coupled:
                value = followers.get(name)
            if value is None:
                continue
            if nq == 1:
                q[idx] = value
            elif nq == 2:  # a continuous joint: (cos, sin)
                q[idx : idx + 2] = (math.cos(value), math.sin(value))
        out: dict[str, np.ndarray] = {}
        with self._data_lock:
            d = self._data
            pin.framesForwardKinematics(m, d, q)
            placements = d.oMf
            for name, fid in links:
                placement = placements[fid]
                t = np.eye(4)
                t[:3, :3], t[:3, 3] = placement.rotation, placement.translation
                out.setdefault(name, t)
        root = out.get(self.root)
        if root is not None and not np.array_equal(root, np.eye(4)):
            inv = np.linalg.inv(root)
            out = {name: inv @ t for name, t in out.items()}
        return out

    @cached_property
    def root(self) -> str:
        """The root link: the body frame on the universe joint's placement, first."""
        import pinocchio as pin

        for f in self.model.frames:
            if f.type == pin.FrameType.BODY:
                return str(f.name)
        return ""


def read_urdfdom(xml: bytes) -> tuple[UrdfdomReading | None, str | None]:
    """(urdfdom's reading, None), or (None, why not): pinocchio not installed, or
    urdfdom's own first error."""
    try:
        import pinocchio as pin
    except ImportError:
        return None, "pinocchio is not installed (pip install 'mjcf-forge[verify]')"
    from .stored import version_of

    text = xml.decode("utf-8", errors="replace")
    implementation = f"urdfdom {version_of('cmeel-urdfdom') or version_of('urdfdom') or ''}"
    with urdfdom_quiet() as lines:
        try:
            model, coupled = pin.buildModelFromXML(text, mimic=True), True
        except Exception:  # a mimic pinocchio cannot couple (a leader of another type)
            model, coupled = None, False
        if model is None:
            try:
                model = pin.buildModelFromXML(text)
            except Exception as exc:  # pinocchio raises ValueError or RuntimeError
                failure: BaseException | None = exc
            else:
                failure = None
    if model is None:
        return None, f"urdfdom cannot read it: {urdfdom_error(lines, failure)}"
    return UrdfdomReading(model, coupled, implementation.strip()), None


# -- yourdfpy, with what URDF 1.1 adds ---------------------------------------------

_YOURDFPY_SHAPES = ("box", "cylinder", "sphere", "mesh")


@dataclass
class CapsuleShape:
    """A URDF 1.1 ``<capsule>``, which yourdfpy does not know: a part's ``geometry.capsule``."""

    radius: float
    length: float
    """The cylindrical part's length, metres (the caps add a radius at each end)."""


def _urdf_version(root: Any) -> tuple[int, int]:
    """``<robot version>``; (1, 0) when absent or not MAJOR.MINOR (urdfdom refuses those)."""
    text = root.get("version")
    parts = (text or "").strip().split(".")
    if text is None or len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        return (1, 0)
    return int(parts[0]), int(parts[1])


def _for_yourdfpy(xml: bytes) -> tuple[bytes, list[tuple[tuple[str, ...], Any]]]:
    """The document yourdfpy can read, and what to put back into its reading: each
    geometry it does not know (a placeholder sphere stands in for it) and each URDF
    1.1 quaternion origin, by where yourdfpy keeps it: ``(("joint", name), origin)``,
    ``(("link", name, part, index), element)`` with part ``inertial``, ``visual`` or
    ``collision``."""
    from lxml import etree

    root = etree.fromstring(xml, etree.XMLParser(remove_comments=True, resolve_entities=False))
    quaternions = _urdf_version(root) >= (1, 1)
    later: list[tuple[tuple[str, ...], Any]] = []

    def origin(where: tuple[str, ...], el: Any) -> None:
        o = el.find("origin")
        if quaternions and o is not None and o.get("quat_xyzw") is not None:
            if o.get("rpy") is not None:
                raise ValueError("an <origin> has both rpy and quat_xyzw")
            later.append((where, o))

    for joint in root.findall("joint"):
        origin(("joint", joint.get("name", "")), joint)
    for link in root.findall("link"):
        name = link.get("name", "")
        inertial = link.find("inertial")
        if inertial is not None:
            origin(("link", name, "inertial", "0"), inertial)
        for part in ("visual", "collision"):
            for i, el in enumerate(link.findall(part)):
                where = ("link", name, part, str(i))
                origin(where, el)
                geometry = el.find("geometry")
                shapes = [] if geometry is None else [c for c in geometry if isinstance(c.tag, str)]
                if shapes and (shapes[0].tag not in _YOURDFPY_SHAPES or _no_size(shapes[0])):
                    later.append((where, shapes[0]))
                    geometry.replace(shapes[0], etree.Element("sphere", radius="1"))
    if not later:
        return xml, []
    return etree.tostring(root), later


def _no_size(shape: Any) -> bool:
    """A box, sphere or cylinder with a zero dimension: no volume, so no shape (MuJoCo
    has none of it either); a mesh's scale is the mesh figures' business."""
    keys = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length")}
    try:
        values = [float(v) for k in keys.get(shape.tag, ()) for v in shape.get(k, "1").split()]
    except ValueError:
        return False  # yourdfpy says what it cannot read
    return 0.0 in values


def _sized(el: Any, yourdfpy: Any) -> Any:
    """yourdfpy's geometry of a zero-size box, sphere or cylinder, as the file has it."""
    if el.tag == "box":
        size = np.array([float(v) for v in el.get("size", "").split()], float)
        return yourdfpy.Geometry(box=yourdfpy.Box(size=size))
    if el.tag == "sphere":
        return yourdfpy.Geometry(sphere=yourdfpy.Sphere(radius=float(el.get("radius"))))
    return yourdfpy.Geometry(
        cylinder=yourdfpy.Cylinder(
            radius=float(el.get("radius", "1")), length=float(el.get("length", "1"))
        )
    )


def _complete(urdf: Any, later: list[tuple[tuple[str, ...], Any]]) -> None:
    """Put into yourdfpy's reading what :func:`_for_yourdfpy` set aside."""
    import trimesh.transformations as tra
    import yourdfpy

    for where, el in later:
        if where[0] == "joint":
            owner = urdf.joint_map[where[1]]
        else:
            link = urdf.link_map[where[1]]
            owner = (
                link.inertial
                if where[2] == "inertial"
                else getattr(link, f"{where[2]}s")[int(where[3])]
            )
        if el.tag != "origin":  # a shape yourdfpy does not know or of no size: none (or a capsule)
            geometry = yourdfpy.Geometry()
            if el.tag == "capsule":
                geometry.capsule = CapsuleShape(  # type: ignore[attr-defined]
                    float(el.get("radius")), float(el.get("length"))
                )
            elif _no_size(el):  # kept as read, after loading: the figures say it is the flaw
                geometry = _sized(el, yourdfpy)
            owner.geometry = geometry
            continue
        values = [float(v) for v in el.get("quat_xyzw").split()]
        if len(values) != 4 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"quat_xyzw '{el.get('quat_xyzw')}' is not 4 numbers")
        x, y, z, w = values
        matrix = tra.quaternion_matrix([w, x, y, z])  # normalised; zero: the identity
        matrix[:3, 3] = [float(v) for v in el.get("xyz", "0 0 0").split()][:3]
        owner.origin = matrix


def load(document: UrdfDocument, *, collision_meshes: bool = False) -> Reference:
    """The expanded URDF of ``document`` read by yourdfpy (and by urdfdom where
    pinocchio is installed); an InputError when neither can read it (the certificate
    then says so instead of passing)."""
    import io

    try:
        import yourdfpy
    except ImportError as exc:  # pragma: no cover - a dependency
        raise InputError(f"the certificate needs yourdfpy ({exc})", file=document.source) from None

    urdfdom, urdfdom_why = read_urdfdom(document.xml)

    def handler(fname: str) -> str:
        try:
            return str(document.resolver.resolve(fname))
        except ConversionError:
            return fname  # yourdfpy reports the mesh missing; the check says so

    def cannot(exc: BaseException) -> InputError:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        if urdfdom is not None:  # its parts (masses, geometry) are read by yourdfpy only
            why = f"yourdfpy, which reads its parts for the certificate, cannot read it: {msg}"
        else:
            urdfdom_said = (urdfdom_why or "").replace("urdfdom cannot read it: ", "")
            why = f"no reference reads it (urdfdom: {urdfdom_said}; yourdfpy: {msg})"
        return InputError(why, file=document.source)

    try:
        xml, later = _for_yourdfpy(document.xml)
        with quiet_yourdfpy():
            urdf = yourdfpy.URDF.load(
                io.BytesIO(xml),
                build_scene_graph=False,  # frames: composed from its joint transforms
                build_collision_scene_graph=collision_meshes,
                load_meshes=False,
                load_collision_meshes=collision_meshes,
                filename_handler=handler,
            )
        _complete(urdf, later)
    except Exception as exc:  # yourdfpy raises many types for what it cannot read
        raise cannot(exc) from None
    ref = Reference(document=document, urdf=urdf, urdfdom=urdfdom, urdfdom_why=urdfdom_why)
    try:
        if urdf.base_link is None:  # yourdfpy finds it only while building a scene graph
            urdf._base_link = urdf._determine_base_link()
        for joint in urdf.robot.joints:  # yourdfpy keeps every number it is given
            if joint.axis is not None and np.shape(joint.axis) != (3,):
                raise ValueError(f"joint {joint.name!r}: an axis of {np.size(joint.axis)} numbers")
        ref.yourdfpy_frames()  # what it cannot compute it cannot read
    except Exception as exc:
        raise cannot(exc) from None
    return ref
