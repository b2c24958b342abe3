"""Link frames and joints: the description (urdfdom's frames where pinocchio reads it,
else yourdfpy's; yourdfpy's joints) against a compiled MuJoCo model.

Every pose is taken in the root link's frame on both sides, so a model placed
anywhere in its world (a hand-tuned one on a table, ours at the origin, a free
root anywhere) compares the same. URDF links are matched with bodies of the
same name (or the name a :class:`NameMap` gives); a link the conversion fused
into its parent (``--fuse-fixed``) is matched with the site of its name, which
sits at its frame. A URDF joint value ``q`` is MuJoCo's ``qpos0 + q`` (its
``ref``), multi-dof joints (floating, planar) stay at their zero displacement,
as both references' forward kinematics keep them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from .reference import Reference

SCALAR = ("revolute", "continuous", "prismatic")
_MJ_TYPE = {"revolute": "hinge", "continuous": "hinge", "prismatic": "slide"}
_UNLIMITED_SPAN = {"prismatic": 0.5, "revolute": math.pi, "continuous": math.pi}
"""Half-range sampled for a joint the description leaves unlimited (m or rad)."""


@dataclass(frozen=True)
class NameMap:
    """URDF names -> MJCF names where a model names them differently (identity otherwise)."""

    links: Mapping[str, str] = field(default_factory=dict)
    joints: Mapping[str, str] = field(default_factory=dict)

    def body(self, link: str) -> str:
        return self.links.get(link, link)

    def joint(self, joint: str) -> str:
        return self.joints.get(joint, joint)


def vector_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between unit vectors ``a`` and ``b``, exact near 0."""
    return 2 * math.asin(min(1.0, float(np.linalg.norm(a - b)) / 2))


@dataclass
class Match:
    """Where each URDF link and joint is in a compiled MuJoCo model."""

    ref: Reference
    m: Any
    names: NameMap
    root_body: int
    frames: dict[str, tuple[str, int]]
    """Link -> ("body" | "site", id) for every link found."""
    missing: list[str]
    """Links with neither a body nor a site of their name."""
    joints: dict[str, list[int]]
    """URDF joint (not fixed) -> MJCF joint ids (several for floating and planar)."""
    unmatched_joints: list[str]
    """URDF joints with no MJCF joint."""
    extra_joints: list[str]
    """MJCF joints of no URDF joint (a free joint on the root body is not one)."""
    root_free: int | None
    """The free joint on the root body that no URDF joint describes (--floating-base)."""

    def scalar(self) -> list[str]:
        """URDF one-number joints found in the model, in document order."""
        return [
            name
            for name, ids in self.joints.items()
            if self.ref.urdf.joint_map[name].type in SCALAR and len(ids) == 1
        ]


def _id(m: Any, kind: Any, name: str) -> int:
    import mujoco

    return int(mujoco.mj_name2id(m, kind, name))


def match(ref: Reference, m: Any, names: NameMap | None = None) -> Match:
    """Find the description's links and joints in ``m``; an InputError when its root
    link has no body (nothing can be compared)."""
    import mujoco

    names = names or NameMap()
    urdf = ref.urdf
    root = str(urdf.base_link)
    root_body = _id(m, mujoco.mjtObj.mjOBJ_BODY, names.body(root))
    if root_body < 0:
        raise InputError(
            f"the model has no body '{names.body(root)}' for the root link '{root}' "
            "(give a --name-map for a model that names its bodies differently)"
        )
    frames: dict[str, tuple[str, int]] = {}
    missing = []
    for link in ref.link_names:
        body = _id(m, mujoco.mjtObj.mjOBJ_BODY, names.body(link))
        site = _id(m, mujoco.mjtObj.mjOBJ_SITE, names.body(link))
        if body >= 0:
            frames[link] = ("body", body)
        elif site >= 0:
            frames[link] = ("site", site)
        else:
            missing.append(link)
    if len(frames) < 2 <= len(ref.link_names):  # the root at most: not this robot's model
        raise InputError(
            f"the model has no body or site for any link of '{ref.name}' but its root "
            "(give a --name-map for a model that names its bodies differently)"
        )
    joints: dict[str, list[int]] = {}
    unmatched = []
    for j in urdf.robot.joints:
        if j.type == "fixed":
            continue
        base = names.joint(j.name)
        one = _id(m, mujoco.mjtObj.mjOBJ_JOINT, base)
        if one >= 0:
            ids = [one]
        else:  # our planar (x, y, rot) and floating-below-the-root (x, y, z, rot) joints
            suffixes = {"planar": "x y rot", "floating": "x y z rot"}.get(j.type, "")
            ids = [_id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{base}_{s}") for s in suffixes.split()]
            if not ids or min(ids) < 0:
                ids = []
        if ids:
            joints[j.name] = ids
        else:
            unmatched.append(j.name)
    used = {i for ids in joints.values() for i in ids}
    root_free = None
    extra = []
    for jid in range(m.njnt):
        if jid in used:
            continue
        if m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_FREE and m.jnt_bodyid[jid] == root_body:
            root_free = jid
        else:
            extra.append(m.joint(jid).name or f"joint #{jid}")
    return Match(ref, m, names, root_body, frames, missing, joints, unmatched, extra, root_free)


def sample_configurations(ref: Reference, count: int, seed: int = 0) -> list[dict[str, float]]:
    """The home configuration (every joint at 0) and ``count`` random ones within the
    description's limits; values of the one-number actuated joints, by name."""
    rng = np.random.default_rng(seed)
    joints = [ref.urdf.joint_map[n] for n in ref.actuated_joints]
    joints = [j for j in joints if j.type in SCALAR]
    out: list[dict[str, float]] = [{j.name: 0.0 for j in joints}]
    for _ in range(count):
        cfg = {}
        for j in joints:
            lo, hi = _range(j)
            cfg[j.name] = float(rng.uniform(lo, hi))
        out.append(cfg)
    return out


def _range(joint: Any) -> tuple[float, float]:
    limit = joint.limit
    if joint.type != "continuous" and limit is not None:
        lo, hi = limit.lower, limit.upper
        if (
            lo is not None
            and hi is not None
            and math.isfinite(lo)
            and math.isfinite(hi)
            and lo < hi
        ):
            return float(lo), float(hi)
    span = _UNLIMITED_SPAN[joint.type]
    return -span, span


def with_mimics(ref: Reference, cfg: Mapping[str, float]) -> dict[str, float]:
    """``cfg`` with every mimic follower's value, as the description couples it."""
    out = dict(cfg)
    for j in ref.urdf.robot.joints:
        if j.mimic is not None and j.type in SCALAR:
            mult = 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier)
            off = 0.0 if j.mimic.offset is None else float(j.mimic.offset)
            out[j.name] = mult * out.get(j.mimic.joint, 0.0) + off
    return out


def config_vector(ref: Reference, cfg: Mapping[str, float]) -> np.ndarray:
    """``cfg`` in yourdfpy's actuated-joint order (other joints at 0)."""
    values = np.zeros(len(ref.actuated_joints))
    for i, name in enumerate(ref.actuated_joints):
        values[i] = cfg.get(name, 0.0)
    return values


def reference_frames(ref: Reference, cfg: Mapping[str, float]) -> dict[str, np.ndarray]:
    """The reference's link frames (root frame) at ``cfg`` (other joints at 0)."""
    return ref.frames(config_vector(ref, cfg))


def set_qpos(mt: Match, d: Any, cfg: Mapping[str, float]) -> None:
    """``d.qpos``: the model's zero (qpos0) moved by ``cfg`` (followers included)."""
    m = mt.m
    d.qpos[:] = m.qpos0
    for name, value in cfg.items():
        ids = mt.joints.get(name)
        if ids and len(ids) == 1:
            adr = m.jnt_qposadr[ids[0]]
            d.qpos[adr] = m.qpos0[adr] + value
    d.qvel[:] = 0


def model_frames(mt: Match, d: Any) -> dict[str, np.ndarray]:
    """The model's link frames (root frame) after kinematics of ``d``."""
    links, pos, rot = _model_poses(mt, d)
    out = {}
    for link, x, r in zip(links, pos, rot, strict=True):
        t = np.eye(4)
        t[:3, :3], t[:3, 3] = r, x
        out[link] = t
    return out


def _model_poses(mt: Match, d: Any) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(links, positions (n, 3), rotations (n, 3, 3)) of the matched links in the root
    body's frame, as :func:`model_frames`, in one array operation."""
    links = list(mt.frames)
    body = np.array([mt.frames[name][0] == "body" for name in links], bool)
    idx = np.array([mt.frames[name][1] for name in links], int)
    pos, mats = np.empty((len(links), 3)), np.empty((len(links), 9))
    pos[body], mats[body] = d.xpos[idx[body]], d.xmat[idx[body]]
    pos[~body], mats[~body] = d.site_xpos[idx[~body]], d.site_xmat[idx[~body]]
    r0, p0 = d.xmat[mt.root_body].reshape(3, 3), d.xpos[mt.root_body]
    rot = np.einsum("ji,njk->nik", r0, mats.reshape(-1, 3, 3))
    return links, (pos - p0) @ r0, rot


def frames_section(
    mt: Match, configs: list[dict[str, float]], position_tol: float, rotation_tol: float
) -> tuple[dict[str, Any], list[str], list[dict[str, np.ndarray]]]:
    """Worst link frame error over ``configs``: (section, failures, reference frames
    per configuration, for the sections that need them)."""
    import mujoco

    d = mujoco.MjData(mt.m)
    worst_p, worst_r = (0.0, "", 0), (0.0, "", 0)
    all_frames = []
    for k, cfg in enumerate(configs):
        full = with_mimics(mt.ref, cfg)
        ref_frames = reference_frames(mt.ref, full)
        all_frames.append(ref_frames)
        set_qpos(mt, d, full)
        mujoco.mj_kinematics(mt.m, d)
        links, pos, rot = _model_poses(mt, d)
        if not links:
            continue
        ref = np.stack([ref_frames[link] for link in links])
        p_err = np.linalg.norm(pos - ref[:, :3, 3], axis=1)
        # the rotation angle from the chord |a - b|_F = 2 sqrt(2) sin(angle / 2): arccos
        # of the trace would lose half the digits near 0
        chord = np.linalg.norm((rot - ref[:, :3, :3]).reshape(len(links), 9), axis=1)
        r_err = 2 * np.arcsin(np.minimum(1.0, chord / (2 * math.sqrt(2))))
        i, j = int(np.argmax(p_err)), int(np.argmax(r_err))
        if p_err[i] > worst_p[0]:
            worst_p = (float(p_err[i]), links[i], k)
        if r_err[j] > worst_r[0]:
            worst_r = (float(r_err[j]), links[j], k)
    section: dict[str, Any] = {
        "max_position_error_m": worst_p[0],
        "max_rotation_error_rad": worst_r[0],
        "configurations": len(configs),
        "links": len(mt.frames),
        "worst_position_link": worst_p[1] or None,
        "worst_rotation_link": worst_r[1] or None,
        "missing_links": list(mt.missing),
    }
    failures = []
    if worst_p[0] > position_tol:
        failures.append(
            f"frames.max_position_error_m: {worst_p[0]:.3g} m > {position_tol:g} "
            f"(link '{worst_p[1]}', {_config_name(worst_p[2])})"
        )
    if worst_r[0] > rotation_tol:
        failures.append(
            f"frames.max_rotation_error_rad: {worst_r[0]:.3g} rad > {rotation_tol:g} "
            f"(link '{worst_r[1]}', {_config_name(worst_r[2])})"
        )
    if mt.missing:
        shown = ", ".join(f"'{n}'" for n in mt.missing[:5])
        more = f" and {len(mt.missing) - 5} more" if len(mt.missing) > 5 else ""
        failures.append(
            f"frames.missing_links: {len(mt.missing)} > 0 (no body or site for link {shown}{more})"
        )
    return section, failures, all_frames


def _config_name(k: int) -> str:
    return "at home" if k == 0 else f"configuration {k}"


def joints_section(
    mt: Match, home: Mapping[str, np.ndarray], tol: Any
) -> tuple[dict[str, Any], list[str], list[dict[str, str]]]:
    """Joint types, axes and anchors at home, limits and mimic couplings:
    (section, failures, changes the model makes that the description allows for)."""
    import mujoco

    m = mt.m
    d = mujoco.MjData(m)
    set_qpos(mt, d, with_mimics(mt.ref, {}))
    mujoco.mj_kinematics(m, d)
    r0, p0 = d.xmat[mt.root_body].reshape(3, 3), d.xpos[mt.root_body]
    mismatches: list[dict[str, Any]] = []
    changes: list[dict[str, str]] = []

    def bad(joint: str, figure: str, value: Any, tolerance: Any, message: str) -> None:
        mismatches.append(
            {
                "joint": joint,
                "figure": figure,
                "value": value,
                "tolerance": tolerance,
                "message": message,
            }
        )

    for name in mt.unmatched_joints:
        bad(name, "missing", None, None, f"no MJCF joint '{mt.names.joint(name)}'")
    for name in mt.extra_joints:
        bad(name, "extra", None, None, "a model joint the description does not have")
    if mt.root_free is not None:
        changes.append(
            {
                "element": f"body '{m.body(mt.root_body).name}'",
                "kind": "floating base",
                "message": "the root body has a free joint the description does not have",
            }
        )
    checked = 0
    for name, ids in mt.joints.items():
        j = mt.ref.urdf.joint_map[name]
        checked += 1
        types = [int(m.jnt_type[i]) for i in ids]
        want = _expected_types(j.type, len(ids))
        if types not in want:
            got = "+".join(mujoco.mjtJoint(t).name.removeprefix("mjJNT_").lower() for t in types)
            bad(name, "type", got, j.type, f"{j.type} joint is {got} in the model")
            continue
        if j.type not in SCALAR:
            continue
        jid = ids[0]
        axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), float)
        axis = axis / np.linalg.norm(axis)
        child = home[j.child]
        want_axis = child[:3, :3] @ axis
        got_axis = r0.T @ d.xaxis[jid]
        angle = vector_angle(want_axis, got_axis)
        if angle > tol.joint_axis_rad:
            bad(name, "axis", angle, tol.joint_axis_rad, f"axis off by {angle:.3g} rad")
        anchor = float(np.linalg.norm(r0.T @ (d.xanchor[jid] - p0) - child[:3, 3]))
        if anchor > tol.joint_anchor_m:
            bad(name, "anchor", anchor, tol.joint_anchor_m, f"anchor off by {anchor:.3g} m")
        _check_limits(mt, j, jid, tol, bad, changes)
    _check_mimics(mt, tol, bad, changes)
    section = {"checked": checked, "mismatches": mismatches}
    failures = [
        f"joints.{x['figure']}: joint '{x['joint']}': {x['message']}"
        + (f" > {x['tolerance']:g}" if isinstance(x["tolerance"], float) else "")
        for x in mismatches
    ]
    return section, failures, changes


def _expected_types(urdf_type: str, n: int) -> list[list[int]]:
    import mujoco

    t = mujoco.mjtJoint
    if urdf_type in _MJ_TYPE:
        return [[int(t.mjJNT_HINGE if _MJ_TYPE[urdf_type] == "hinge" else t.mjJNT_SLIDE)]]
    if urdf_type == "floating":
        return [[int(t.mjJNT_FREE)], [int(t.mjJNT_SLIDE)] * 3 + [int(t.mjJNT_BALL)]]
    if urdf_type == "planar":
        return [[int(t.mjJNT_SLIDE), int(t.mjJNT_SLIDE), int(t.mjJNT_HINGE)]]
    return []


def _check_limits(mt: Match, j: Any, jid: int, tol: Any, bad: Any, changes: list) -> None:
    m = mt.m
    limited = bool(m.jnt_limited[jid])
    ref0 = float(m.qpos0[m.jnt_qposadr[jid]])
    rng = (float(m.jnt_range[jid][0]) - ref0, float(m.jnt_range[jid][1]) - ref0)
    if j.type == "continuous":
        if limited:
            bad(j.name, "limits", list(rng), None, f"continuous joint limited to {rng}")
        return
    limit = j.limit
    lo = None if limit is None else limit.lower
    hi = None if limit is None else limit.upper
    if lo is None and hi is None:
        if limit is None or not limited:  # no limit given: unlimited, as urdfdom reads it
            return
    lo, hi = float(lo or 0.0), float(hi or 0.0)
    if not lo < hi:  # no range: MuJoCo cannot limit it; unlimited is the model's choice
        if limited:
            bad(j.name, "limits", list(rng), None, f"limited to {rng}; description: {lo}..{hi}")
        else:
            changes.append(
                {
                    "element": f"joint '{j.name}'",
                    "kind": "limit",
                    "message": f"limit has no range ({lo:g} .. {hi:g}); unlimited in the model",
                }
            )
        return
    if not limited:
        bad(j.name, "limits", None, tol.joint_limit, f"unlimited; description: {lo:g} .. {hi:g}")
        return
    err = max(abs(rng[0] - lo), abs(rng[1] - hi))
    if err > tol.joint_limit:
        bad(
            j.name,
            "limits",
            err,
            tol.joint_limit,
            f"range {rng[0]:.6g} .. {rng[1]:.6g}, description {lo:.6g} .. {hi:.6g}: off by "
            f"{err:.3g}",
        )


def _check_mimics(mt: Match, tol: Any, bad: Any, changes: list) -> None:
    import mujoco

    m = mt.m
    couplings: dict[tuple[int, int], np.ndarray] = {}
    for e in range(m.neq):
        if m.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT and m.eq_active0[e]:
            couplings[(int(m.eq_obj1id[e]), int(m.eq_obj2id[e]))] = np.array(m.eq_data[e][:5])
    jmap = mt.ref.urdf.joint_map
    for j in mt.ref.urdf.robot.joints:
        if j.mimic is None:
            continue
        leader = jmap.get(j.mimic.joint)
        if leader is None or j.type not in SCALAR or leader.type not in SCALAR:
            changes.append(
                {
                    "element": f"joint '{j.name}'",
                    "kind": "mimic",
                    "message": f"mimics '{j.mimic.joint}', which MuJoCo cannot couple "
                    "(one of them is not a one-number joint); not coupled",
                }
            )
            continue
        a, b = mt.joints.get(j.name), mt.joints.get(leader.name)
        if not a or not b:
            continue  # reported as a missing joint
        poly = couplings.get((a[0], b[0]))
        if poly is None:
            bad(
                j.name, "mimic", None, None, f"mimics '{leader.name}' but the model has no coupling"
            )
            continue
        mult = 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier)
        off = 0.0 if j.mimic.offset is None else float(j.mimic.offset)
        err = float(np.abs(poly - np.array([off, mult, 0.0, 0.0, 0.0])).max())
        if err > tol.mimic:
            bad(
                j.name,
                "mimic",
                err,
                tol.mimic,
                f"coupling {poly[1]:g} x + {poly[0]:g}, description {mult:g} x + {off:g}",
            )
