"""Collision-free joint moves: OMPL's RRT* with MuJoCo as the collision checker, timed
with TOPP-RA within the joints' velocity and acceleration limits.

The paper's stack planned its joint moves with MoveIt and OMPL's RRT*; this is the
same planner on the compiled MuJoCo model, so what is checked is exactly what is
simulated: the model's geoms, its ``contype``/``conaffinity`` rule, its ``<exclude>``s
and MuJoCo's parent-child filter.

**A state** (positions of the planned joints) is checked on a private copy of the model
and a private ``MjData``: every other coordinate comes from the full state at the start
of the move; a joint that follows a planned joint through a joint equality (a mimic:
the lift's middle stage) is set from its leader by the equality's polynomial;
``mj_kinematics`` + ``mj_collision`` run. The state is invalid when a contact closer
than ``margin`` involves a robot body (the subtrees of the planned joints, and a held
body) and no ignored body, in a pair that is not allowed. The copy's contact bits are
rewritten so that MuJoCo computes only pairs with a robot geom (the same pairs its own
rule gives; pairs of mockup parts are skipped). A held body (``attached_body``, a free
body) keeps its pose relative to the body of the deepest planned joint at the start of
the move; its contacts with that body's subtree (the gripper holding it) are allowed.

**A move**:

1. the straight joint interpolation, checked every ``resolution`` (joint-space norm,
   rad and m mixed); when free it is the path (``planner == "straight"``);
2. otherwise RRT* (``ompl.geometric.RRTstar``, OMPL 2.0's nanobind bindings) in the box
   of the joint ranges narrowed to the start-goal span plus HINGE_SLACK per hinge, OMPL's
   RNG seeded from ``seed``, steps of at most RRT_RANGE, motions checked at
   ``resolution``. Its one tree is rooted at the more confined end (fewer free states
   among OPENNESS_SAMPLES seeded ones within OPENNESS_RADIUS: a pose in a narrow place is
   far easier to leave than to enter; the path is reversed when rooted at the goal). It
   stops ITERATIONS iterations after its first solution, or fails after ``max_iterations``
   iterations without one: budgets of work, never of time, so a seed gives the same path
   and the same verdict on a quiet machine and on a loaded one. ``wall_limit`` seconds
   from the start of the move is only a safety net, far above any normal move, and a move
   stopped by it fails saying so; then OMPL's ``PathSimplifier`` (rope shortcutting,
   vertex reduction; seeded too);
3. TOPP-RA time-optimal timing, from rest to rest, of a cubic spline through the path
   densified to DENSE spacing (the spline keeps to the checked segments), under
   ``|qd| <= vmax`` and ``|qdd| <= amax`` per joint. TOPP-RA holds the limits at its grid
   points; the grid is refined where its profile exceeds a limit in between, and the
   samples (every SAMPLE_DT seconds) are stretched in time if their finite differences
   still do. The spline is checked against collisions again.

States of a planned path (steps 1 and 2) keep PAD metres beyond ``margin`` from every
pair of bodies that are not already that close at the start or the goal, so that the
motion between two checks does not graze an obstacle.

Failures raise ``PlanningError`` (a ``ConversionError``): the start or goal in collision
(naming the two bodies and geoms), out of range, or no path within the iteration budget
(or, on a machine far too slow, the wall-clock safety net).
"""

from __future__ import annotations

import copy
import logging
import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..errors import PlanningError

log = logging.getLogger(__name__)

SAMPLE_DT = 0.01
"""Spacing of the timed trajectory's samples (s)."""
ITERATIONS = 25
"""RRT* iterations once a solution exists (the planner refines it meanwhile)."""
MAX_ITERATIONS = 5000
"""RRT* iterations a move may take to find its first solution. The facility's blocked
move (approach_bench_seat) finds one after 90 on every seed tried, in about 0.2 s on an
idle 2-core machine; a move with no path fails after this many (about 10 s there)."""
WALL_LIMIT = 600.0
"""Seconds a move may plan before it fails whatever its budget: a safety net against a
machine stalled far beyond any normal load (a normal move takes well under 1 s), never
what decides a move; hitting it is reported as such."""
DENSE = 0.05
"""Waypoint spacing along each path segment for the timing spline (joint-space norm)."""
HINGE, SLIDE, FREE = (
    int(t)
    for t in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_FREE)
)
PAD = 0.005
"""Clearance (m) beyond ``margin`` kept at the checked states of a planned path, so that
the motion between two checks (``resolution`` apart) does not graze an obstacle; pairs
of bodies already that close at the start or the goal (a grasp, the rail carriage on its
rail) need only ``margin``."""
HINGE_SLACK = math.pi / 2
"""How far (rad) a hinge may swing beyond the span of its start and goal while planning."""
RRT_RANGE = 0.5
"""RRT*'s longest motion (joint-space norm). OMPL's default, a fifth of the space's extent
(about 1.7 here), costs many checks per step and rarely connects into a confined pose: on
the facility's blocked moves 0.5 planned each of 8 seeded runs in under 1 s where the
default took 1 to 18 s or failed in 20 s."""
OPENNESS_SAMPLES = 32
OPENNESS_RADIUS = 0.3
"""Random states (and their joint-space radius) that tell how confined a path's end is."""
GRID_REFINEMENTS = 6
"""Rounds of TOPP-RA grid refinement where its profile exceeds a limit between points."""
RANGE_TOL = 1e-3
"""A start this far past a joint's range (rad or m) counts as at the limit."""


@dataclass(frozen=True)
class PlannedMove:
    times: np.ndarray
    """(n,) seconds from the start, ``times[0] == 0``."""
    q: np.ndarray
    """(n, k) positions of the planned joints at ``times`` (rad or m)."""
    qd: np.ndarray
    """(n, k) joint velocities (rad/s or m/s)."""
    path: np.ndarray
    """(m, k) the geometric path (after shortcutting), before timing."""
    planning_time_s: float
    """Wall time spent planning: checks, OMPL, simplification and timing (s)."""
    path_length: float
    """Joint-space length of ``path`` (rad and m mixed: sum of the segments' norms)."""
    straight_line_free: bool
    """True when the straight joint interpolation was already collision-free."""
    planner: str
    """``"straight"`` or ``"RRTstar"``: what produced the path."""
    iterations: int = 0
    """RRT*'s iterations (0 for a straight path): the work the move took, the same for a
    seed on any machine."""


@dataclass(frozen=True)
class _Contact:
    body1: str
    body2: str
    geom1: str
    geom2: str
    dist: float

    def __str__(self) -> str:
        return (
            f"'{self.body1}' (geom '{self.geom1}') touches '{self.body2}' "
            f"(geom '{self.geom2}'), distance {self.dist * 1000:.1f} mm"
        )


def _name(m: mujoco.MjModel, kind: mujoco.mjtObj, i: int) -> str:
    return mujoco.mj_id2name(m, kind, i) or f"#{i}"


def _subtree(m: mujoco.MjModel, roots: Iterable[int]) -> np.ndarray:
    """(nbody,) bool: the bodies in the subtrees of ``roots``."""
    inside = np.zeros(m.nbody, bool)
    inside[list(roots)] = True
    # MuJoCo numbers a body after its parent, so one pass in order reaches every descendant.
    for b in range(1, m.nbody):
        inside[b] |= inside[m.body_parentid[b]]
    return inside


def path_length(path: np.ndarray) -> float:
    """Sum of the segments' norms of a joint path (rows)."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) > 1 else 0.0


def _densify(path: np.ndarray, step: float) -> np.ndarray:
    """The polyline through ``path`` with points at most ``step`` apart (corners kept)."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
        out.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
    return np.vstack(out)


class JointPlanner:
    """Collision-free, timed moves of a set of hinge and slide joints of a model."""

    def __init__(
        self,
        model: mujoco.MjModel,
        joint_ids: Sequence[int],
        vmax: ArrayLike,
        amax: ArrayLike,
        *,
        ignore_bodies: Iterable[int] = (),
        allowed_pairs: Iterable[tuple[int, int]] = (),
        margin: float = 0.0,
        seed: int = 0,
        max_iterations: int = MAX_ITERATIONS,
        wall_limit: float = WALL_LIMIT,
        resolution: float = 0.01,
        link_of_geom: Callable[[int], str] | None = None,
    ) -> None:
        """``link_of_geom``: the name an error gives a geom's body (a built facility's
        ``Facility.link_of_geom``: the link a folded fixture was described on); by
        default the MuJoCo body's name."""
        import toppra  # noqa: F401  (slow first import, here rather than in a move's timing)

        # MuJoCo reports a pair only closer than its geoms' margin: widen it on a copy.
        m = copy.deepcopy(model)
        m.geom_margin[:] = np.maximum(m.geom_margin, margin + PAD)
        self.m = m
        self.d = mujoco.MjData(m)
        self.joints = np.asarray(joint_ids, int)
        k = len(self.joints)
        if k == 0:
            raise ValueError("no joints to plan")
        for j in self.joints:
            if int(m.jnt_type[j]) not in (HINGE, SLIDE):
                raise ValueError(
                    f"joint '{_name(m, mujoco.mjtObj.mjOBJ_JOINT, j)}' is not a "
                    "hinge or slide joint"
                )
        self.vmax = np.broadcast_to(np.asarray(vmax, float), (k,)).copy()
        self.amax = np.broadcast_to(np.asarray(amax, float), (k,)).copy()
        if np.any(self.vmax <= 0) or np.any(self.amax <= 0):
            raise ValueError("vmax and amax must be positive")
        self.qadr = m.jnt_qposadr[self.joints]
        self.lower, self.upper = self._bounds()
        self.followers = self._followers()
        self.margin = float(margin)
        self.seed = int(seed)
        self.max_iterations = int(max_iterations)
        if self.max_iterations < 1:
            raise ValueError("max_iterations must be at least 1")
        self.wall_limit = float(wall_limit)
        self.resolution = float(resolution)
        self.robot = _subtree(m, m.jnt_bodyid[self.joints])
        self._geom_body = m.geom_bodyid.copy()
        self._link_of_geom = link_of_geom
        self._contype0 = m.geom_contype.copy()
        self._conaffinity0 = m.geom_conaffinity.copy()
        self.ignored = np.zeros(m.nbody, bool)
        self.ignored[list(ignore_bodies)] = True
        self.allowed = np.zeros((m.nbody, m.nbody), bool)
        for a, b in allowed_pairs:
            self.allowed[a, b] = self.allowed[b, a] = True
        # the body of the deepest planned joint: what a held body moves with
        depth = np.zeros(m.nbody, int)
        for b in range(1, m.nbody):
            depth[b] = depth[m.body_parentid[b]] + 1
        self.last_body = int(max(m.jnt_bodyid[self.joints], key=lambda b: depth[b]))
        # per plan(): the full state at the start and the held body, if any
        self._base = m.qpos0.copy()
        self._held: tuple[int, int, np.ndarray, np.ndarray] | None = None
        # per pair of bodies: a contact closer than this counts (-inf: never); the second
        # adds the clearance kept while a path is planned
        self._limit_free = np.full((m.nbody, m.nbody), -np.inf)
        self._limit_plan: np.ndarray | None = None
        self._robot_now, self._allowed_now = self.robot, self.allowed
        self._use(self.robot, self.allowed)

    # ---- model facts ----------------------------------------------------------------

    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        m = self.m
        lo, hi = np.empty(len(self.joints)), np.empty(len(self.joints))
        for i, j in enumerate(self.joints):
            if m.jnt_limited[j]:
                lo[i], hi[i] = m.jnt_range[j]
            elif int(m.jnt_type[j]) == HINGE:
                lo[i], hi[i] = -2 * math.pi, 2 * math.pi
            else:
                raise ValueError(
                    f"slide joint '{_name(m, mujoco.mjtObj.mjOBJ_JOINT, j)}' has "
                    "no range: the planner needs bounds"
                )
        return lo, hi

    def _followers(self) -> list[tuple[int, int, int, np.ndarray]]:
        """(follower qpos adr, leader index in the planned joints, leader qpos adr, polycoef)
        for each active joint equality whose leader is planned and follower is not."""
        m = self.m
        planned = {int(j): i for i, j in enumerate(self.joints)}
        out = []
        for e in range(m.neq):
            if int(m.eq_type[e]) != int(mujoco.mjtEq.mjEQ_JOINT) or not m.eq_active0[e]:
                continue
            j1, j2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
            if j2 in planned and j1 not in planned:
                out.append(
                    (
                        int(m.jnt_qposadr[j1]),
                        planned[j2],
                        int(m.jnt_qposadr[j2]),
                        m.eq_data[e, :5].copy(),
                    )
                )
        return out

    # ---- collision checks -------------------------------------------------------------

    def _set(self, q: np.ndarray) -> None:
        """Private data at the planned joints' ``q``, everything else from the start state."""
        m, d = self.m, self.d
        d.qpos[:] = self._base
        d.qpos[self.qadr] = q
        for f_adr, i, l_adr, c in self.followers:
            x = q[i] - m.qpos0[l_adr]
            d.qpos[f_adr] = m.qpos0[f_adr] + c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * c[4])))
        mujoco.mj_kinematics(m, d)
        if self._held is not None:
            adr, _, rel_pos, rel_quat = self._held
            link = self.last_body
            pos, quat = np.empty(3), np.empty(4)
            mujoco.mju_mulPose(pos, quat, d.xpos[link], d.xquat[link], rel_pos, rel_quat)
            d.qpos[adr : adr + 3], d.qpos[adr + 3 : adr + 7] = pos, quat
            mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)

    def _first_contact(self, limit: np.ndarray | None = None) -> _Contact | None:
        """The closest counted contact in the private data (closer than ``limit`` of its
        pair of bodies, by default ``margin`` for the pairs that count), or None."""
        m, d = self.m, self.d
        if d.ncon == 0:
            return None
        contact = d.contact
        geoms, dist = contact.geom, contact.dist
        b1, b2 = self._geom_body[geoms[:, 0]], self._geom_body[geoms[:, 1]]
        counted = dist < (self._limit_free if limit is None else limit)[b1, b2]
        if not counted.any():
            return None
        c = int(np.flatnonzero(counted)[np.argmin(dist[counted])])
        body, geom = mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM
        g1, g2 = int(geoms[c, 0]), int(geoms[c, 1])
        if self._link_of_geom is not None:
            name1, name2 = self._link_of_geom(g1), self._link_of_geom(g2)
        else:
            name1, name2 = _name(m, body, int(b1[c])), _name(m, body, int(b2[c]))
        return _Contact(name1, name2, _name(m, geom, g1), _name(m, geom, g2), float(dist[c]))

    def _contact_at(self, q: np.ndarray) -> _Contact | None:
        self._set(np.asarray(q, float))
        return self._first_contact()

    def _valid(self, q: np.ndarray) -> bool:
        """A state of the path being planned: clear by ``margin`` plus its pairs' pad."""
        self._set(q)
        return self._first_contact(self._limit_plan) is None

    def _free(self, q: np.ndarray) -> bool:
        self._set(q)
        return self._first_contact() is None

    def _pads(self, ends: Iterable[np.ndarray]) -> np.ndarray:
        """PAD for every pair of bodies, except those closer than margin + PAD at an end."""
        pad = np.full((self.m.nbody, self.m.nbody), PAD)
        for q in ends:
            self._set(q)
            n = self.d.ncon
            close = self.d.contact.dist[:n] < self.margin + PAD
            b = self.m.geom_bodyid[self.d.contact.geom[:n][close]]
            pad[b[:, 0], b[:, 1]] = pad[b[:, 1], b[:, 0]] = 0.0
        return pad

    def _use(self, robot: np.ndarray, allowed: np.ndarray) -> None:
        """Check contacts of ``robot`` (bodies) only: on the private model, rewrite the
        contact bits so that every pair MuJoCo would test with a robot geom is still tested
        (same contype/conaffinity rule) and pairs without one are not computed at all."""
        self._robot_now, self._allowed_now = robot, allowed
        counts = (robot[:, None] | robot[None, :]) & ~allowed
        counts &= ~self.ignored[:, None] & ~self.ignored[None, :]
        self._limit_free = np.where(counts, self.margin, -np.inf)
        m, ct0, ca0 = self.m, self._contype0, self._conaffinity0
        body = m.geom_bodyid
        mine = robot[body] & ~self.ignored[body]
        classes = sorted(set(zip(ct0[mine].tolist(), ca0[mine].tolist(), strict=True)))
        if len(classes) > 31:  # more kinds than bits: keep MuJoCo's bits as they are
            ct, ca = ct0.copy(), ca0.copy()
        else:
            ct, ca = np.zeros_like(ct0), np.zeros_like(ca0)
            for i, (c_type, c_aff) in enumerate(classes):
                bit = 1 << i
                ct[mine & (ct0 == c_type) & (ca0 == c_aff)] = bit
                ca[((c_type & ca0) != 0) | ((ct0 & c_aff) != 0)] |= bit
        ct[self.ignored[body]] = ca[self.ignored[body]] = 0
        m.geom_contype[:], m.geom_conaffinity[:] = ct, ca
        # the broadphase filters bodies by the union of their geoms' bits
        m.body_contype[:] = m.body_conaffinity[:] = 0
        np.bitwise_or.at(m.body_contype, body, ct)
        np.bitwise_or.at(m.body_conaffinity, body, ca)

    def is_free(self, qpos_full: np.ndarray) -> bool:
        """True when the full state ``qpos_full`` has no counted contact (no held body)."""
        saved = self._base, self._held, self._robot_now, self._allowed_now
        self._base, self._held = np.asarray(qpos_full, float).copy(), None
        self._use(self.robot, self.allowed)
        try:
            return self._free(self._base[self.qadr])
        finally:
            self._base, self._held = saved[0], saved[1]
            self._use(saved[2], saved[3])

    def _segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / self.resolution))
        return all(self._valid(a + (i / n) * (b - a)) for i in range(1, n + 1))

    # ---- planning ---------------------------------------------------------------------

    def _hold(self, attached_body: int | None) -> None:
        """Start-of-move bookkeeping of the held body (pose in the last robot body)."""
        m = self.m
        self._held = None
        self._use(self.robot, self.allowed)
        if attached_body is None:
            return
        b = int(attached_body)
        jnt = m.body_jntadr[b]
        if m.body_jntnum[b] != 1 or int(m.jnt_type[jnt]) != FREE:
            raise ValueError(
                f"attached body '{_name(m, mujoco.mjtObj.mjOBJ_BODY, b)}' is not a free body"
            )
        self._set(self._base[self.qadr])  # start pose, nothing held yet
        d, link = self.d, self.last_body
        inv_pos, inv_quat = np.empty(3), np.empty(4)
        mujoco.mju_negPose(inv_pos, inv_quat, d.xpos[link], d.xquat[link])
        rel_pos, rel_quat = np.empty(3), np.empty(4)
        mujoco.mju_mulPose(rel_pos, rel_quat, inv_pos, inv_quat, d.xpos[b], d.xquat[b])
        self._held = (int(m.jnt_qposadr[jnt]), b, rel_pos, rel_quat)
        held = _subtree(m, [b])
        grip = _subtree(m, [link])
        allowed = self.allowed.copy()
        allowed[np.ix_(held, grip)] = allowed[np.ix_(grip, held)] = True
        self._use(self.robot | held, allowed)

    def plan(
        self,
        qpos_full_start: np.ndarray,
        q_goal: ArrayLike,
        *,
        attached_body: int | None = None,
    ) -> PlannedMove:
        """A collision-free, timed move of the planned joints from the state
        ``qpos_full_start`` (the model's full qpos) to ``q_goal`` (planned joints only)."""
        t0 = time.perf_counter()
        self._base = np.asarray(qpos_full_start, float).copy()
        if self._base.shape != (self.m.nq,):
            raise ValueError(
                f"qpos_full_start has shape {self._base.shape}, expected ({self.m.nq},)"
            )
        goal = np.asarray(q_goal, float).reshape(-1)
        if goal.shape != self.lower.shape:
            raise ValueError(f"q_goal has {goal.size} values for {self.lower.size} joints")
        start_true = self._base[self.qadr].copy()
        start = self._in_range("start", start_true, RANGE_TOL)
        self._in_range("goal", goal, 1e-9)
        self._hold(attached_body)
        for what, q in (("start", start), ("goal", goal)):
            hit = self._contact_at(q)
            if hit is not None:
                raise PlanningError(f"the {what} state is in collision: {hit}")

        self._limit_plan = self._limit_free + self._pads((start, goal))
        try:
            straight = self._segment_free(start, goal)
            iterations = 0
            if straight:
                path, planner = np.vstack([start, goal]), "straight"
            else:
                # RRT* grows one tree: root it at the more confined end (a pose in a
                # narrow place is reached far more easily by leaving it than by entering)
                if self._openness(goal) < self._openness(start):
                    path, iterations = self._rrtstar(goal, start, t0)
                    path = path[::-1].copy()
                else:
                    path, iterations = self._rrtstar(start, goal, t0)
                planner = "RRTstar"
        finally:
            self._limit_plan = None
        path[0] = start_true
        times, q, qd = self._timed(path)
        elapsed = time.perf_counter() - t0
        log.info(
            "planned move (%s): %d waypoints, length %.3f, %.2f s long, planned in %.3f s",
            planner,
            len(path),
            path_length(path),
            times[-1],
            elapsed,
        )
        return PlannedMove(
            times, q, qd, path, elapsed, path_length(path), straight, planner, iterations
        )

    def _in_range(self, what: str, q: np.ndarray, tol: float) -> np.ndarray:
        out = (q < self.lower - tol) | (q > self.upper + tol)
        if out.any():
            i = int(np.flatnonzero(out)[0])
            name = _name(self.m, mujoco.mjtObj.mjOBJ_JOINT, int(self.joints[i]))
            raise PlanningError(
                f"the {what} has joint '{name}' at {q[i]:.4f}, outside its range "
                f"[{self.lower[i]:.4f}, {self.upper[i]:.4f}]"
            )
        return np.clip(q, self.lower, self.upper)

    def _openness(self, q: np.ndarray) -> float:
        """Fraction of OPENNESS_SAMPLES seeded states within OPENNESS_RADIUS of ``q`` (in
        the joint ranges) that are free: how confined ``q`` is."""
        rng = np.random.default_rng(self.seed)
        k = len(q)
        v = rng.normal(size=(OPENNESS_SAMPLES, k))
        v *= (rng.uniform(size=(OPENNESS_SAMPLES, 1)) ** (1 / k)) / np.linalg.norm(
            v, axis=1, keepdims=True
        )
        states = np.clip(q + OPENNESS_RADIUS * v, self.lower, self.upper)
        return sum(self._valid(x) for x in states) / OPENNESS_SAMPLES

    def _box(self, start: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sampling box: a hinge may swing HINGE_SLACK beyond the span of its start and
        goal (its full range, often +-2 pi, is mostly detours), a slide over its range."""
        hinge = np.array([int(self.m.jnt_type[j]) == HINGE for j in self.joints])
        lo = np.where(hinge, np.minimum(start, goal) - HINGE_SLACK, self.lower)
        hi = np.where(hinge, np.maximum(start, goal) + HINGE_SLACK, self.upper)
        return np.maximum(lo, self.lower), np.minimum(hi, self.upper)

    def _rrtstar(
        self, start: np.ndarray, goal: np.ndarray, t0: float
    ) -> tuple[np.ndarray, int]:
        """RRT*'s simplified path from ``start`` to ``goal`` and its iterations."""
        from ompl import util as ou

        level = ou.getLogLevel()
        ou.setLogLevel(ou.LOG_NONE)  # OMPL prints its progress otherwise
        try:
            return self._rrtstar_quiet(start, goal, t0)
        finally:
            ou.setLogLevel(level)

    def _rrtstar_quiet(
        self, start: np.ndarray, goal: np.ndarray, t0: float
    ) -> tuple[np.ndarray, int]:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        k = len(start)
        # OMPL seeds every new RNG (planner, sampler, simplifier) from this one: reseeding
        # before each plan makes a plan depend only on the seed and the problem.
        ou.RNG.setSeed(self.seed % 2147483646 + 1)  # 0 is refused by OMPL
        lo, hi = self._box(start, goal)
        space = ob.RealVectorStateSpace(k)
        bounds = ob.RealVectorBounds(k)
        for i in range(k):
            bounds.setLow(i, float(lo[i]))
            bounds.setHigh(i, float(hi[i]))
        space.setBounds(bounds)
        ss = og.SimpleSetup(space)
        ss.setStateValidityChecker(lambda s: self._valid(np.array([s[i] for i in range(k)])))
        si = ss.getSpaceInformation()
        si.setStateValidityCheckingResolution(self.resolution / space.getMaximumExtent())
        planner = og.RRTstar(si)
        planner.setRange(RRT_RANGE)
        ss.setPlanner(planner)
        a, b = space.allocState(), space.allocState()
        for i in range(k):
            a[i], b[i] = float(start[i]), float(goal[i])
        ss.setStartAndGoalStates(a, b)
        ss.setup()
        pdef = ss.getProblemDefinition()
        deadline = t0 + self.wall_limit
        first: list[int] = []
        stalled: list[bool] = []

        def done() -> bool:
            # OMPL asks once per iteration: the iteration counts decide, the clock only
            # when the machine stalls far beyond any normal load
            n = planner.numIterations()
            if not first:
                # RRT* hands its solution to the problem definition only when it stops
                if math.isfinite(planner.bestCost().value()):
                    first.append(n)
                elif n >= self.max_iterations:
                    return True
            elif n >= first[0] + ITERATIONS:
                return True
            if time.perf_counter() > deadline:
                stalled.append(True)
                return True
            return False

        ss.solve(ob.PlannerTerminationCondition(done))
        iterations = planner.numIterations()
        if stalled:
            raise PlanningError(
                f"RRT* was stopped by the wall-clock safety net of {self.wall_limit:g} s "
                f"after {iterations} iterations (its budget: {self.max_iterations} "
                "to a first solution): this machine is far too slow or loaded for the move; "
                "its result is not the seed's"
            )
        if not pdef.hasExactSolution():
            raise PlanningError(
                f"no collision-free path found by RRT* within its budget of "
                f"{self.max_iterations} iterations"
            )
        # OMPL's rope shortcutting (pulls the path taut along itself), then vertex
        # reduction (seeded): as short as simplifyMax's full loop on the facility's moves
        # for a third of its collision checks
        sol = ss.getSolutionPath()
        simplifier = og.PathSimplifier(si)
        simplifier.ropeShortcutPath(sol)
        simplifier.reduceVertices(sol)
        simplifier.collapseCloseVertices(sol)
        states = sol.getStates()
        path = np.array([[s[i] for i in range(k)] for s in states])
        path[0], path[-1] = start, goal
        return path, iterations

    # ---- timing -----------------------------------------------------------------------

    def _timed(self, path: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """TOPP-RA timing of the path, sampled every SAMPLE_DT; the sampled motion is checked
        against collisions (a spline through too sparse points could cut a corner)."""
        step = DENSE
        for _ in range(4):
            times, q, qd, fine = self._topp(path, step)
            if all(self._free(x) for x in fine):
                return times, q, qd
            step /= 4
        raise PlanningError("the timed trajectory leaves the collision-free path")

    def _over_limits(self, geo: object, grid: np.ndarray, sd: np.ndarray) -> np.ndarray:
        """(len(grid) - 1,) bool: the grid intervals inside which the joint velocity or
        acceleration of TOPP-RA's profile (path speed squared linear in the path parameter)
        exceeds a limit by more than 0.1 %."""
        u = np.array([0.25, 0.5, 0.75])
        a, b = grid[:-1, None], grid[1:, None]
        x2a, x2b = sd[:-1, None] ** 2, sd[1:, None] ** 2
        s = a + u * (b - a)
        x2 = x2a + u * (x2b - x2a)  # path speed squared
        sdd = (x2b - x2a) / (2 * (b - a))  # path acceleration, constant in the interval
        d1 = np.asarray(geo(s.ravel(), 1)).reshape(*s.shape, -1)  # type: ignore[operator]
        d2 = np.asarray(geo(s.ravel(), 2)).reshape(*s.shape, -1)  # type: ignore[operator]
        qd = d1 * np.sqrt(x2)[..., None]
        qdd = d2 * x2[..., None] + d1 * sdd[..., None]
        over = (np.abs(qd) > self.vmax * 1.001) | (np.abs(qdd) > self.amax * 1.001)
        return np.asarray(over.any(axis=(1, 2)))

    def _topp(
        self, path: np.ndarray, step: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        import toppra

        if path_length(path) < 1e-12:
            z = np.zeros((1, path.shape[1]))
            return np.zeros(1), path[:1].copy(), z, path[:1].copy()
        dense = _densify(path, step)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
        geo = toppra.SplineInterpolator(s / s[-1], dense)
        constraints = [
            toppra.constraint.JointVelocityConstraint(np.stack([-self.vmax, self.vmax], 1)),
            toppra.constraint.JointAccelerationConstraint(np.stack([-self.amax, self.amax], 1)),
        ]
        # TOPP-RA holds the limits at its grid points; between them (constant path
        # acceleration) a bend of the spline can exceed them: refine the grid there
        grid = np.asarray(toppra.interpolator.propose_gridpoints(geo), float)
        for _ in range(GRID_REFINEMENTS):
            algo = toppra.algorithm.TOPPRA(
                constraints, geo, gridpoints=grid, parametrizer="ParametrizeConstAccel"
            )
            sd = algo.compute_parameterization(0.0, 0.0)[1]
            if sd is None or not np.all(np.isfinite(sd)):
                break
            bad = self._over_limits(geo, grid, np.asarray(sd, float))
            if not bad.any():
                break
            grid = np.union1d(grid, (grid[:-1][bad] + grid[1:][bad]) / 2)
        traj = algo.compute_trajectory(0.0, 0.0)
        if traj is None:
            raise PlanningError("TOPP-RA found no timing of the path within the joint limits")
        T = float(traj.duration)

        def sample(scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            # a whole number of SAMPLE_DT: uniform samples (stretching only slows the motion)
            n = max(2, math.ceil(T * scale / SAMPLE_DT - 1e-9))
            scale = n * SAMPLE_DT / T
            times = np.arange(n + 1) * SAMPLE_DT
            u = np.minimum(times / scale, T)
            return times, np.asarray(traj(u)), np.asarray(traj(u, 1)) / scale

        # TOPP-RA holds the limits at its grid points; stretch time where the samples
        # (their velocities and finite differences) exceed them in between.
        scale = 1.0
        for _ in range(8):
            times, q, qd = sample(scale)
            v = np.diff(q, axis=0) / SAMPLE_DT
            acc = np.diff(q, 2, axis=0) / SAMPLE_DT**2
            ratio = max(
                float(np.max(np.abs(qd) / self.vmax)),
                float(np.max(np.abs(v) / self.vmax)),
                math.sqrt(float(np.max(np.abs(acc) / self.amax))),
            )
            if ratio <= 1.0:
                break
            scale = times[-1] / T * ratio * 1.001
        q[0], q[-1] = path[0], path[-1]
        qd[0], qd[-1] = 0.0, 0.0
        # the timed motion follows the spline: check it at the planner's resolution (the
        # spline's parameter is the densified polyline's normalised length)
        fine = np.asarray(geo(np.linspace(0.0, 1.0, math.ceil(s[-1] / self.resolution) + 2)))
        return times, q, qd, fine
