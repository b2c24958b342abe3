"""Actuators pass: MuJoCo actuators, joint tuning and gravity compensation.

Runs after the inertia pass and before emit (whose document of the robot the pipeline
hands it, to compile: :data:`RobotTree`). ``run`` fills
``Model.actuators`` (one per actuated joint, in URDF joint order),
``Model.joint_tuning`` (armature, damping, frictionloss) and
``Model.gravcomp``. A robot with no ``<ros2_control>``, no ``<transmission>``,
no actuator file and no ``--gravcomp`` is returned unchanged.

Default gains are designed from the robot's linearised dynamics by :mod:`.servo`.

**Where actuators come from**, lowest precedence first, key by key:

1. documented defaults (below);
2. the URDF: ``<ros2_control>`` command interfaces and parameters, else a ROS 1
   ``<transmission>`` (a joint in both takes ros2_control's; see
   :mod:`.tags` for the tags read);
3. the actuator file ``--actuator-config FILE`` (schema in
   :mod:`.config`), whose ``joints`` patterns (``fnmatch``,
   case-sensitive) can also actuate joints the URDF leaves bare.

Command interface ``position`` gives a ``<position>`` servo, ``velocity`` a
``<velocity>`` actuator, ``effort`` a ``<motor>``. Fixed joints never get an
actuator; nor do floating and planar joints (warning). A mimic follower gets
none of its own (info note): its leader's actuator drives the group through the
equality constraint emit writes, so a gripper whose fingers mimic each other
has one actuator. A ros2_control or transmission joint missing from the URDF,
and an actuator-file pattern matching no joint (or gravcomp pattern matching
no link), give a warning and are skipped -- one actuator file may serve
variants of a robot with and without, say, a gripper.

**Ranges.** Position: ``ctrlrange`` = the joint's [lower, upper] when limited
(none for continuous joints). Velocity: +-the URDF velocity limit. Motor:
+-the effort limit. ``forcerange`` of position and velocity actuators:
+-the effort limit (URDF ``<limit effort>``, ros2_control ``force_limit``, or
the file's ``forcerange``); none when it is 0 or absent. ros2_control ``min``
/ ``max`` and the file's ``ctrlrange`` replace the command range.

**Default gains** are sized from the robot's own dynamics at the home pose
(emit's ``home`` keyframe): the model is compiled in memory (with the armature
and damping this pass sets) and linearised in independent joint coordinates,
each mimic follower folded into its leader (coupling vector c: 1 for the
leader, the multiplier for each follower, as the equality makes them move):

* M_r = C^T M C: MuJoCo's joint-space inertia (``mj_fullM``, armature
  included) seen by the independent joints; I = (M_r)_jj = c^T M c is the
  inertia a joint drives with the other joints held;
* tau_g = sum_k |c_k| W_k: the worst gravity load over the joint's own motion.
  W_k = |g_perp| |s_perp| for a hinge (s: the first mass moment
  sum_b m_b (1 - gravcomp_b) (x_b - anchor) of the bodies it moves; s and g
  taken perpendicular to the axis); W_k = |g . axis| sum_b m_b (1 - gravcomp_b)
  for a slide;
* B_r: the joints' own damping, b = (B_r)_jj.

Position servo, with omega = 2 pi f, f = ``bandwidth_hz`` = 10 Hz:

1. kp = max(I omega^2, min(tau_g, E) / theta_tol): at least the bandwidth, and
   stiff enough that the static sag under the robot's own weight,
   tau_g / kp, stays within theta_tol = ``sag_tolerance`` = 0.002 rad
   (``sag_tolerance_linear`` = 1 mm for slides). E is the force limit: a servo
   saturating at E gains nothing from more stiffness. For a UR10e
   shoulder (public link masses: about 130 N m of own weight at full reach)
   this gives kp ~ 6.5e4 N m/rad; hand-tuned MuJoCo gains for that arm use 1e5.
2. Stability: the fastest mode of M_r q'' + Kp q = 0 must satisfy
   omega_max * dt <= ``max_omega_dt`` = 1 at the model's timestep (MuJoCo's
   2 ms). MuJoCo integrates the spring explicitly (semi-implicit Euler is
   stable undamped up to omega * dt = 2; implicitfast takes kv implicitly,
   which widens that); 1 keeps six steps per servo period. 10 Hz alone is
   omega * dt = 0.13. Where the limit binds, the default kp carrying most of
   that mode's energy is lowered until it holds, with a warning giving the
   expected sag (add armature, or use ``--gravcomp``). Given kps making
   omega_max * dt > 2 get a warning.
3. kv = max(0, a * 2 zeta sqrt(kp I) - b), zeta = ``damping_ratio`` = 1:
   critically damped in total with the joint's own damping. The factor
   a >= 1 (one for all joints) is the least that damps every mode of the
   coupled system M_r q'' + (B_r + Kv) q' + Kp q = 0 at least zeta - 0.05
   (zeta capped at 1): inertial coupling between joints otherwise leaves a
   mode underdamped and a step overshoots by a few per cent. The note says
   when a > 1.

Velocity actuator: kv = max(I omega, min(tau_g, E) / ``drift_tolerance``): a
first-order response at the bandwidth, and a drift under gravity below
0.01 rad/s (m/s). Motor: no gains. Armature: 0 unless given. Gains given by
the URDF or the file are kept; a kv left out is completed for the given kp.
Chosen gains are rounded to 3 significant digits (kp upwards, so the sag
bound holds) and listed in ``info`` notes. The gains count the robot's own
weight only: a payload needs the file's ``kp`` (or ``--gravcomp``).

**Gravity compensation.** ``--gravcomp`` (or the file's ``gravcomp: true``)
sets MuJoCo's body ``gravcomp = 1`` on every link that a non-fixed joint
moves: an upward force equal to the body's weight at its centre of mass,
cancelling gravity exactly for a robot at rest (the servo then holds the home
pose with no sag). The file's list or ``{pattern: fraction}`` sets chosen
links (fractions in [0, 1]; listed links override ``--gravcomp``'s 1). By
default MuJoCo adds this force to the passive forces; the joint attribute
``actuatorgravcomp="true"`` routes it through the actuators instead, so it
counts against the joint's ``actuatorfrcrange`` like a real controller's
feed-forward. Gravity loads above are computed with these compensations.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ValidationError
from ...ir import Actuator, Joint, JointTuning, Model, Note, Robot
from ...mjcf.compile import HomeCompiles, compile_home
from ...mjcf.document import Document
from . import config as actuator_config
from . import servo as servo_design
from . import tags as control_tags
from .config import ActuatorFile, ActuatorSpec
from .servo import DesignParams, ServoRequest, ServoSystem

_GLOB = set("*?[")
_ACTUATABLE = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class ActuatorConfig:
    config_file: Path | None = None
    """The actuator file (``--actuator-config``); see :mod:`.config`."""
    gravcomp: bool = False
    """``--gravcomp``: gravcomp = 1 on every link a non-fixed joint moves."""
    bandwidth_hz: float = 10.0
    """Servo bandwidth f, Hz: kp >= I (2 pi f)^2 (position), kv >= I 2 pi f (velocity)."""
    damping_ratio: float = 1.0
    """zeta of the position servo with the joint's damping; 1 is critically damped."""
    sag_tolerance: float = 0.002
    """theta_tol, rad: the static sag a hinge servo may show under the robot's weight."""
    sag_tolerance_linear: float = 0.001
    """The same for slides, m."""
    drift_tolerance: float = 0.01
    """rad/s or m/s: the drift a velocity actuator may show under the robot's weight."""
    max_omega_dt: float = 1.0
    """Limit on omega_max * timestep of the coupled servo modes, for default kp."""
    floating_base: bool = False
    """As emit's: the root link moves freely (the coupled modes then include the base)."""

    def __post_init__(self) -> None:
        for name in actuator_config.DESIGN_KEYS + ("max_omega_dt",):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")


RobotTree = Callable[[Model, bool], Document]
"""The robot's MJCF document for a model (and ``floating_base``), which this pass
compiles to size gains: the pipeline hands it emit's (``urdf2mjcf.api``), so that this
pass never runs another."""


def run(
    model: Model, cfg: ActuatorConfig, tree: RobotTree, compiles: HomeCompiles | None = None
) -> Model:
    """``tree``: the robot's document for a model (:data:`RobotTree`). ``compiles``: where
    the conversion keeps this pass's compile of the robot (the scene pass reuses it where
    the shapes agree)."""
    robot = model.robot
    home = control_tags.initial_positions(robot)
    if home:  # the described start pose: the home keyframe, and the pose gains are sized at
        model = replace(model, home={**model.home, **home})
    tags = control_tags.read(robot)
    file = actuator_config.load(cfg.config_file) if cfg.config_file is not None else None
    if file is not None and file.defaults:
        cfg = replace(cfg, **file.defaults)  # type: ignore[arg-type]  # DESIGN_KEYS: floats
    if not tags.specs and file is None and not cfg.gravcomp:
        return replace(model, notes=model.notes + tags.notes) if tags.notes else model
    notes = list(tags.notes)

    specs, explicit, sources = _merged_specs(robot, tags, file, notes)
    plan, tuning = _plan(robot, specs, explicit, sources, notes)
    gravcomp = _gravcomp(robot, model.gravcomp, cfg, file, notes)
    all_tuning = {**model.joint_tuning, **tuning}

    ranges = {
        name: _ranges(robot.joint_map[name], kind, spec, notes)
        for name, (kind, spec) in plan.items()
    }
    sized = {
        name: ServoRequest(
            kind,
            spec.kp,
            spec.kv,
            _effort(ranges[name][1]),
            spec.bandwidth_hz or cfg.bandwidth_hz,
            spec.damping_ratio or cfg.damping_ratio,
        )
        for name, (kind, spec) in plan.items()
        if kind in ("position", "velocity")
    }
    gains: dict[str, tuple[float | None, float | None]] = {}
    if sized:
        system = _measure(
            replace(model, joint_tuning=all_tuning, gravcomp=gravcomp),
            list(sized),
            cfg,
            tree,
            compiles,
        )
        params = DesignParams(
            cfg.sag_tolerance, cfg.sag_tolerance_linear, cfg.drift_tolerance, cfg.max_omega_dt
        )
        requests = {n: r for n, r in sized.items() if n in system.index}
        gains, design_notes = servo_design.design(system, requests, params)
        notes += design_notes
    ours = []
    for name, (kind, spec) in plan.items():
        ctrlrange, forcerange = ranges[name]
        kp, kv = gains.get(name, (spec.kp, spec.kv))
        ours.append(
            Actuator(
                name=name,
                joint=name,
                kind=kind,  # type: ignore[arg-type]
                kp=kp if kind == "position" else None,
                kv=kv if kind in ("position", "velocity") else None,
                ctrlrange=ctrlrange,
                forcerange=forcerange,
                actuator_class=spec.actuator_class,
            )
        )
    order = {j.name: i for i, j in enumerate(robot.joints)}
    kept = [a for a in model.actuators if a.joint not in plan]
    actuators = sorted(kept + ours, key=lambda a: order.get(a.joint, len(order)))
    if ours:
        counts = Counter(a.kind for a in ours)
        kinds = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
        origin = ", ".join(sorted({sources[name] for name in plan}))
        notes.insert(0, Note("info", "actuators", f"{len(ours)} actuators ({kinds}) from {origin}"))
    return replace(
        model,
        actuators=tuple(actuators),
        joint_tuning=all_tuning,
        gravcomp=gravcomp,
        notes=model.notes + tuple(notes),
    )


# -- which joints, with which settings ----------------------------------------


def _merged_specs(
    robot: Robot, tags: control_tags.ControlTags, file: ActuatorFile | None, notes: list[Note]
) -> tuple[dict[str, ActuatorSpec], set[str], dict[str, str]]:
    """Joint -> URDF settings overridden by the file's; the joints named explicitly;
    where each joint's actuator was declared."""
    specs: dict[str, ActuatorSpec] = {}
    sources: dict[str, str] = {}
    for name, spec in tags.specs.items():
        if name not in robot.joint_map:
            notes.append(
                Note(
                    "warning",
                    f"joint '{name}'",
                    f"named in {tags.sources[name]} but not in the URDF; skipped",
                )
            )
            continue
        specs[name], sources[name] = spec, tags.sources[name]
    explicit = set(specs)
    if file is None:
        return specs, explicit, sources
    for pattern, spec in file.joints:
        matched = [j.name for j in robot.joints if fnmatchcase(j.name, pattern)]
        if not matched:
            notes.append(
                Note(
                    "warning",
                    f"actuator file '{file.path.name}'",
                    f"joints pattern '{pattern}' matches no joint; ignored",
                )
            )
        for name in matched:
            specs[name] = spec.over(specs.get(name, ActuatorSpec()))
            sources.setdefault(name, "actuator file")
        if not _GLOB & set(pattern):
            explicit.update(matched)
    return specs, explicit, sources


def _is_follower(robot: Robot, joint: Joint) -> bool:
    """A mimic follower that emit ties to its leader with an equality (one-number joints)."""
    return (
        joint.mimic is not None
        and joint.type in _ACTUATABLE
        and robot.joint_map[joint.mimic.joint].type in _ACTUATABLE
    )


def _plan(
    robot: Robot,
    specs: dict[str, ActuatorSpec],
    explicit: set[str],
    sources: dict[str, str],
    notes: list[Note],
) -> tuple[dict[str, tuple[str, ActuatorSpec]], dict[str, JointTuning]]:
    """Actuated joint -> (kind, settings) in URDF order; joint tuning."""
    plan: dict[str, tuple[str, ActuatorSpec]] = {}
    tuning: dict[str, JointTuning] = {}
    for joint in robot.joints:
        spec = specs.get(joint.name)
        if spec is None:
            continue
        kind = spec.type or "position"
        where = f"joint '{joint.name}'"
        said = joint.name in explicit and kind != "none"
        if joint.type == "fixed":
            if said:
                notes.append(
                    Note("warning", where, f"fixed joint in {sources[joint.name]}; no actuator")
                )
            continue
        if any(v is not None for v in (spec.armature, spec.damping, spec.frictionloss)):
            tuning[joint.name] = JointTuning(spec.armature, spec.damping, spec.frictionloss)
        if kind == "none":
            continue
        if _is_follower(robot, joint):
            if said:
                leader = joint.mimic.joint  # type: ignore[union-attr]
                notes.append(
                    Note(
                        "info",
                        where,
                        f"mimics '{leader}': driven by its leader's actuator through the "
                        "equality constraint; no actuator of its own",
                    )
                )
            continue
        if joint.type not in _ACTUATABLE:
            if said:
                notes.append(
                    Note(
                        "warning",
                        where,
                        f"{joint.type} joint has several degrees of freedom; no actuator",
                    )
                )
            continue
        plan[joint.name] = (kind, spec)
    return plan, tuning


def _gravcomp(
    robot: Robot,
    existing: Mapping[str, float],
    cfg: ActuatorConfig,
    file: ActuatorFile | None,
    notes: list[Note],
) -> dict[str, float]:
    out = dict(existing)
    listed = file.gravcomp if file is not None else False
    if cfg.gravcomp or listed is True:
        out.update({link.name: 1.0 for link in robot.links if robot.is_moving(link.name)})
    if isinstance(listed, tuple):
        for pattern, fraction in listed:
            matched = [link.name for link in robot.links if fnmatchcase(link.name, pattern)]
            if not matched:
                notes.append(
                    Note(
                        "warning",
                        f"actuator file '{file.path.name}'",  # type: ignore[union-attr]
                        f"gravcomp pattern '{pattern}' matches no link; ignored",
                    )
                )
            out.update(dict.fromkeys(matched, fraction))
    return {k: v for k, v in out.items() if v != 0.0}


# -- ranges --------------------------------------------------------------------


def _symmetric(limit: float | None) -> tuple[float, float] | None:
    return (-limit, limit) if limit is not None and limit > 0 else None


def _effort(forcerange: tuple[float, float] | None) -> float | None:
    return max(abs(forcerange[0]), abs(forcerange[1])) if forcerange else None


def _ranges(
    joint: Joint, kind: str, spec: ActuatorSpec, notes: list[Note]
) -> tuple[tuple[float, float] | None, tuple[float, float] | None]:
    """(ctrlrange, forcerange) of the actuator of ``joint``."""
    limit = joint.limit
    if spec.forcerange is not None:
        force = None if spec.forcerange == (0.0, 0.0) else spec.forcerange
    else:
        force = _symmetric(limit.effort if limit else None)
    if kind == "position":
        ctrl = joint.range
    elif kind == "velocity":
        ctrl = _symmetric(limit.velocity if limit else None)
    else:
        ctrl = force  # a motor's command is its force
        if spec.forcerange is None:
            force = None
    if spec.ctrlrange is not None:
        lo = spec.ctrlrange[0] if spec.ctrlrange[0] is not None else (ctrl[0] if ctrl else None)
        hi = spec.ctrlrange[1] if spec.ctrlrange[1] is not None else (ctrl[1] if ctrl else None)
        if lo is None or hi is None or not lo < hi:
            notes.append(
                Note(
                    "warning",
                    f"joint '{joint.name}'",
                    f"command range [{lo}, {hi}] is incomplete or empty; no ctrlrange",
                )
            )
            ctrl = None
        else:
            ctrl = (lo, hi)
    return ctrl, force


# -- the robot's dynamics at the home pose ----------------------------------------


def _measure(
    model: Model,
    joints: list[str],
    cfg: ActuatorConfig,
    tree: RobotTree,
    compiles: HomeCompiles | None = None,
) -> ServoSystem:
    """Compile ``model`` in memory and linearise it at the home keyframe."""
    import mujoco

    robot = model.robot
    result = tree(replace(model, actuators=(), sensors=()), cfg.floating_base)
    try:
        # visual geoms carry no mass and touch nothing: left out of this compile
        m, d = compile_home(result.root, result.files, collision_only=True, compiles=compiles)
    except ValueError as exc:
        raise ValidationError(
            f"MuJoCo rejected the model while sizing actuator gains: {exc}", file=robot.source
        ) from None
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)

    def dof(name: str) -> int | None:
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0 or int(m.jnt_type[jid]) not in (hinge, slide):
            return None
        return int(m.jnt_dofadr[jid])

    # Mimic followers, resolved to their root leader: dof -> (leader dof, multiplier).
    follows: dict[int, tuple[int, float]] = {}
    for joint in robot.joints:
        if not _is_follower(robot, joint):
            continue
        k, name, seen = 1.0, joint.name, {joint.name}
        while _is_follower(robot, robot.joint_map[name]):
            mimic = robot.joint_map[name].mimic
            assert mimic is not None
            k, name = k * mimic.multiplier, mimic.joint
            if name in seen:  # a mimic cycle: no root leader
                break
            seen.add(name)
        f, lead = dof(joint.name), dof(name)
        if f is not None and lead is not None and f != lead:
            follows[f] = (lead, k)
    independent = [i for i in range(m.nv) if i not in follows]
    column = {i: c for c, i in enumerate(independent)}
    coupling = np.zeros((m.nv, len(independent)))
    for i in independent:
        coupling[i, column[i]] = 1.0
    for f, (lead, k) in follows.items():
        coupling[f, column[lead]] = k

    gravity = np.array(m.opt.gravity)
    weight = np.array(
        [m.body_mass[b] * (1.0 - model.gravcomp.get(m.body(b).name, 0.0)) for b in range(m.nbody)]
    )
    ancestors = [_ancestors(m, b) for b in range(m.nbody)]

    def worst_load(i: int) -> float:
        """Worst gravity load on dof ``i`` over its own motion, others at home."""
        jid = int(m.dof_jntid[i])
        moved = [b for b in range(m.nbody) if int(m.jnt_bodyid[jid]) in ancestors[b]]
        axis = np.array(d.xaxis[jid])
        if int(m.jnt_type[jid]) == slide:
            return abs(float(gravity @ axis)) * float(weight[moved].sum())
        moment = (weight[moved, None] * (d.xipos[moved] - d.xanchor[jid])).sum(axis=0)
        return float(np.linalg.norm(_perp(moment, axis)) * np.linalg.norm(_perp(gravity, axis)))

    index: dict[str, int] = {}
    load: dict[str, float] = {}
    linear: dict[str, bool] = {}
    for name in joints:
        own = dof(name)
        if own is None or own not in column:
            continue
        index[name] = col = column[own]
        members = np.flatnonzero(coupling[:, col])
        load[name] = sum(abs(coupling[k, col]) * worst_load(int(k)) for k in members)
        linear[name] = int(m.jnt_type[m.dof_jntid[own]]) == slide
    reduced = coupling.T @ full @ coupling
    # A hair of regularisation keeps the Cholesky factor defined for a dof with no inertia.
    reduced += np.eye(len(reduced)) * 1e-12 * max(float(np.diag(reduced).max(initial=0.0)), 1e-9)
    return ServoSystem(
        inertia=reduced,
        damping=coupling.T @ np.diag(m.dof_damping) @ coupling,
        index=index,
        load=load,
        linear=linear,
        timestep=float(m.opt.timestep),
    )


def _ancestors(m: Any, body: int) -> set[int]:
    """``body`` and every body above it, the world excluded."""
    out = set()
    while body > 0:
        out.add(body)
        body = int(m.body_parentid[body])
    return out


def _perp(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    return v - float(v @ axis) * axis
