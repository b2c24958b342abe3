"""A small converted arm and logs of a perturbed copy of it, for the calibration tests.

The truth is made independently of the calibration code: the converted MJCF's attributes
edited with lxml, compiled by MuJoCo, stepped by ``mj_step`` under a multi-sine of position
setpoints, with Gaussian sensor noise added to the log."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np
from lxml import etree

import urdf2mjcf

URDF = """<robot name="arm2">
  <link name="world"/>
  <link name="base"><inertial><mass value="2"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.1 0.1 0.05"/></geometry></collision></link>
  <joint name="fix" type="fixed"><parent link="world"/><child link="base"/></joint>
  <link name="upper"><inertial><origin xyz="0 0 0.15"/><mass value="1.5"/>
    <inertia ixx="0.012" iyy="0.012" izz="0.002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.15"/><geometry><box size="0.05 0.05 0.3"/></geometry>
    </collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.05"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="40" velocity="3"/><dynamics damping="0.5"/></joint>
  <link name="fore"><inertial><origin xyz="0 0 0.12"/><mass value="1.0"/>
    <inertia ixx="0.005" iyy="0.005" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.12"/><geometry><box size="0.04 0.04 0.24"/></geometry>
    </collision></link>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="20" velocity="3"/><dynamics damping="0.3"/></joint>
</robot>
"""

JOINTS = ("shoulder", "elbow")
NOMINAL_KP = {"shoulder": 3170.0, "elbow": 589.0}
"""The gains the converter designs for this arm (10 Hz, critically damped)."""


def convert(folder: Path) -> Path:
    """The arm converted with position servos on both joints."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "arm.urdf").write_text(URDF)
    (folder / "act.yaml").write_text('joints:\n  "*": {type: position}\n')
    out = folder / "out" / "arm.xml"
    urdf2mjcf.convert(
        folder / "arm.urdf", out, actuator_config=folder / "act.yaml", use_environment=False
    )
    return out


def perturbed(
    model: Path, dest: Path, joints: Mapping[str, Mapping[str, float]], kp: Mapping[str, float]
) -> Path:
    """``model`` with joint attributes and servo gains set as given."""
    tree = etree.parse(str(model))
    for el in tree.iter("joint"):
        for key, value in joints.get(el.get("name"), {}).items():
            el.set(key, repr(float(value)))
    for el in tree.iter("position"):
        if el.get("name") in kp:
            el.set("kp", repr(float(kp[el.get("name")])))
    dest.write_bytes(etree.tostring(tree))
    return dest


def record(
    model: Path,
    dest: Path,
    *,
    seconds: float = 10.0,
    rate: float = 500.0,
    seed: int = 0,
    amplitude: float | np.ndarray = 0.3,
    center: np.ndarray | None = None,
    q_noise: float = 2e-4,
    v_noise: float = 5e-3,
    still: tuple[int, ...] = (),
    odometry: list | None = None,
) -> Path:
    """A CSV log of ``model`` tracking a multi-sine sent and sampled at ``rate`` Hz, with noise;
    the actuators ``still`` hold ``center`` (default 0; ``amplitude``: one, or one per
    actuator). A floating base (a free joint) is logged as the calibration reads it: its
    position and quaternion (``q.<joint>.x`` .. ``.qz``), its velocity as MuJoCo holds it
    (``v.<joint>.vx`` .. ``.wz``). ``odometry``, where given, gets one row per sample of
    that base body's state as a ``nav_msgs/Odometry`` holds it, from MuJoCo's own body
    quantities (``xpos``, ``xquat`` and ``mj_objectVelocity`` in the body's frame), without
    noise: ``t``, position, quaternion (x, y, z, w), linear and angular velocity."""
    m = mujoco.MjModel.from_xml_path(str(model))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    freqs = np.array([0.2, 0.5, 0.9, 1.4, 2.0])
    phase = rng.uniform(0, 2 * np.pi, (m.nu, len(freqs)))
    gain = np.broadcast_to(np.asarray(amplitude, dtype=float), (m.nu,)).copy()
    gain[list(still)] = 0.0
    offset = np.zeros(m.nu) if center is None else np.asarray(center, dtype=float)
    every = max(1, int(round(1.0 / (rate * m.opt.timestep))))  # steps per log sample
    rows = []
    free = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    body = int(m.jnt_bodyid[free[0]]) if free else -1
    twist = np.zeros(6)
    for k in range(int(round(seconds / m.opt.timestep))):
        t = k * m.opt.timestep
        if k % every == 0:  # the controller sends a command at the log's rate
            sines = np.sin(2 * np.pi * freqs * t + phase).sum(axis=1)
            d.ctrl[:] = offset + gain * 2 / len(freqs) * sines
            rows.append([t, *d.qpos, *d.qvel, *d.ctrl])
            if odometry is not None and body >= 0:
                mujoco.mj_forward(m, d)
                mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, body, twist, 1)
                w, x, y, z = d.xquat[body]
                odometry.append([t, *d.xpos[body], x, y, z, w, *twist[3:], *twist[:3]])
        mujoco.mj_step(m, d)
    data = np.array(rows)
    data[:, 1 : 1 + m.nq] += rng.normal(0, q_noise, (len(data), m.nq))
    data[:, 1 + m.nq : 1 + m.nq + m.nv] += rng.normal(0, v_noise, (len(data), m.nv))
    q_cols: list[str] = []
    v_cols: list[str] = []
    for j in range(m.njnt):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        if int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE):
            q_cols += [f"q.{name}.{c}" for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]
            v_cols += [f"v.{name}.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")]
        else:
            q_cols.append(f"q.{name}")
            v_cols.append(f"v.{name}")
    assert len(q_cols) == m.nq and len(v_cols) == m.nv  # qpos and qvel in joint order
    acts = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(m.nu)]
    header = ["t", *q_cols, *v_cols, *(f"u.{a}" for a in acts)]
    lines = [",".join(header)] + [",".join(f"{x:.9g}" for x in row) for row in data]
    dest.write_text("\n".join(lines) + "\n")
    return dest
