"""Compare a converted robot with pinocchio, an independent URDF implementation."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

from urdf2mjcf.ir import Model


def example_robot_data_share() -> Path:
    """The share folder holding the ``example-robot-data`` package (a pip install)."""
    from importlib.metadata import distribution

    return Path(distribution("example-robot-data").locate_file("cmeel.prefix/share"))


def example_robot_data_urdfs() -> list[Path]:
    return sorted((example_robot_data_share() / "example-robot-data" / "robots").rglob("*.urdf"))


def patched_urdf(source: Path, model: Model, dest: Path) -> Path:
    """The source URDF with every repaired or estimated inertial replaced by ours.

    Lets pinocchio check the dynamics of the whole robot, our repairs included,
    while links whose inertial we kept remain exactly the user's.
    """
    tree = etree.parse(str(source))
    changed = {
        name: i for name, i in model.inertials.items() if i is not None and i.source != "urdf"
    }
    dropped = {name for name, i in model.inertials.items() if i is None}
    for link in tree.getroot().findall("link"):
        name = link.get("name")
        if name not in changed and name not in dropped:
            continue
        for old in link.findall("inertial"):
            link.remove(old)
        if name in changed:
            i = changed[name]
            ixx, iyy, izz, ixy, ixz, iyz = (repr(v) for v in i.fullinertia)
            el = etree.SubElement(link, "inertial")
            etree.SubElement(el, "origin", xyz=" ".join(repr(v) for v in i.pos), rpy="0 0 0")
            etree.SubElement(el, "mass", value=repr(i.mass))
            etree.SubElement(el, "inertia", ixx=ixx, ixy=ixy, ixz=ixz, iyy=iyy, iyz=iyz, izz=izz)
    tree.write(str(dest))
    return dest


@dataclass
class Comparison:
    max_frame_pos_err: float
    max_frame_rot_err: float
    max_gravity_rel_err: float
    frames: int
    dofs: int


def compare_with_pinocchio(
    urdf: Path,
    mjcf: Path,
    mimics: dict[str, tuple[str, float, float]],
    samples: int = 5,
    seed: int = 0,
) -> Comparison:
    """World pose of every link frame and joint gravity torques at random configurations."""
    import pinocchio as pin

    pm = pin.buildModelFromUrdf(str(urdf))
    pd = pm.createData()
    mm = mujoco.MjModel.from_xml_path(str(mjcf))
    md = mujoco.MjData(mm)
    rng = np.random.default_rng(seed)

    mj_joints = [mujoco.mj_id2name(mm, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(mm.njnt)]
    pin_joints = {pm.names[i]: i for i in range(1, pm.njoints)}
    assert set(mj_joints) == set(pin_joints), set(mj_joints) ^ set(pin_joints)
    links = [
        pm.frames[f].name for f in range(pm.nframes) if pm.frames[f].type == pin.FrameType.BODY
    ]

    worst = [0.0, 0.0, 0.0]
    for _ in range(samples):
        values: dict[str, float] = {}
        for j, name in enumerate(mj_joints):
            lo, hi = mm.jnt_range[j] if mm.jnt_limited[j] else (-math.pi, math.pi)
            values[name] = float(rng.uniform(lo, hi))
        for follower, (leader, mult, off) in mimics.items():
            values[follower] = mult * values[leader] + off
        q = pin.neutral(pm)
        for name, v in values.items():
            j = mm.joint(name)
            md.qpos[j.qposadr[0]] = v
            pj = pm.joints[pin_joints[name]]
            if pj.nq == 2:  # continuous joints are (cos, sin) in pinocchio
                q[pj.idx_q : pj.idx_q + 2] = (math.cos(v), math.sin(v))
            else:
                q[pj.idx_q] = v
        md.qvel[:] = 0
        mujoco.mj_forward(mm, md)
        pin.framesForwardKinematics(pm, pd, q)
        for link in links:
            placement = pd.oMf[pm.getFrameId(link, pin.FrameType.BODY)]
            body = mm.body(link)
            worst[0] = max(worst[0], float(np.abs(md.xpos[body.id] - placement.translation).max()))
            worst[1] = max(
                worst[1], float(np.abs(md.xmat[body.id].reshape(3, 3) - placement.rotation).max())
            )
        g_pin = pin.computeGeneralizedGravity(pm, pd, q)
        scale = max(float(np.abs(g_pin).max(initial=0.0)), 1e-9)
        for name in mj_joints:
            pj = pm.joints[pin_joints[name]]
            mj_val = md.qfrc_bias[mm.joint(name).dofadr[0]]
            worst[2] = max(worst[2], abs(mj_val - g_pin[pj.idx_v]) / scale)
    return Comparison(worst[0], worst[1], worst[2], len(links), mm.nv)


def check_robot(urdf: Path, out_dir: Path, **options) -> dict:
    """Convert one corpus robot and compare it with pinocchio.

    Returns a JSON-ready summary: sizes, worst errors, and every inertial we
    changed (repaired or estimated) with the reason. Used by the corpus test
    and by ``bench/corpus_report.py``, which writes docs/corpus.md.
    """
    import urdf2mjcf

    out = out_dir / "robot.xml"
    report = urdf2mjcf.convert(
        urdf, out, package_paths=[example_robot_data_share()], use_environment=False, **options
    )
    model = report.model
    summary = {
        "robot": urdf.stem,
        "file": str(urdf.relative_to(example_robot_data_share())),
        "links": len(model.robot.links),
        "changed_inertials": {
            n.element: n.message for n in report.notes if n.kind in ("repaired", "estimated")
        },
        "warnings": [f"{n.element}: {n.message}" for n in report.warnings],
        "decomposed": len(report.decomposed) + len(report.cached),
    }
    if not model.robot.links:
        m = mujoco.MjModel.from_xml_path(str(out))
        summary.update(
            bodies=m.nbody - 1, dofs=m.nv, frames=0, pos_err=0.0, rot_err=0.0, gravity_rel_err=0.0
        )
        return summary
    joints = model.robot.joint_map
    mimics = {  # as emitted: a mimic involving a fixed joint is ignored with a warning
        j.name: (j.mimic.joint, j.mimic.multiplier, j.mimic.offset)
        for j in model.robot.joints
        if j.mimic and "fixed" not in (j.type, joints[j.mimic.joint].type)
    }
    reference = patched_urdf(urdf, model, out_dir / "reference.urdf")
    cmp = compare_with_pinocchio(reference, out, mimics)
    summary.update(
        bodies=report.bodies,
        dofs=cmp.dofs,
        frames=cmp.frames,
        pos_err=cmp.max_frame_pos_err,
        rot_err=cmp.max_frame_rot_err,
        gravity_rel_err=cmp.max_gravity_rel_err,
    )
    return summary
