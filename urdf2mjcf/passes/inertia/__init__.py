"""Inertia pass: the mass, centre of mass and inertia of every link.

``run`` fills ``Model.inertials`` with one entry per link: a
:class:`~urdf2mjcf.ir.BodyInertial` (``fullinertia`` about the centre of mass, in
link axes) or None for a massless body. It assumes the emitter writes each as
``<inertial>`` with ``fullinertia`` (or ``diaginertia`` for a diagonal tensor,
which MuJoCo accepts whenever it accepts the ``fullinertia`` form) under
``<compiler inertiafromgeom="false">``, so MuJoCo uses exactly these numbers.

Rules, per link:

1. **Valid URDF inertials are kept exactly.** Valid means mass > 0 and a tensor
   MuJoCo 4.0 accepts as emit writes it (``diaginertia`` when diagonal: moments
   >= 0, so a point mass on a welded frame stays; else ``fullinertia``: principal
   moments, as MuJoCo's eigen-solver computes them, >= 1e-14 kg m^2) that satisfy
   A + B >= C with no tolerance (a tensor 1 ulp past A + B = C is rejected). The
   only change is the rotation into link axes, R I R^T with R from the
   ``<origin>`` rpy; the centre of mass is its xyz. MuJoCo itself is asked for
   the verdict, since its rounding decides boundary cases such as thin plates.
2. **Negative mass, or a non-finite number** anywhere in ``<inertial>``, raises
   :class:`~urdf2mjcf.errors.InertiaError`.
3. **A tensor MuJoCo rejects is repaired**, keeping its principal axes: every
   principal moment is raised to at least 1e-3 x the largest (and 1e-12 kg m^2),
   or, when none reaches 1e-12 kg m^2 (a point mass), to that of a solid sphere
   of radius 1 cm, 0.4 m (0.01 m)^2. Then, if A + B < C, the two smaller moments
   are raised by equal amounts until A + B = C (1 + 1e-12) (margins 1e-9, then
   1e-6, only if MuJoCo's rounding still rejects it). Note ``repaired``, with
   the old and new principal moments.
4. **Mass 0 leaves the link massless** (None, no note), except where MuJoCo
   would reject the model. MuJoCo (``mjCModel::CheckBodyMassInertia`` in
   ``src/user/user_model.cc``) requires of every body with joints that it, or a
   body welded to it (reached through fixed joints only), has mass and all
   principal moments >= mjMINVAL (1e-15). Massive descendants behind another
   joint do not count: the massless middle link of a two-joint universal joint
   is rejected, a massless link whose fixed child has mass is accepted. A body
   with joints is a link whose parent joint is not fixed (and the root when
   ``free_root``). Such a link gets mass from its geometry as in rule 5, or else
   ``fallback_mass`` with ``fallback_inertia`` about the link origin; a link
   whose mass is a point mass (moments below 1e-15) keeps its mass and centre
   of mass and gets the tensor of its geometry (as rule 5 finds it) scaled to
   that mass, or rule 3's tensor when it has no geometry with a volume. Note
   ``repaired``.
5. **No** ``<inertial>`` **but geometry: estimated** at
   ``link_density.get(link, density)``, from the link's collision geoms (boxes,
   spheres, cylinders, capsules analytically; mesh pieces as their convex hull,
   which is what MuJoCo collides with) or, when it has none, from its URDF
   visuals (primitives analytically; meshes as the solid they enclose: exact
   when watertight, else made manifold by manifold3d, else with small holes
   filled, else their convex hull, noted ``hull``). Parts are combined with the
   parallel axis theorem; overlapping parts count twice. Note ``estimated``.
   Geometry without volume leaves the link massless with a ``warning``.
6. **Neither inertial nor geometry**: massless (None).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ...errors import InertiaError
from ...geometry import primitive_geom
from ...ir import BodyInertial, Link, MeshAsset, MeshRef, Model, Note, Plane, Robot
from ...transforms import (
    inertia_matrix,
    mujoco_fullinertia,
    pose_matrix,
    transform,
    vec3,
)
from .mass_properties import MassProperties, combine, convex_hull, mesh_solid, primitive

Source = Literal["urdf", "repaired", "estimated"]
Six = tuple[float, float, float, float, float, float]

MJ_MINVAL = 1e-15
"""mjMINVAL: the least mass and principal moment of a body with joints."""

_FLOOR_RATIO = 1e-3
_POINT_RADIUS = 0.01  # m: a point mass is repaired into a solid sphere of this radius
_MIN_MOMENT = 1e-12  # kg m^2: 100 x mjEPS, clear of MuJoCo's eigenvalue rounding


@dataclass(frozen=True)
class InertiaConfig:
    density: float = 1000.0
    """kg/m^3, for links with geometry but no ``<inertial>`` (water; ABS is 1050,
    aluminium 2700, steel 7850)."""
    link_density: Mapping[str, float] = field(default_factory=dict)
    """Per-link density override, kg/m^3."""
    fallback_mass: float = 1e-3
    """kg, for a body with joints that MuJoCo would reject and that has no geometry."""
    fallback_inertia: float = 1e-6
    """kg m^2, each principal moment of that fallback body."""
    free_root: bool = False
    """True when the emitter gives the root body a free joint (it then needs mass)."""

    def __post_init__(self) -> None:
        densities = {"density": self.density, **self.link_density}
        for what, value in densities.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"density for {what!r} must be a positive number, got {value!r}")
        if not self.fallback_mass >= MJ_MINVAL or not self.fallback_inertia >= _MIN_MOMENT:
            raise ValueError(
                "fallback_mass must be >= 1e-15 kg and fallback_inertia >= 1e-12 kg m^2"
            )


def run(model: Model, cfg: InertiaConfig) -> Model:
    robot = model.robot
    notes: list[Note] = [
        Note("warning", f"link '{name}'", "link_density names a link that does not exist")
        for name in cfg.link_density
        if name not in robot.link_map
    ]
    inertials: dict[str, BodyInertial | None] = {}
    for link in robot.links:
        if link.inertial is not None:
            inertials[link.name] = _from_urdf(link, robot, notes)
        else:
            inertials[link.name] = _estimated(model, link, cfg, notes)

    # Rule 4: only where MuJoCo's moving-body check would fail.
    for link in robot.links:
        if _has_joint(robot, link.name, cfg) and not _carries_mass(robot, link.name, inertials):
            current = inertials[link.name]
            if current is not None and current.mass >= MJ_MINVAL:
                inertials[link.name] = _point_mass_repaired(model, link, cfg, current, notes)
            else:
                inertials[link.name] = _massless_repaired(model, link, cfg, notes)

    return dataclasses.replace(model, inertials=inertials, notes=model.notes + tuple(notes))


# ---------------------------------------------------------------------------
# URDF inertials
# ---------------------------------------------------------------------------


def _from_urdf(link: Link, robot: Robot, notes: list[Note]) -> BodyInertial | None:
    inertial = link.inertial
    assert inertial is not None
    element = f"link '{link.name}' inertial"
    numbers = (inertial.mass, *inertial.inertia, *inertial.origin.xyz, *inertial.origin.rpy)
    if not all(math.isfinite(x) for x in numbers):
        raise InertiaError(
            f"non-finite value: mass {inertial.mass!r}, inertia {inertial.inertia!r}, "
            f"origin xyz {inertial.origin.xyz!r} rpy {inertial.origin.rpy!r}",
            file=robot.source,
            element=element,
        )
    if inertial.mass < 0:
        raise InertiaError(
            f"mass {inertial.mass!r} kg is negative; it must be >= 0 (0 makes the link massless)",
            file=robot.source,
            element=element,
        )
    if inertial.mass == 0:
        return None
    tensor = inertia_matrix(inertial.inertia)
    if inertial.origin.rpy != (0.0, 0.0, 0.0) or inertial.origin.quat is not None:
        r = pose_matrix(inertial.origin)[:3, :3]
        tensor = r @ tensor @ r.T
    return _checked(link.name, inertial.mass, inertial.origin.xyz, tensor, "urdf", notes)


def _checked(
    name: str,
    mass: float,
    com: np.ndarray | tuple[float, ...],
    tensor: np.ndarray,
    source: Source,
    notes: list[Note],
) -> BodyInertial:
    """The inertial as given when MuJoCo accepts its tensor, else repaired (rule 3)."""
    full = mujoco_fullinertia(tensor)
    reason = mujoco_rejects(full)
    if reason is not None:
        old, new, full = _repaired_tensor(full, mass)
        notes.append(
            Note(
                "repaired",
                f"link '{name}'",
                f"MuJoCo rejects the inertia ({reason}); principal moments "
                f"{_fmt(old)} -> {_fmt(new)} kg m^2, principal axes kept",
            )
        )
        source = "repaired"
    return BodyInertial(mass=float(mass), pos=vec3(com), fullinertia=full, source=source)


@functools.lru_cache(maxsize=4096)
def mujoco_rejects(fullinertia: Six) -> str | None:
    """MuJoCo's verdict on a body's inertia as emit writes it: None, or its error.

    Emit writes ``diaginertia`` when the off-diagonal terms are zero, else
    ``fullinertia``; MuJoCo diagonalises the latter with its own Jacobi
    iteration and tests the result without tolerance, so only MuJoCo can say
    where the boundary lies. A one-body compile costs about 0.3 ms. The body
    has no joint: the moving-body check is rule 4's.
    """
    import mujoco

    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body()
    body.explicitinertial = True
    body.mass = 1.0  # the tensor checks do not depend on the mass
    if fullinertia[3:] == (0.0, 0.0, 0.0):
        body.inertia = list(fullinertia[:3])
    else:
        body.fullinertia = list(fullinertia)
    try:
        spec.compile()
    except ValueError as exc:
        return str(exc).splitlines()[0].removeprefix("Error: ")
    return None


def _repaired_tensor(full: Six, mass: float) -> tuple[np.ndarray, np.ndarray, Six]:
    """Rule 3: (old moments, new moments, repaired fullinertia) with the axes kept."""
    old, axes = np.linalg.eigh(full_matrix(full))  # ascending
    if old[-1] >= _MIN_MOMENT:
        floor = max(_FLOOR_RATIO * old[-1], _MIN_MOMENT)
    else:  # nothing to scale from: a point mass
        floor = max(0.4 * mass * _POINT_RADIUS**2, _MIN_MOMENT)
    for margin in (1e-12, 1e-9, 1e-6):  # a wider margin only if MuJoCo's rounding needs it
        new = np.maximum(old, floor)
        gap = new[2] * (1 + margin) - new[0] - new[1]
        if gap > 0:
            new[:2] += gap / 2
        fixed = mujoco_fullinertia(axes @ np.diag(new) @ axes.T)
        if mujoco_rejects(fixed) is None:
            return old, new, fixed
    raise AssertionError(f"could not repair inertia {full}")  # pragma: no cover


def full_matrix(full: Six) -> np.ndarray:
    """MuJoCo (ixx, iyy, izz, ixy, ixz, iyz) -> symmetric (3, 3)."""
    ixx, iyy, izz, ixy, ixz, iyz = full
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)


# ---------------------------------------------------------------------------
# Estimates from geometry
# ---------------------------------------------------------------------------


def _estimated(
    model: Model, link: Link, cfg: InertiaConfig, notes: list[Note]
) -> BodyInertial | None:
    """Rule 5 (and 6): mass properties of a link without ``<inertial>``."""
    density = cfg.link_density.get(link.name, cfg.density)
    props, what = _from_geometry(model, link, density, notes)
    if what is None:
        return None
    element = f"link '{link.name}'"
    if props is None or props.mass < MJ_MINVAL:
        notes.append(Note("warning", element, f"{what} encloses no volume and gives no mass"))
        return None
    notes.append(Note("estimated", element, f"mass {props.mass:.6g} kg from {what} {_at(density)}"))
    return _checked(link.name, props.mass, props.com, props.inertia, "estimated", notes)


def _from_geometry(
    model: Model, link: Link, density: float, notes: list[Note]
) -> tuple[MassProperties | None, str | None]:
    """Combined mass properties of the link's collision geoms, else of its visuals.

    Returns (None, None) when the link has no geometry at all.
    """
    parts: list[MassProperties] = []
    kinds: Counter[str] = Counter()

    def add(part: MassProperties | None, placement: np.ndarray, kind: str) -> None:
        kinds[kind] += 1
        if part is not None:
            parts.append(part.transformed(placement))

    # Planes (static links only) are unbounded: they carry no mass.
    geoms = tuple(g for g in model.collision_geoms.get(link.name, ()) if g.type != "plane")
    visuals = [v for v in link.visuals if not isinstance(v.geometry, Plane)]
    if geoms:
        source = "collision geometry"
        assets = {a.name: a for a in model.mesh_assets}
        for g in geoms:
            if g.type == "mesh":
                assert g.mesh is not None, "mesh geom without a mesh asset"
                part = convex_hull(_asset_vertices(assets[g.mesh]), density)
            else:
                part = primitive(g.type, g.size, density)
            add(part, transform(g.pos, g.quat), g.type)
    elif visuals:
        source = "visual geometry"
        for v in visuals:
            if isinstance(v.geometry, MeshRef):
                add(
                    _visual_mesh(model, link, v.geometry, density, notes),
                    pose_matrix(v.origin),
                    "mesh",
                )
            else:
                g = primitive_geom("visual", v.origin, v.geometry)
                add(primitive(g.type, g.size, density), transform(g.pos, g.quat), g.type)
    else:
        return None, None
    listing = ", ".join(k if n == 1 else f"{n} x {k}" for k, n in sorted(kinds.items()))
    return combine(parts), f"{source} ({listing})"


def _visual_mesh(
    model: Model, link: Link, ref: MeshRef, density: float, notes: list[Note]
) -> MassProperties | None:
    """The solid a visual mesh encloses, in its mesh-file frame."""
    loaded = model.meshes.get((ref.path, ref.scale)) if ref.path is not None else None
    element = f"link '{link.name}'"
    if loaded is None:
        notes.append(Note("warning", element, f"mesh '{ref.filename}' is not loaded; adds no mass"))
        return None
    props, how = mesh_solid(loaded.merged.vertices, loaded.merged.faces, density)
    if how == "convex hull":
        notes.append(
            Note("hull", element, f"mesh '{ref.filename}' is not watertight; using its convex hull")
        )
    elif how != "closed":
        notes.append(
            Note("info", element, f"mesh '{ref.filename}' is not watertight; made solid by {how}")
        )
    return props


def _asset_vertices(asset: MeshAsset) -> np.ndarray:
    """(n, 3) vertices of a mesh asset, as the mesh and collision passes kept them."""
    if asset.vertices is None:
        raise ValueError(f"mesh asset {asset.name} carries no vertices")
    return asset.vertices


# ---------------------------------------------------------------------------
# Bodies with joints (rule 4)
# ---------------------------------------------------------------------------


def _has_joint(robot: Robot, name: str, cfg: InertiaConfig) -> bool:
    joint = robot.parent_joint.get(name)
    return joint.type != "fixed" if joint is not None else cfg.free_root


def _carries_mass(robot: Robot, name: str, inertials: Mapping[str, BodyInertial | None]) -> bool:
    """MuJoCo's CheckBodyMassInertia: the body or one welded below it has mass
    and all principal moments >= mjMINVAL (a point mass on a welded tool frame
    is accepted by MuJoCo and kept, but does not carry a joint)."""
    stack = [name]  # not recursion: a welded chain may be any length
    while stack:
        link = stack.pop()
        inertial = inertials.get(link)
        if (
            inertial is not None
            and inertial.mass >= MJ_MINVAL
            and np.linalg.eigvalsh(full_matrix(inertial.fullinertia)).min() >= MJ_MINVAL
        ):
            return True
        stack.extend(j.child for j in robot.child_joints.get(link, ()) if j.type == "fixed")
    return False


def _point_mass_repaired(
    model: Model, link: Link, cfg: InertiaConfig, inertial: BodyInertial, notes: list[Note]
) -> BodyInertial:
    """A body with joints MuJoCo rejects although it has mass. A point mass (no moment
    reaches 1e-12 kg m^2) gets the tensor of its geometry (as rule 5 finds it) scaled
    to the declared mass, about the declared centre of mass: a heavy link given a
    pebble's inertia swings its joints faster than a step can follow. Other tensors
    (a negative moment MuJoCo lets a body without joints have), and a point mass
    without geometry, get rule 3's."""
    element = f"link '{link.name}'"
    why = "a body with joints needs principal moments >= 1e-15 kg m^2 in MuJoCo"
    density = cfg.link_density.get(link.name, cfg.density)
    point = float(np.abs(np.linalg.eigvalsh(full_matrix(inertial.fullinertia))).max()) < _MIN_MOMENT
    props, what = _from_geometry(model, link, density, []) if point else (None, None)
    if props is not None and props.mass >= MJ_MINVAL:
        tensor = props.inertia * (inertial.mass / props.mass)
        full = mujoco_fullinertia(tensor)
        if mujoco_rejects(full) is None:
            old = np.linalg.eigvalsh(full_matrix(inertial.fullinertia))
            new = np.linalg.eigvalsh(tensor)
            notes.append(
                Note(
                    "repaired",
                    element,
                    f"{why}: principal moments {_fmt(old)} -> {_fmt(new)} kg m^2, those of "
                    f"its {what} at the declared mass {inertial.mass:.6g} kg",
                )
            )
            return dataclasses.replace(inertial, fullinertia=full, source="repaired")
    old, new, full = _repaired_tensor(inertial.fullinertia, inertial.mass)
    notes.append(
        Note("repaired", element, f"{why}; principal moments {_fmt(old)} -> {_fmt(new)} kg m^2")
    )
    return dataclasses.replace(inertial, fullinertia=full, source="repaired")


def _massless_repaired(
    model: Model, link: Link, cfg: InertiaConfig, notes: list[Note]
) -> BodyInertial:
    element = f"link '{link.name}'"
    why = "a body with joints and no mass, not even welded below it, is rejected by MuJoCo"
    density = cfg.link_density.get(link.name, cfg.density)
    geometry_notes: list[Note] = []
    props, what = _from_geometry(model, link, density, geometry_notes)
    if props is not None and props.mass >= MJ_MINVAL:
        notes.extend(geometry_notes)
        notes.append(
            Note(
                "repaired",
                element,
                f"{why}: mass {props.mass:.6g} kg estimated from {what} {_at(density)}",
            )
        )
        return _checked(link.name, props.mass, props.com, props.inertia, "repaired", notes)
    notes.append(
        Note(
            "repaired",
            element,
            f"{why}: given mass {cfg.fallback_mass:g} kg and principal moments "
            f"{cfg.fallback_inertia:g} kg m^2 at the link origin",
        )
    )
    f = float(cfg.fallback_inertia)
    return BodyInertial(cfg.fallback_mass, (0.0, 0.0, 0.0), (f, f, f, 0.0, 0.0, 0.0), "repaired")


def _at(density: float) -> str:
    return f"at density {density:g} kg/m^3"


def _fmt(values: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in values) + ")"
