"""Seeded component poses applied to a loaded facility, without rebuilding it.

make-facility applies a recipe's jitter by writing the jittered poses into the
xacro (``urdf2mjcf.facility.jitter``). An environment draws the very same offsets
(the same function, the same order, the same seed gives the same facility as
``make-facility --seed``) and applies them to the compiled model instead: a
component's root bodies (children of the world) move with its placement, so a body
at world pose B of a component placed at P goes to P' P^-1 B when the placement
becomes P'. A fixed body moves by its model fields (``body_pos``, ``body_quat``), a
free body (the CTB, a rover's base) by its free joint's ``qpos``. Everything starts
from the nominal model, so resets never accumulate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..bundle_manifest import Manifest
from ..facility.jitter import jittered
from ..facility.recipe import Pose2D, Ranges
from ..runner.load import LoadError


@dataclass(frozen=True)
class Placed:
    """One placed component and the root bodies that carry its placement."""

    name: str
    nominal: Pose2D
    """Its placement in the loaded facility (facility.json's ``pose``)."""
    fixed: tuple[int, ...]
    """Root bodies without a free joint: moved by ``body_pos``/``body_quat`` (their
    joints, if any, move with that frame)."""
    free: tuple[int, ...]
    """qpos addresses of the free joints of its root bodies."""


def _quat_z(angle: float) -> np.ndarray:
    return np.array([math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)])


def _rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(4)
    mujoco.mju_mulQuat(out, np.asarray(a, dtype=float), np.asarray(b, dtype=float).copy())
    return out


def root_bodies(m: mujoco.MjModel, manifest: Manifest, name: str) -> list[int]:
    """The children of the world that belong to component ``name``: those whose names
    start with its prefix (the longest prefix of the manifest that matches wins); for an
    unprefixed component (a robot), the root of the bodies its roles name (its base body,
    its joints)."""
    comps = manifest.components
    prefix = comps[name].prefix or ""
    roots = [b for b in range(1, m.nbody) if m.body_parentid[b] == 0]
    if prefix:
        # hatch_ must not claim hatch_4060_'s bodies: a longer matching prefix wins
        prefixes = [c.prefix or "" for c in comps.values()]

        def owner(body: str) -> str:
            return max((p for p in prefixes if p and body.startswith(p)), key=len, default="")

        return [b for b in roots if owner(m.body(b).name) == prefix]
    roles: Mapping[str, Any] = comps[name].roles or {}
    found: set[int] = set()
    B, J = mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_JOINT
    named = [(B, roles.get("base")), (J, roles.get("base_joint"))]
    named += [(J, j) for j in roles.get("joints") or []]
    for kind, value in named:
        i = mujoco.mj_name2id(m, kind, value) if isinstance(value, str) else -1
        if i >= 0:
            body = i if kind == B else int(m.jnt_bodyid[i])
            found.add(int(m.body_rootid[body]))
    return sorted(found)


class Poses:
    """Draws a component offsets from a seed and applies them to ``(m, d)``."""

    def __init__(
        self,
        m: mujoco.MjModel,
        manifest: Manifest,
        ranges: Mapping[str, Ranges],
        manifest_path: Path | None = None,
    ):
        """``ranges``: component -> {position, yaw} or None (never moves), as
        :meth:`Recipe.jitter_ranges` gives them; the model's current body fields and its
        ``qpos0`` are the nominal poses."""
        comps = manifest.components
        self.placed: dict[str, Placed] = {}
        self.ranges = dict(ranges)
        for name, comp in sorted(comps.items()):
            pose = comp.pose
            if pose is None:
                continue  # not placed: the recipe left it out
            bodies = root_bodies(m, manifest, name)
            moves = ranges.get(name) is not None and any(ranges[name].values())  # type: ignore[union-attr]
            if moves and not bodies:
                raise LoadError(
                    "has jitter ranges but no body of the facility carries it",
                    file=manifest_path,
                    element=f"components.{name}",
                )
            is_free = {
                b: bool(m.body_jntnum[b])
                and m.jnt_type[m.body_jntadr[b]] == mujoco.mjtJoint.mjJNT_FREE
                for b in bodies
            }
            fixed = tuple(b for b in bodies if not is_free[b])
            free = tuple(int(m.jnt_qposadr[m.body_jntadr[b]]) for b in bodies if is_free[b])
            self.placed[name] = Placed(
                name, Pose2D(tuple(float(v) for v in pose.xyz), float(pose.yaw)), fixed, free  # type: ignore[arg-type]
            )
        self.free_names = {n for n, c in comps.items() if c.free}
        self._body_pos = m.body_pos.copy()
        self._body_quat = m.body_quat.copy()

    def draw(self, seed: int) -> tuple[dict[str, Pose2D], dict[str, dict[str, float]]]:
        """The poses and offsets ``make-facility --seed seed`` would give."""
        nominal = {n: p.nominal for n, p in self.placed.items()}
        ranges = {n: self.ranges.get(n, {}) for n in nominal}
        free = {n for n in nominal if n in self.free_names}
        return jittered(nominal, ranges, free, seed)

    def apply(self, m: mujoco.MjModel, d: mujoco.MjData, seed: int) -> dict[str, dict[str, float]]:
        """Move every component by its offsets drawn from ``seed``: fixed root bodies in
        the model, free ones in ``d.qpos`` (which must hold the nominal free poses, as
        after a reset to the keyframe). Returns the offsets; call ``mj_forward`` after."""
        m.body_pos[:] = self._body_pos
        m.body_quat[:] = self._body_quat
        moved, offsets = self.draw(seed)
        for name, off in offsets.items():
            p = self.placed[name]
            origin = np.array(p.nominal.xyz)
            shift = np.array([off["dx"], off["dy"], 0.0])
            rot, q = _rot_z(off["dyaw"]), _quat_z(off["dyaw"])
            for b in p.fixed:
                m.body_pos[b] = origin + shift + rot @ (self._body_pos[b] - origin)
                m.body_quat[b] = _mul(q, self._body_quat[b])
            for adr in p.free:
                pos = d.qpos[adr : adr + 3].copy()
                d.qpos[adr : adr + 3] = origin + shift + rot @ (pos - origin)
                d.qpos[adr + 3 : adr + 7] = _mul(q, d.qpos[adr + 3 : adr + 7])
        return offsets
