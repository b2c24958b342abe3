"""Joint-space mass matrix and gravity torques: the model against pinocchio.

Only where pinocchio is installed (``pip install 'mjcf-forge[verify]'``):
pinocchio reads the description's expanded URDF (urdfdom, not our parser), its
inertials amended where the model supplies them (:mod:`.mass`), mimic followers
as independent joints (MuJoCo couples them by an equality constraint, which
the mass matrix does not see). The one-number joints are compared, and the
root's free joint when the model adds one (at identity orientation, where
pinocchio's local and MuJoCo's world linear velocities coincide); joint
armature, which the description does not have, is taken off MuJoCo's diagonal.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from .kinematics import Match, set_qpos, with_mimics
from .mass import LinkInertial
from .reference import urdfdom_error, urdfdom_quiet

log = logging.getLogger(__name__)

_TINY = 1e-12
DEPTH_MAX = 2_000
"""Links deep a description's tree may be for pinocchio to read it: urdfdom walks the
tree recursively in C++ and overflows the stack (a crash, not an error) somewhere
between 3,000 and 4,000 links deep; a deeper tree's dynamics are not compared."""


def tree_depth(joints: Any) -> int:
    """How many links deep the tree of ``joints`` (each with ``parent`` and ``child``
    link names) is, counted without recursion."""
    parent = {j.child: j.parent for j in joints}
    depth: dict[str, int] = {}
    for link in parent:
        path = []
        while link in parent and link not in depth:
            path.append(link)
            link = parent[link]
            if len(path) > len(parent):  # a cycle: the parse refuses it first
                return len(parent) + 1
        base = depth.get(link, 0)
        for k, name in enumerate(reversed(path), 1):
            depth[name] = base + k
    return 1 + max(depth.values(), default=0)


def available() -> bool:
    try:
        import pinocchio  # noqa: F401
    except ImportError:
        return False
    return True


def patched_xml(
    xml: bytes, inertials: Mapping[str, LinkInertial], drop: frozenset[str] = frozenset()
) -> str:
    """The URDF ``xml`` with the ``<inertial>`` of each link in ``inertials`` replaced,
    and that of each link in ``drop`` removed."""
    from lxml import etree

    root = etree.fromstring(xml, etree.XMLParser(remove_blank_text=False, resolve_entities=False))
    for link in root.findall("link"):
        name = link.get("name", "")
        new = inertials.get(name)
        if new is None and name not in drop:
            continue
        for old in link.findall("inertial"):
            link.remove(old)
        if new is None:
            continue
        el = etree.SubElement(link, "inertial")
        etree.SubElement(el, "origin", xyz=" ".join(repr(float(v)) for v in new.com), rpy="0 0 0")
        etree.SubElement(el, "mass", value=repr(float(new.mass)))
        i = new.inertia
        etree.SubElement(
            el,
            "inertia",
            ixx=repr(float(i[0, 0])),
            ixy=repr(float(i[0, 1])),
            ixz=repr(float(i[0, 2])),
            iyy=repr(float(i[1, 1])),
            iyz=repr(float(i[1, 2])),
            izz=repr(float(i[2, 2])),
        )
    return etree.tostring(root, encoding="unicode")


def body_inertial(m: Any, body: int) -> LinkInertial:
    """A body's inertial in its own frame (mass, centre of mass, tensor in body axes)."""
    import mujoco

    r = np.zeros(9)
    mujoco.mju_quat2Mat(r, m.body_iquat[body])
    r3 = r.reshape(3, 3)
    return LinkInertial(
        float(m.body_mass[body]),
        np.array(m.body_ipos[body]),
        r3 @ np.diag(m.body_inertia[body]) @ r3.T,
    )


def dynamics_section(
    mt: Match,
    configs: list[dict[str, float]],
    amended: Mapping[str, LinkInertial | None],
    tol: float,
) -> tuple[dict[str, Any], list[str]]:
    """(section, failures): relative error of the mass matrix and of the gravity torques."""
    if not available():
        return {"computed": False, "why": "pinocchio not installed"}, []
    import mujoco
    import pinocchio as pin

    m = mt.m
    patch: dict[str, LinkInertial] = {}
    for link, value in amended.items():
        if value is not None:
            patch[link] = value
            continue
        where = mt.frames.get(link)
        if where is None or where[0] != "body":
            why = f"link '{link}' has no inertial in the description and no body of its own"
            return {"computed": False, "why": why}, []
        patch[link] = body_inertial(m, where[1])
    # mass 0 is massless in MuJoCo, a rotational inertia given with it included (urdfdom
    # keeps it): compared without it, listed as a change (changes.massless_with_inertia)
    drop = frozenset(
        link.name
        for link in mt.ref.urdf.robot.links
        if link.name not in patch and link.inertial is not None and not link.inertial.mass
    )
    depth = tree_depth(mt.ref.urdf.robot.joints)
    if depth > DEPTH_MAX:
        why = f"the description is {depth} links deep; pinocchio reads at most {DEPTH_MAX}"
        return {"computed": False, "why": why}, []
    xml = patched_xml(mt.ref.document.xml, patch, drop)
    with urdfdom_quiet() as printed:  # urdfdom prints from C++: held back
        try:
            if mt.root_free is not None:
                pm = pin.buildModelFromXML(xml, pin.JointModelFreeFlyer())
            else:
                pm = pin.buildModelFromXML(xml)
            failure = None
        except Exception as exc:  # urdfdom refuses what yourdfpy read
            failure = exc
    if failure is not None:
        why = f"urdfdom cannot read the description: {urdfdom_error(printed, failure)[:200]}"
        return {"computed": False, "why": why}, []
    pd = pm.createData()
    plan = _dof_plan(mt, pm)
    if not plan:
        return {"computed": False, "why": "no joint to compare"}, []
    pin_dofs = [i for p, _ in plan for i in p]
    mj_dofs = [i for _, q in plan for i in q]
    d = mujoco.MjData(m)
    joints, names = list(pm.joints), list(pm.names)  # each access copies pinocchio's vector
    diff_m = diff_g = scale_m = scale_g = 0.0
    full = np.zeros((m.nv, m.nv))
    flags = m.opt.disableflags
    # the sensors (a lidar's rays) and contacts change neither matrix: not evaluated
    m.opt.disableflags = (
        flags | int(mujoco.mjtDisableBit.mjDSBL_SENSOR) | int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    )
    try:
        for cfg in configs:
            values = with_mimics(mt.ref, cfg)
            set_qpos(mt, d, values)
            if mt.root_free is not None:  # identity orientation: see the module's comment
                adr = m.jnt_qposadr[mt.root_free]
                d.qpos[adr + 3 : adr + 7] = (1.0, 0.0, 0.0, 0.0)
            mujoco.mj_forward(m, d)
            q = pin.neutral(pm)
            for j in range(1, pm.njoints):
                joint, angle = joints[j], values.get(names[j])
                if angle is None or joint.nv != 1:
                    continue
                if joint.nq == 2:  # continuous: (cos, sin)
                    q[joint.idx_q : joint.idx_q + 2] = (math.cos(angle), math.sin(angle))
                else:
                    q[joint.idx_q] = angle
            r0 = d.xmat[mt.root_body].reshape(3, 3)
            pm.gravity.linear = r0.T @ m.opt.gravity
            mass = pin.crba(pm, pd, q)
            mass = np.triu(mass) + np.triu(mass, 1).T
            gravity = pin.computeGeneralizedGravity(pm, pd, q)
            mujoco.mj_fullM(m, d, full)
            ours = full - np.diag(m.dof_armature)
            a = ours[np.ix_(mj_dofs, mj_dofs)]
            b = mass[np.ix_(pin_dofs, pin_dofs)]
            diff_m = max(diff_m, float(np.abs(a - b).max()))
            scale_m = max(scale_m, float(np.abs(b).max()))
            ga, gb = d.qfrc_bias[mj_dofs], gravity[pin_dofs]
            diff_g = max(diff_g, float(np.abs(ga - gb).max()))
            scale_g = max(scale_g, float(np.abs(gb).max()))
    finally:
        m.opt.disableflags = flags
    # Relative to the largest entry over all configurations: gravity torques vanish at
    # some poses (an arm pointing up), where a relative error per pose means nothing.
    # Torques below the robot's weight on a 1 mm lever count as zero.
    weight = float(sum(m.body_mass)) * float(np.linalg.norm(m.opt.gravity))
    worst_m = diff_m / max(scale_m, _TINY)
    worst_g = diff_g / max(scale_g, weight * 1e-3, _TINY)
    from .stored import version_of

    pin = version_of("pin")
    section = {
        "computed": True,
        "reference": f"pinocchio {pin}" if pin else "pinocchio",
        "configurations": len(configs),
        "dofs": len(mj_dofs),
        "mass_matrix_relative_error": worst_m,
        "gravity_relative_error": worst_g,
    }
    failures = []
    if worst_m > tol:
        failures.append(f"dynamics.mass_matrix_relative_error: {worst_m:.3g} > {tol:g}")
    if worst_g > tol:
        failures.append(f"dynamics.gravity_relative_error: {worst_g:.3g} > {tol:g}")
    return section, failures


def _dof_plan(mt: Match, pm: Any) -> list[tuple[list[int], list[int]]]:
    """(pinocchio velocity indices, MuJoCo dof indices) of every joint compared."""
    m = mt.m
    plan = []
    for j in range(1, pm.njoints):
        joint, name = pm.joints[j], pm.names[j]
        if mt.root_free is not None and j == 1 and joint.nv == 6:
            adr = int(m.jnt_dofadr[mt.root_free])
            plan.append((list(range(joint.idx_v, joint.idx_v + 6)), list(range(adr, adr + 6))))
            continue
        ids = mt.joints.get(name)
        if ids and len(ids) == 1 and joint.nv == 1:
            plan.append(([joint.idx_v], [int(m.jnt_dofadr[ids[0]])]))
    return plan
