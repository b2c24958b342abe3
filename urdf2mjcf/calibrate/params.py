"""Which parameters a calibration frees, their bounds, and where each lives in a model.

``--free damping,frictionloss,armature,gains,masses,payload,delay`` frees a kind for every
joint (damping, frictionloss, armature), actuator (gains), moving body (masses), the tool
(payload: a point mass at the last body's origin) or the log (delay: one sensor delay, s).
A ``--params`` YAML file then frees, fixes or bounds single ones::

    joints:
      elbow: {damping: [0, 5], frictionloss: false}   # [lo, hi]: free within; false: fixed
    actuators:
      shoulder: {kp: [1000, 8000]}
    bodies:
      fore: {mass: true}                               # true: free, default bounds
    payload: {body: fore, mass: [0, 3]}
    delay: [0, 0.02]

What ``gains`` means per actuator: a position servo's ``kp``, a velocity servo's ``kv``, a
motor's gain (its ``gainprm[0]``). A position servo's ``kv`` is not freed with it: it is
the same torque on the joint as the joint's damping, so the two could not be told apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .. import schema
from ..errors import InputError

KINDS = ("damping", "frictionloss", "armature", "gains", "masses", "payload", "delay")
"""What ``--free`` takes."""

DEFAULT_FREE = ("damping", "frictionloss", "armature")

JOINT_FIELDS = ("damping", "frictionloss", "armature")
GAIN_FIELDS = ("kp", "kv", "gain")


@dataclass(frozen=True)
class Param:
    """One free parameter."""

    field: str
    """``damping``, ``frictionloss``, ``armature`` (joint), ``kp``, ``kv``, ``gain``
    (actuator), ``mass`` (body: scales its mass and inertia), ``payload`` (kg at
    ``target``'s origin) or ``delay`` (s, of every measured signal)."""
    target: str
    """The joint, actuator or body it belongs to ('' for the delay)."""
    nominal: float
    """Its value in the model given (kg for ``mass``)."""
    lo: float
    hi: float

    @property
    def label(self) -> str:
        return f"{self.target}.{self.field}" if self.target else self.field

    @property
    def owner(self) -> str:
        """What it belongs to, in words."""
        if self.field in JOINT_FIELDS:
            return f"joint '{self.target}'"
        if self.field in GAIN_FIELDS:
            return f"actuator '{self.target}'"
        if self.field in ("mass", "payload"):
            return f"body '{self.target}'"
        return "the logs"


BASE_Q = ("x", "y", "z", "qw", "qx", "qy", "qz")
"""A floating base's logged position (m, in the world) and orientation (a unit
quaternion, w first): columns ``q.<base>.x`` .. ``q.<base>.qz``, as MuJoCo's free joint
holds them."""
BASE_V = ("vx", "vy", "vz", "wx", "wy", "wz")
"""A floating base's logged velocity, as MuJoCo's free joint holds it: linear in the
world (m/s), angular in the base's own frame (rad/s, as a body-mounted IMU's gyro reads
it): columns ``v.<base>.vx`` .. ``v.<base>.wz``."""


def joint_ids(m: Any) -> list[int]:
    """The model's hinge and slide joints, in order: a floating base (one free joint) is
    left out, its state logged apart (:func:`floating_base`); :class:`InputError` for a ball
    joint (its state is not what a joint log holds)."""
    ids = []
    hinge_or_slide = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    for j in range(m.njnt):
        kind = int(m.jnt_type[j])
        if kind == int(mujoco.mjtJoint.mjJNT_BALL):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint {j}"
            raise InputError(
                f"joint '{name}' is a ball joint; calibrate fits robots whose joints are "
                "hinges and slides, on a fixed or one floating base"
            )
        if kind in hinge_or_slide:
            ids.append(j)
    base_joint_id(m)  # at most one floating base
    return ids


def joint_names(m: Any) -> list[str]:
    """The names of :func:`joint_ids`' joints."""
    return [
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint {j}" for j in joint_ids(m)
    ]


def base_joint_id(m: Any) -> int | None:
    """The id of the model's floating base (its one free joint), or None for a fixed
    base; :class:`InputError` for more than one (a log follows one robot)."""
    free = [j for j in range(m.njnt) if int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE)]
    if len(free) > 1:
        raise InputError(
            f"the model has {len(free)} free joints; calibrate fits one robot, on a fixed "
            "or one floating base (give the robot's own model, not a world of several)"
        )
    return free[0] if free else None


@dataclass(frozen=True)
class Base:
    """A model's floating base, as a log names it."""

    joint: str
    """The free joint's name (``joint N`` where it has none): the CSV's columns are
    ``q.<joint>.x`` .. ``v.<joint>.wz``."""
    body: str
    """The body it moves: the frame a bag's ``nav_msgs/Odometry`` must be of."""


def floating_base(m: Any) -> Base | None:
    """The model's floating base (:func:`base_joint_id`), or None for a fixed base."""
    j = base_joint_id(m)
    if j is None:
        return None
    body = int(m.jnt_bodyid[j])
    return Base(
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint {j}",
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, body) or f"body {body}",
    )


def actuator_names(m: Any) -> list[str]:
    return [
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) or f"actuator {a}"
        for a in range(m.nu)
    ]


def position_servos(m: Any) -> dict[str, str]:
    """Joint name -> the name of the position servo that drives it: what a
    ``JointTrajectory``'s positions command (:func:`.logs.read_bag`)."""
    names = actuator_names(m)
    out: dict[str, str] = {}
    joint_kind = int(mujoco.mjtTrn.mjTRN_JOINT)
    for a in range(m.nu):
        if gain_field(m, a) == "kp" and int(m.actuator_trntype[a]) == joint_kind:
            j = int(m.actuator_trnid[a, 0])
            out.setdefault(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or "", names[a])
    return out


def gain_field(m: Any, a: int) -> str:
    """``kp`` for a position servo, ``kv`` for a velocity servo, else ``gain``."""
    if (
        int(m.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
        and int(m.actuator_biastype[a]) == 1
    ):
        if m.actuator_biasprm[a, 1] != 0.0:
            return "kp"
        if m.actuator_biasprm[a, 2] != 0.0:
            return "kv"
    return "gain"


def leaf_bodies(m: Any) -> list[int]:
    """Bodies with no child, in order: a tool is one."""
    parents = set(int(p) for p in m.body_parentid[1:])
    return [b for b in range(1, m.nbody) if b not in parents]


def value(m: Any, p: Param) -> float:
    """``p``'s value in the compiled model ``m``."""
    if p.field in JOINT_FIELDS:
        dof = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, p.target)]
        return float(getattr(m, f"dof_{p.field}")[dof])
    if p.field in GAIN_FIELDS:
        return float(
            m.actuator_gainprm[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, p.target), 0]
        )
    if p.field == "mass":
        return float(m.body_mass[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, p.target)])
    return 0.0  # a payload or delay the model does not hold


def select(m: Any, free: Sequence[str], params_file: Path | None = None) -> list[Param]:
    """The free parameters of the compiled model ``m``: ``free``'s kinds for every joint,
    actuator or body, then ``params_file``'s entries."""
    bad = [k for k in free if k not in KINDS]
    if bad:
        raise InputError(
            f"--free: unknown {', '.join(repr(b) for b in bad)}; choose from {', '.join(KINDS)}"
        )
    chosen: dict[tuple[str, str], tuple[float, float]] = {}
    joints, actuators = joint_names(m), actuator_names(m)
    bodies = [
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or f"body {b}" for b in range(m.nbody)
    ]
    for kind in free:
        if kind in JOINT_FIELDS:
            chosen.update({(j, kind): default_bounds(m, j, kind) for j in joints})
        elif kind == "gains":
            for a, name in enumerate(actuators):
                chosen[(name, gain_field(m, a))] = default_bounds(m, name, gain_field(m, a))
        elif kind == "masses":
            for b in range(1, m.nbody):
                if m.body_dofnum[b] or m.body_parentid[b] and _moves(m, b):
                    chosen[(bodies[b], "mass")] = default_bounds(m, bodies[b], "mass")
        elif kind == "payload":
            tool = bodies[leaf_bodies(m)[-1]]
            chosen[(tool, "payload")] = default_bounds(m, tool, "payload")
        elif kind == "delay":
            chosen[("", "delay")] = default_bounds(m, "", "delay")
    if params_file is not None:
        _read_params(m, params_file, chosen, joints, actuators, bodies)
    out = []
    for (target, field), (lo, hi) in chosen.items():
        nominal = value(m, Param(field, target, 0.0, lo, hi))
        out.append(Param(field, target, nominal, lo, hi))
    return out


def _moves(m: Any, b: int) -> bool:
    while b:
        if m.body_dofnum[b]:
            return True
        b = m.body_parentid[b]
    return False


def default_bounds(m: Any, target: str, field: str) -> tuple[float, float]:
    """Bounds sensible for an arm: wide enough for a URDF's guess to be far off."""
    nominal = value(m, Param(field, target, 0.0, 0.0, 0.0)) if field != "payload" else 0.0
    if field == "damping":
        return 0.0, max(10.0 * nominal, 50.0)
    if field == "frictionloss":
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, target)
        effort = float(np.max(np.abs(m.jnt_actfrcrange[j]))) if m.jnt_actfrclimited[j] else 0.0
        return 0.0, max(10.0 * nominal, 0.5 * effort, 20.0)
    if field == "armature":
        return 0.0, max(10.0 * nominal, 1.0)
    if field in GAIN_FIELDS:
        return 0.2 * nominal, 5.0 * nominal
    if field == "mass":
        return 0.5 * nominal, 2.0 * nominal
    if field == "payload":
        return 0.0, 10.0
    return 0.0, 0.05  # delay, s


def _bounds(
    raw: Any, path: Path, where: str, default: tuple[float, float]
) -> tuple[float, float] | None:
    if raw is True:
        return default
    if raw is False:
        return None
    if (
        isinstance(raw, list)
        and len(raw) == 2
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in raw)
        and np.isfinite(raw).all()
        and 0 <= raw[0] < raw[1]
    ):
        return float(raw[0]), float(raw[1])
    raise InputError(
        "expected [lo, hi] with 0 <= lo < hi (free within), true (free, default bounds) or "
        "false (fixed)",
        file=path,
        element=where,
    )


def _read_params(
    m: Any,
    path: Path,
    chosen: dict[tuple[str, str], tuple[float, float]],
    joints: list[str],
    actuators: list[str],
    bodies: list[str],
) -> None:
    data, _source = schema.load(path, "parameter file")
    data = {} if data is None else data
    sections = ("joints", "actuators", "bodies", "payload", "delay")
    if not isinstance(data, dict) or set(data) - set(sections):
        raise InputError(f"a parameter file is a mapping of {', '.join(sections)}", file=path)

    def each(section: str, names: list[str], fields: Sequence[str]) -> None:
        entries = data.get(section) or {}
        if not isinstance(entries, dict):
            raise InputError(
                f"{section}: expected a mapping NAME: {{FIELD: BOUNDS}}", file=path, element=section
            )
        for name, fields_of in entries.items():
            where = f"{section}.{name}"
            if name not in names:
                raise InputError(
                    f"the model has no such {section[:-1]} (it has {', '.join(names[:8])})",
                    file=path,
                    element=where,
                )
            if not isinstance(fields_of, dict):
                raise InputError(
                    f"expected a mapping of {', '.join(fields)}", file=path, element=where
                )
            for field, raw in fields_of.items():
                if field not in fields:
                    raise InputError(
                        f"unknown key {field!r}; expected {', '.join(fields)}",
                        file=path,
                        element=f"{where}.{field}",
                    )
                if field in GAIN_FIELDS:
                    real = gain_field(m, actuators.index(name))
                    if field != real:
                        raise InputError(
                            f"this actuator's gain is {real!r}",
                            file=path,
                            element=f"{where}.{field}",
                        )
                got = _bounds(raw, path, f"{where}.{field}", default_bounds(m, name, field))
                if got is None:
                    chosen.pop((name, field), None)
                else:
                    chosen[(name, field)] = got

    each("joints", joints, JOINT_FIELDS)
    each("actuators", actuators, GAIN_FIELDS)
    each("bodies", bodies[1:], ("mass",))
    payload = data.get("payload")
    if payload is not None:
        if (
            not isinstance(payload, dict)
            or set(payload) - {"body", "mass"}
            or payload.get("body") not in bodies[1:]
        ):
            raise InputError(
                "payload: expected {body: BODY, mass: BOUNDS} naming a body of the model",
                file=path,
                element="payload",
            )
        got = _bounds(
            payload.get("mass", True),
            path,
            "payload.mass",
            default_bounds(m, payload["body"], "payload"),
        )
        for key in [k for k in chosen if k[1] == "payload"]:
            chosen.pop(key)
        if got is not None:
            chosen[(payload["body"], "payload")] = got
    if "delay" in data:
        got = _bounds(data["delay"], path, "delay", default_bounds(m, "", "delay"))
        chosen.pop(("", "delay"), None)
        if got is not None:
            chosen[("", "delay")] = got


class Applier:
    """Writes parameter values into copies of one compiled model, fast (no recompile)."""

    def __init__(self, m: Any, params: Sequence[Param]):
        self.base = m
        self.params = list(params)
        self._index = []
        for p in self.params:
            if p.field in JOINT_FIELDS:
                i = int(m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, p.target)])
            elif p.field in GAIN_FIELDS:
                i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, p.target)
            elif p.field in ("mass", "payload"):
                i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, p.target)
            else:
                i = -1
            self._index.append(i)
        # armature, masses and a payload change the constants MuJoCo derives at compile time
        # from the inertia at qpos0 (dof_invweight0 sets how soft friction and limits are)
        self.inertial = any(p.field in ("armature", "mass", "payload") for p in self.params)

    def model(self, x: np.ndarray) -> Any:
        """A copy of the model with the parameters at ``x``."""
        m = self.base.__copy__()
        for p, i, val in zip(self.params, self._index, x, strict=True):
            if p.field in JOINT_FIELDS:
                getattr(m, f"dof_{p.field}")[i] = val
            elif p.field == "kp":
                m.actuator_gainprm[i, 0] = val
                m.actuator_biasprm[i, 1] = -val
            elif p.field == "kv":
                m.actuator_gainprm[i, 0] = val
                m.actuator_biasprm[i, 2] = -val
            elif p.field == "gain":
                m.actuator_gainprm[i, 0] = val
            elif p.field == "mass":
                scale = val / self.base.body_mass[i]
                m.body_mass[i] = val
                m.body_inertia[i] = self.base.body_inertia[i] * scale
            elif p.field == "payload":
                add_point_mass(m, i, float(val))
        if self.inertial:
            mujoco.mj_setConst(m, mujoco.MjData(m))
        return m

    def delay(self, x: np.ndarray) -> float:
        for p, val in zip(self.params, x, strict=True):
            if p.field == "delay":
                return float(val)
        return 0.0


def add_point_mass(m: Any, body: int, mass: float) -> None:
    """Add ``mass`` kg at ``body``'s origin to its inertial (mass, centre, inertia)."""
    if mass <= 0.0:
        return
    m0 = float(m.body_mass[body])
    c0 = np.array(m.body_ipos[body])
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, m.body_iquat[body])
    r = rot.reshape(3, 3)
    inertia0 = r @ np.diag(m.body_inertia[body]) @ r.T
    total = m0 + mass
    c = m0 * c0 / total
    d0, dp = c0 - c, -c
    eye = np.eye(3)
    inertia = (
        inertia0
        + m0 * (d0 @ d0 * eye - np.outer(d0, d0))
        + mass * (dp @ dp * eye - np.outer(dp, dp))
    )
    w, vecs = np.linalg.eigh(inertia)
    if np.linalg.det(vecs) < 0:
        vecs[:, 0] = -vecs[:, 0]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, vecs.flatten())
    m.body_mass[body] = total
    m.body_ipos[body] = c
    m.body_iquat[body] = quat
    m.body_inertia[body] = np.maximum(w, 1e-12)
