"""Judge the demo: intended and unintended contacts per step, and the final success.

Each step declares the contacts it intends as pairs of body-name patterns
(fnmatch globs, e.g. ``["finger_*", "ctb"]``). Any other contact between the
robot or the carried bag and the environment (floor, mockups) fails the step
with a message naming the bodies. Success: after the robot retreats the CTB
lies inside the bin's inner volume, tilted < 10 deg and slower than 1 cm/s.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .load import Facility


@dataclass
class ContactLog:
    intended: set[tuple[str, str]] = field(default_factory=set)
    unintended: dict[tuple[str, str], float] = field(default_factory=dict)  # pair -> deepest (m)


class ContactJudge:
    """Called after every physics step; collects contacts of the current step."""

    def __init__(self, fac: Facility, bag_body: str, tolerance: float = 1e-4):
        self.fac = fac
        self.m, self.d = fac.model, fac.data
        self.robot = fac.robot.bodies
        self.bag = fac.body(bag_body)
        self.tolerance = tolerance
        self.allowed: list[tuple[str, str]] = []
        self.carried = False
        self.log = ContactLog()

    def begin(self, allowed: list[list[str]] | None, carried: bool) -> None:
        self.allowed = [(p[0], p[1]) for p in (allowed or [])]
        self.carried = carried
        self.log = ContactLog()

    def _match(self, a: str, b: str) -> bool:
        for p, q in self.allowed:
            if (fnmatch.fnmatch(a, p) and fnmatch.fnmatch(b, q)) or (
                fnmatch.fnmatch(a, q) and fnmatch.fnmatch(b, p)
            ):
                return True
        return False

    def __call__(self) -> None:
        m, d = self.m, self.d
        for i in range(d.ncon):
            c = d.contact[i]
            if c.dist > -self.tolerance:
                continue
            b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
            r1, r2 = b1 in self.robot, b2 in self.robot
            if r1 and r2:
                continue  # the robot's own parts
            g1, g2 = b1 == self.bag, b2 == self.bag
            involved = r1 or r2 or ((g1 or g2) and self.carried)
            if not involved:
                continue
            n1, n2 = self.fac.link_of_geom(c.geom[0]), self.fac.link_of_geom(c.geom[1])
            pair = (n1, n2) if n1 <= n2 else (n2, n1)
            if self._match(n1, n2):
                self.log.intended.add(pair)
            else:
                depth = -float(c.dist)
                self.log.unintended[pair] = max(depth, self.log.unintended.get(pair, 0.0))

    def message(self) -> str | None:
        if not self.log.unintended:
            return None
        worst = sorted(self.log.unintended.items(), key=lambda kv: -kv[1])
        return "unintended contact: " + ", ".join(
            f"{a} with {b} ({1000 * dep:.1f} mm deep)" for (a, b), dep in worst[:4]
        )


@dataclass
class Verdict:
    ok: bool
    inside: bool
    tilt_deg: float
    speed: float  # m/s
    outside_by: float  # m, worst corner outside the volume (0 when inside)
    message: str


def box_corners(m: mujoco.MjModel, d: mujoco.MjData, geom: int) -> np.ndarray:
    s = m.geom_size[geom]
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    R = d.geom_xmat[geom].reshape(3, 3)
    return d.geom_xpos[geom] + (signs * s) @ R.T


def stowed(
    fac: Facility,
    bag_body: str,
    bag_geom: str,
    bin_body: str,
    inside: tuple[float, float, float],
    *,
    max_tilt_deg: float = 10.0,
    max_speed: float = 0.01,
    tolerance: float = 0.005,
) -> Verdict:
    """Is the bag's box inside the bin's inner volume (``inside`` = x, y, z sizes
    with the bin frame at the centre of the inner floor), upright and still?"""
    m, d = fac.model, fac.data
    b = fac.body(bag_body)
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, bag_geom)
    if g < 0:
        raise ValueError(f"no geom '{bag_geom}'")
    binb = fac.body(bin_body)
    R_bin, p_bin = d.xmat[binb].reshape(3, 3), d.xpos[binb]
    local = (box_corners(m, d, g) - p_bin) @ R_bin
    hx, hy, hz = inside[0] / 2, inside[1] / 2, inside[2]
    out = np.maximum.reduce(
        [
            np.abs(local[:, 0]) - hx,
            np.abs(local[:, 1]) - hy,
            -local[:, 2],
            local[:, 2] - hz,
        ]
    )
    outside_by = float(max(0.0, out.max()))
    up = d.xmat[b].reshape(3, 3)[:, 2]
    tilt = math.degrees(math.acos(np.clip(up[2], -1, 1)))
    vel = np.zeros(6)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, vel, 0)
    speed = float(np.linalg.norm(vel[3:]))
    inside_ok = outside_by <= tolerance
    ok = inside_ok and tilt < max_tilt_deg and speed < max_speed
    why = []
    if not inside_ok:
        why.append(
            f"the CTB is {100 * outside_by:.1f} cm outside the stowage volume of '{bin_body}'"
        )
    if tilt >= max_tilt_deg:
        why.append(f"the CTB is tilted {tilt:.1f} deg (limit {max_tilt_deg:g})")
    if speed >= max_speed:
        why.append(f"the CTB still moves at {100 * speed:.1f} cm/s")
    msg = (
        "; ".join(why)
        if why
        else (f"the CTB rests in '{bin_body}', tilted {tilt:.1f} deg, {1000 * speed:.1f} mm/s")
    )
    return Verdict(ok, inside_ok, tilt, speed, outside_by, msg)
