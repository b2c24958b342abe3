"""Masses and the centre of mass: the description against a compiled model.

Each MuJoCo body carries the links matched to it: its own and those fused into
it (their sites are on it). A body's mass must be the sum of its links' masses
in the description, except where the description gives a link no usable
inertial and the model supplies one (:class:`Amended`): our conversion's
estimates and repairs, whose values it states, or, for a model we did not
write, whatever the model gives such a link (reported as a change, with the
mass it adds).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .kinematics import Match, set_qpos, with_mimics

_MASS_FLOOR = 1e-12
"""kg: masses below this compare as absolute differences (a relative error of a
massless link is meaningless)."""


@dataclass(frozen=True)
class LinkInertial:
    """A link's inertial in its own frame: mass, centre of mass, 3x3 tensor about it."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray


Amended = Mapping[str, LinkInertial | None]
"""Links whose inertial the model may supply: the value it must have (our conversion
knows it), or None (the model's own is taken)."""


def urdf_inertial(ref_link: Any) -> LinkInertial | None:
    """yourdfpy's link inertial, or None where the link has none (or mass 0)."""
    inertial = ref_link.inertial
    if inertial is None or not inertial.mass:
        return None
    origin = np.eye(4) if inertial.origin is None else np.asarray(inertial.origin, float)
    tensor = np.zeros((3, 3)) if inertial.inertia is None else np.asarray(inertial.inertia, float)
    r = origin[:3, :3]
    return LinkInertial(float(inertial.mass), origin[:3, 3].copy(), r @ tensor @ r.T)


def _mass(inertial: LinkInertial | None) -> float:
    return 0.0 if inertial is None else inertial.mass


def expected_inertials(mt: Match, amended: Amended) -> dict[str, LinkInertial | None]:
    """Per link: what the model must hold (None: nothing, or the model's own when amended)."""
    out: dict[str, LinkInertial | None] = {}
    for link in mt.ref.urdf.robot.links:
        out[link.name] = amended[link.name] if link.name in amended else urdf_inertial(link)
    return out


def groups(mt: Match) -> dict[int, list[str]]:
    """Body id -> the links it carries (its own, and those fused into it)."""
    out: dict[int, list[str]] = {}
    for link, (kind, i) in mt.frames.items():
        body = i if kind == "body" else int(mt.m.site_bodyid[i])
        out.setdefault(body, []).append(link)
    return out


def subtree(m: Any, root: int) -> list[int]:
    """``root`` and every body below it (MuJoCo numbers a parent before its children)."""
    inside = {root}
    for b in range(root + 1, m.nbody):
        if int(m.body_parentid[b]) in inside:
            inside.add(b)
    return sorted(inside)


def mass_section(
    mt: Match,
    home: Mapping[str, np.ndarray],
    amended: Amended,
    mass_tol: float,
    com_tol: float,
) -> tuple[dict[str, Any], list[str], list[dict[str, str]]]:
    """(section, failures, changes): total and per-body mass, centre of mass at home."""
    import mujoco

    m = mt.m
    d = mujoco.MjData(m)
    set_qpos(mt, d, with_mimics(mt.ref, {}))
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    r0, p0 = d.xmat[mt.root_body].reshape(3, 3), d.xpos[mt.root_body]
    expected = expected_inertials(mt, amended)
    urdf_kg = sum(i.mass for i in map(urdf_inertial, mt.ref.urdf.robot.links) if i is not None)
    bodies = subtree(m, mt.root_body)
    mjcf_kg = float(sum(m.body_mass[b] for b in bodies))
    failures: list[str] = []
    changes: list[dict[str, str]] = []
    mismatches: list[dict[str, Any]] = []
    added = sum(
        v.mass - _mass(urdf_inertial(mt.ref.urdf.link_map[k]))
        for k, v in amended.items()
        if v is not None
    )
    moment = np.zeros(3)
    welded = 0.0
    for body, links in groups(mt).items():
        have = float(m.body_mass[body])
        xipos = r0.T @ (d.xipos[body] - p0)
        free = [k for k in links if k in amended and amended[k] is None]
        fixed_mass = 0.0
        for k in links:
            e = expected[k]
            if e is None or k in free:
                continue
            if body == 0:  # fused into the world body, which has no mass in MuJoCo
                welded += e.mass
                changes.append(
                    {
                        "element": f"link '{k}'",
                        "kind": "welded",
                        "message": f"its {e.mass:.6g} kg is part of the world body, which has "
                        "no mass in MuJoCo (welded to the world, it moves nothing)",
                    }
                )
                continue
            fixed_mass += e.mass
            moment += e.mass * (home[k][:3, :3] @ e.com + home[k][:3, 3])
        if free:  # the model's own: what it adds is a change, not a failure
            extra = have - fixed_mass
            moment += extra * xipos
            added += extra
            if extra > _MASS_FLOOR:
                changes.append(
                    {
                        "element": f"link '{free[0]}'",
                        "kind": "inertial",
                        "message": f"the description gives no usable inertial; the model's "
                        f"body '{m.body(body).name}' adds {extra:.6g} kg",
                    }
                )
            continue
        err = abs(have - fixed_mass)
        if err > mass_tol * max(fixed_mass, have, _MASS_FLOOR):
            name = m.body(body).name
            mismatches.append(
                {"body": name, "links": links, "mjcf_kg": have, "urdf_kg": fixed_mass}
            )
            failures.append(
                f"mass.body '{name}': {have:.6g} kg, description {fixed_mass:.6g} kg "
                f"(relative {err / max(fixed_mass, _MASS_FLOOR):.3g} > {mass_tol:g})"
            )
    want_kg = urdf_kg + added - welded
    total_err = abs(mjcf_kg - want_kg)
    if total_err > mass_tol * max(want_kg, _MASS_FLOOR) and not mismatches:
        failures.append(
            f"mass.mjcf_kg: {mjcf_kg:.6g} kg, description {urdf_kg:.6g} kg"
            + (f" + {added:.6g} kg supplied" if added else "")
            + (f" - {welded:.6g} kg welded to the world" if welded else "")
            + f" (relative {total_err / max(want_kg, _MASS_FLOOR):.3g} > {mass_tol:g})"
        )
    com_err = None
    if mjcf_kg > 0 and want_kg > 0:
        have_com = sum(m.body_mass[b] * (r0.T @ (d.xipos[b] - p0)) for b in bodies) / mjcf_kg
        com_err = float(np.linalg.norm(have_com - moment / want_kg))
        if com_err > com_tol:
            failures.append(f"mass.com_error_m: {com_err:.3g} m > {com_tol:g}")
    section = {
        "urdf_kg": urdf_kg,
        "mjcf_kg": mjcf_kg,
        "added_kg": added,
        "welded_kg": welded,
        "com_error_m": com_err,
        "mismatches": mismatches,
    }
    return section, failures, changes
