"""Simulation checks shared by the mockup tests: convert a standalone
description, read its joints, pose it, sweep joints through their ranges
looking for interpenetration, let it rest, push a joint."""

from __future__ import annotations

import itertools
import subprocess
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

import urdf2mjcf

ROOT = Path(__file__).resolve().parents[2]
CONVERT_OPTIONS = {
    "package_paths": [
        ROOT / "facility" / "mockups",
        ROOT / "facility" / "robots",
        ROOT / "facility" / "worlds",
    ],
    "packages": {
        "facility_common": ROOT / "facility" / "common",
        "facility_meshes": ROOT / "meshes",
    },
    "use_environment": False,
    "overwrite": True,
}
PENETRATION = 0.001
"""Contacts deeper than this (m) count as interpenetration."""
JOINT_TYPES = {
    mujoco.mjtJoint.mjJNT_HINGE: "revolute",
    mujoco.mjtJoint.mjJNT_SLIDE: "prismatic",
    mujoco.mjtJoint.mjJNT_BALL: "ball",
    mujoco.mjtJoint.mjJNT_FREE: "free",
}


def convert(source: Path, out: Path, **args: str) -> tuple[mujoco.MjModel, urdf2mjcf.Report]:
    """Convert ``source`` (validated by the converter) and load the robot file, no floor."""
    report = urdf2mjcf.convert(source, out, args=args, **CONVERT_OPTIONS)
    return mujoco.MjModel.from_xml_path(str(out)), report


@dataclass(frozen=True)
class JointInfo:
    type: str
    range: tuple[float, float]
    damping: float
    frictionloss: float
    axis: tuple[float, float, float]


def joints(m: mujoco.MjModel) -> dict[str, JointInfo]:
    return {
        m.joint(j).name: JointInfo(
            JOINT_TYPES[int(m.jnt_type[j])],
            (float(m.jnt_range[j, 0]), float(m.jnt_range[j, 1])),
            float(m.dof_damping[m.jnt_dofadr[j]]),
            float(m.dof_frictionloss[m.jnt_dofadr[j]]),
            tuple(float(a) for a in m.jnt_axis[j]),
        )
        for j in range(m.njnt)
    }


def home(m: mujoco.MjModel) -> mujoco.MjData:
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    mujoco.mj_forward(m, d)
    return d


def pose(m: mujoco.MjModel, d: mujoco.MjData, values: Mapping[str, float]) -> None:
    """Home, then the given joint values; positions, contacts and all."""
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    for name, q in values.items():
        d.qpos[m.joint(name).qposadr[0]] = q
    mujoco.mj_forward(m, d)


def body_pair(m: mujoco.MjModel, g1: int, g2: int) -> frozenset[str]:
    return frozenset((m.body(m.geom_bodyid[g1]).name, m.body(m.geom_bodyid[g2]).name))


def penetrations(
    m: mujoco.MjModel, d: mujoco.MjData, allowed: Iterable[frozenset[str]] = ()
) -> list[tuple[frozenset[str], float]]:
    """Contacts deeper than PENETRATION between bodies not in ``allowed``."""
    allowed = set(allowed)
    found = []
    for c in d.contact[: d.ncon]:
        pair = body_pair(m, c.geom1, c.geom2)
        if c.dist < -PENETRATION and pair not in allowed:
            found.append((pair, float(c.dist)))
    return found


def span(m: mujoco.MjModel, joint: str, steps: int) -> np.ndarray:
    lo, hi = m.joint(joint).range
    return np.linspace(lo, hi, steps)


def sweep(
    m: mujoco.MjModel,
    grid: Mapping[str, Iterable[float]],
    fixed: Mapping[str, float] | None = None,
    allowed: Iterable[frozenset[str]] = (),
) -> list[tuple[dict[str, float], frozenset[str], float]]:
    """Every combination of the values in ``grid`` (others at home or ``fixed``):
    the poses with interpenetration, and where."""
    d = mujoco.MjData(m)
    names = list(grid)
    bad = []
    for values in itertools.product(*(list(grid[n]) for n in names)):
        q = dict(fixed or {}) | dict(zip(names, (float(v) for v in values), strict=True))
        pose(m, d, q)
        for pair, dist in penetrations(m, d, allowed):
            bad.append((q, pair, dist))
    return bad


def marker_points(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """Each body's origin and three points 0.1 m out along its axes (so a turn
    about the body's own axis shows too), in world coordinates."""
    offsets = np.vstack([np.zeros(3), 0.1 * np.eye(3)])
    return np.array(
        [d.xpos[b] + d.xmat[b].reshape(3, 3) @ o for b in range(1, m.nbody) for o in offsets]
    )


def rest_drift(m: mujoco.MjModel, d: mujoco.MjData, seconds: float) -> float:
    """Largest displacement (m) of any marker point after ``seconds`` undriven."""
    mujoco.mj_forward(m, d)
    start = marker_points(m, d)
    for _ in range(int(round(seconds / m.opt.timestep))):
        mujoco.mj_step(m, d)
    return float(np.max(np.linalg.norm(marker_points(m, d) - start, axis=1)))


def push(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    joint: str,
    force: float,
    seconds: float,
) -> np.ndarray:
    """Apply a constant generalized force to ``joint`` for ``seconds``; its trajectory."""
    dof = m.joint(joint).dofadr[0]
    qadr = m.joint(joint).qposadr[0]
    trace = []
    for _ in range(int(round(seconds / m.opt.timestep))):
        d.qfrc_applied[dof] = force
        mujoco.mj_step(m, d)
        trace.append(float(d.qpos[qadr]))
    d.qfrc_applied[dof] = 0.0
    return np.array(trace)


def run_mesh_script(script: Path, out: Path) -> dict[str, bytes]:
    """Run a mesh script into ``out`` in a fresh interpreter; the files it wrote."""
    out.mkdir(parents=True, exist_ok=True)
    subprocess.run([sys.executable, str(script), "--out", str(out)], check=True, cwd=ROOT)
    return {p.name: p.read_bytes() for p in sorted(out.glob("*.stl"))}


def mesh_volume(path: Path) -> float:
    import trimesh

    mesh = trimesh.load(path, force="mesh")
    assert mesh.is_watertight, path
    return float(mesh.volume)


def mesh_bounds(path: Path) -> np.ndarray:
    import trimesh

    return np.asarray(trimesh.load(path, force="mesh").bounds)


def collision_bounds(m: mujoco.MjModel, d: mujoco.MjData, body: str) -> np.ndarray:
    """World-axis bounding box of a body's collision boxes and cylinders, in the body frame."""
    b = m.body(body).id
    rb, pb = d.xmat[b].reshape(3, 3), d.xpos[b]
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for g in range(m.ngeom):
        if m.geom_bodyid[g] != b or m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0:
            continue
        r = rb.T @ d.geom_xmat[g].reshape(3, 3)
        p = rb.T @ (d.geom_xpos[g] - pb)
        size = m.geom_size[g]
        if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            half = np.abs(r) @ size
        elif m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER:
            # extent of a disc of radius s0 with axis r[:, 2], plus the half length along it
            axis = r[:, 2]
            half = size[0] * np.sqrt(np.clip(1 - axis**2, 0, 1)) + size[1] * np.abs(axis)
        else:
            raise AssertionError(f"unexpected collision geom type {m.geom_type[g]} on {body}")
        lo, hi = np.minimum(lo, p - half), np.maximum(hi, p + half)
    return np.array([lo, hi])


def dh_flange(q, d, a, alpha) -> np.ndarray:
    """(4, 4) flange pose in the base frame from standard DH parameters,
    Rz(theta) Tz(d) Tx(a) Rx(alpha) per joint: an independent reference for UR arms."""
    import math

    t = np.eye(4)
    for theta, di, ai, al in zip(q, d, a, alpha, strict=True):
        ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(al), math.sin(al)
        t = t @ np.array(
            [
                [ct, -st * ca, st * sa, ai * ct],
                [st, ct * ca, -ct * sa, ai * st],
                [0, sa, ca, di],
                [0, 0, 0, 1],
            ]
        )
    return t


# ------------------------------------------------------------------ latches


def hold(m: mujoco.MjModel, d: mujoco.MjData, joint: str, target: float) -> None:
    """A firm hand on ``joint``: at ``target`` and at rest before each step (the step's
    constraints, the couplings that a latch drives among them, act from there)."""
    d.qpos[m.joint(joint).qposadr[0]] = target
    d.qvel[m.joint(joint).dofadr[0]] = 0.0


def opening_sign(m: mujoco.MjModel, d: mujoco.MjData, joint: str) -> float:
    """+1 when ``joint`` opens towards its upper limit (it rests nearer the lower), else -1."""
    lo, hi = m.joint(joint).range
    q = d.qpos[m.joint(joint).qposadr[0]]
    return 1.0 if hi - q >= q - lo else -1.0


def push_latched(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    holds: str,
    lock: str,
    value: float,
    force: float,
    seconds: float = 1.0,
    settle: float = 0.3,
) -> np.ndarray:
    """The lock held at ``value`` (set, then ``settle`` s for what it drives to follow),
    then ``force`` (N m or N, in the opening direction) on ``holds`` for ``seconds``:
    how far ``holds`` moved from where it was, over time (positive: opening)."""
    sign = opening_sign(m, d, holds)
    d.qpos[m.joint(lock).qposadr[0]] = value
    mujoco.mj_forward(m, d)
    for _ in range(int(round(settle / m.opt.timestep))):
        hold(m, d, lock, value)
        mujoco.mj_step(m, d)
    adr, dof = m.joint(holds).qposadr[0], m.joint(holds).dofadr[0]
    start = float(d.qpos[adr])
    trace = []
    for _ in range(int(round(seconds / m.opt.timestep))):
        hold(m, d, lock, value)
        d.qfrc_applied[dof] = sign * force
        mujoco.mj_step(m, d)
        trace.append(sign * (float(d.qpos[adr]) - start))
    d.qfrc_applied[:] = 0.0
    return np.array(trace)


def free_swing(m: mujoco.MjModel, d: mujoco.MjData, joint: str, force: float, t: float) -> float:
    """Independent reference: how far a free joint of the model's inertia (at the current
    pose, with armature), damping b and friction loss f moves in ``t`` s under a constant
    ``force``: I q'' = F - f - b q', from rest: (F - f) / b (t - tau (1 - exp(-t / tau)))."""
    dof = m.joint(joint).dofadr[0]
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    inertia, b, f = full[dof, dof], m.dof_damping[dof], m.dof_frictionloss[dof]
    tau = inertia / b
    return float((force - f) / b * (t - tau * (1 - np.exp(-t / tau))))
