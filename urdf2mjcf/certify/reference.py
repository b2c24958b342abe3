"""The description as an independent implementation of URDF reads it: yourdfpy.

The certificate compares what we wrote with what the description says, and that
comparison is only worth something when the description is read by code that
is not ours: yourdfpy parses the URDF (after xacro, which is the description's
own language) and computes link frames by its own forward kinematics. Only the
file lookups are ours (``package://`` through the conversion's resolver), since
the reference must read the same mesh files the conversion read.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
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
    """A URDF read by yourdfpy, with the conversion's way of finding its files."""

    document: UrdfDocument
    """The xacro pass's output: the expanded URDF bytes and the package resolver."""
    urdf: Any
    """The ``yourdfpy.URDF`` (collision meshes loaded on first use)."""
    memo: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    """What the sections compute once per reference (by section)."""

    @property
    def source(self) -> Path:
        return self.document.source

    @property
    def name(self) -> str:
        return str(self.urdf.robot.name)

    @property
    def implementation(self) -> str:
        """``yourdfpy X.Y.Z``: what the certificate names as its reference."""
        from .stored import version_of

        return f"yourdfpy {version_of('yourdfpy')}"

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
        actuated-joint order; None: all zeros), mimic joints following their leader."""
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


def load(document: UrdfDocument, *, collision_meshes: bool = False) -> Reference:
    """The expanded URDF of ``document`` read by yourdfpy; an InputError when it
    cannot read it (the certificate then says so instead of passing)."""
    import io

    try:
        import yourdfpy
    except ImportError as exc:  # pragma: no cover - a dependency
        raise InputError(f"the certificate needs yourdfpy ({exc})", file=document.source) from None

    def handler(fname: str) -> str:
        try:
            return str(document.resolver.resolve(fname))
        except ConversionError:
            return fname  # yourdfpy reports the mesh missing; the check says so

    try:
        with quiet_yourdfpy():
            urdf = yourdfpy.URDF.load(
                io.BytesIO(document.xml),
                build_scene_graph=False,  # frames: composed from its joint transforms
                build_collision_scene_graph=collision_meshes,
                load_meshes=False,
                load_collision_meshes=collision_meshes,
                filename_handler=handler,
            )
    except Exception as exc:  # yourdfpy raises many types for what it cannot read
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"the reference (yourdfpy) cannot read it: {msg}", file=document.source
        ) from None
    ref = Reference(document=document, urdf=urdf)
    try:
        if urdf.base_link is None:  # yourdfpy finds it only while building a scene graph
            urdf._base_link = urdf._determine_base_link()
        for joint in urdf.robot.joints:  # yourdfpy keeps every number it is given
            if joint.axis is not None and np.shape(joint.axis) != (3,):
                raise ValueError(f"joint {joint.name!r}: an axis of {np.size(joint.axis)} numbers")
        ref.frames()  # what it cannot compute it cannot read
    except Exception as exc:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"the reference (yourdfpy) cannot read it: {msg}", file=document.source
        ) from None
    return ref
