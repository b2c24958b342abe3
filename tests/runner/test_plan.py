"""Collision-free joint moves (runner/plan.py) on a small arm written here, with MuJoCo's
own collision detection (mj_forward on a separate MjData) as the independent check.

The arm: two links turning about z above the floor (0.5 m and 0.4 m). A post stands
0.75 m out on +x: sweeping the stretched arm from one side to the other (the straight
joint interpolation) hits it; the arm has to fold its elbow to pass it.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from urdf2mjcf.errors import ForgeError, PlanningError, RunError
from urdf2mjcf.runner.plan import JointPlanner, PlannedMove

ROOT = Path(__file__).resolve().parents[2]

ARM = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <body name="base" pos="0 0 0.2">
      <geom name="base" type="cylinder" size="0.05 0.05"/>
      <body name="link1" pos="0 0 0.1">
        <joint name="j1" type="hinge" axis="0 0 1" range="-2.5 2.5"/>
        <geom name="link1" type="capsule" fromto="0 0 0 0.5 0 0" size="0.03"/>
        <body name="link2" pos="0.5 0 0">
          <joint name="j2" type="hinge" axis="0 0 1" range="-2.8 2.8"/>
          <geom name="link2" type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
        </body>
      </body>
    </body>
    <body name="post" pos="{post} 0 0.3">
      <geom name="post" type="box" size="0.05 0.05 0.2"/>
    </body>
    {extra}
  </worldbody>
</mujoco>
"""

# a box held at the arm's tip: the arm alone clears a post 1.05 m out, the box does not
HELD = """
    <body name="held" pos="{x} 0 0.3">
      <freejoint name="held"/>
      <geom name="held" type="box" size="0.08 0.03 0.03" contype="1" conaffinity="1"/>
    </body>
"""

VMAX = np.array([1.0, 1.5])
AMAX = np.array([2.0, 3.0])
START = np.array([-1.2, 0.0])
GOAL = np.array([1.2, 0.0])


def arm(post: float = 0.75, extra: str = "") -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(ARM.format(post=post, extra=extra))


def penetrations(m: mujoco.MjModel, qpos: np.ndarray, bodies: set[str]) -> list[tuple[str, str]]:
    """Pairs of bodies (at least one of ``bodies``) that MuJoCo finds penetrating at qpos."""
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    out = []
    for c in d.contact[: d.ncon]:
        names = (m.body(m.geom_bodyid[c.geom1]).name, m.body(m.geom_bodyid[c.geom2]).name)
        if c.dist < 0 and bodies & set(names):
            out.append(names)
    return out


def full(m: mujoco.MjModel, q: np.ndarray) -> np.ndarray:
    qpos = m.qpos0.copy()
    qpos[:2] = q
    return qpos


def fine(q: np.ndarray, step: float) -> np.ndarray:
    """The polyline through the rows of q, with points at most ``step`` apart."""
    out = [q[:1]]
    for a, b in zip(q[:-1], q[1:], strict=True):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out.append(a + np.linspace(0, 1, n + 1)[1:, None] * (b - a))
    return np.vstack(out)


def planner(m: mujoco.MjModel, seed: int = 3, ignore: tuple[int, ...] = (), **kw) -> JointPlanner:
    return JointPlanner(m, [0, 1], VMAX, AMAX, seed=seed, ignore_bodies=ignore, **kw)


@pytest.fixture(scope="module")
def around_the_post() -> PlannedMove:
    m = arm()
    return planner(m).plan(full(m, START), GOAL)


def test_the_straight_line_hits_the_post():
    m = arm()
    hits = [
        penetrations(m, full(m, q), {"link1", "link2"}) for q in fine(np.stack([START, GOAL]), 0.01)
    ]
    assert ("link2", "post") in {p for h in hits for p in h}


def test_the_planned_path_goes_around_the_post(around_the_post):
    mv, m = around_the_post, arm()
    assert mv.planner == "RRTstar" and not mv.straight_line_free
    np.testing.assert_allclose(mv.path[0], START, atol=1e-12)
    np.testing.assert_allclose(mv.path[-1], GOAL, atol=1e-12)
    np.testing.assert_allclose(mv.q[0], START, atol=1e-9)
    np.testing.assert_allclose(mv.q[-1], GOAL, atol=1e-9)
    for path in (mv.path, mv.q):  # the geometric path and the timed one, 2 mrad apart
        for q in fine(path, 0.002):
            assert penetrations(m, full(m, q), {"link1", "link2"}) == [], q
    lo, hi = m.jnt_range[:2, 0], m.jnt_range[:2, 1]
    assert np.all(mv.q >= lo - 1e-9) and np.all(mv.q <= hi + 1e-9)
    seg = np.linalg.norm(np.diff(mv.path, axis=0), axis=1).sum()
    assert mv.path_length == pytest.approx(seg)
    assert mv.path_length > np.linalg.norm(GOAL - START)  # a detour
    assert 0 < mv.planning_time_s < 30


def test_the_timed_move_respects_the_velocity_and_acceleration_limits(around_the_post):
    mv = around_the_post
    t, q, qd = mv.times, mv.q, mv.qd
    assert t[0] == 0 and np.all(np.diff(t) > 0)
    assert q.shape == qd.shape == (len(t), 2)
    h = np.diff(t)
    v = np.diff(q, axis=0) / h[:, None]  # finite differences, not the planner's own qd
    a = np.diff(v, axis=0) / ((h[1:] + h[:-1]) / 2)[:, None]
    assert np.all(np.abs(v) <= VMAX * (1 + 1e-6))
    assert np.all(np.abs(a) <= AMAX * (1 + 1e-6))
    assert np.all(np.abs(qd) <= VMAX * (1 + 1e-6))
    # qd is the derivative of q (central differences agree), from rest to rest
    np.testing.assert_allclose((v[1:] + v[:-1]) / 2, qd[1:-1], atol=0.02 * VMAX.max())
    np.testing.assert_allclose(qd[[0, -1]], 0, atol=1e-9)
    # time-optimal (TOPP-RA): at nearly every instant some joint is at a limit
    active = np.maximum(np.max(np.abs(qd[1:-1]) / VMAX, 1), np.max(np.abs(a) / AMAX, 1))
    assert np.median(active) > 0.95


def test_the_plan_is_deterministic_for_a_seed(around_the_post):
    m = arm()
    again = planner(m).plan(full(m, START), GOAL)
    np.testing.assert_array_equal(again.path, around_the_post.path)
    np.testing.assert_array_equal(again.q, around_the_post.q)


class _SlowMachine:
    """``time`` as a machine 10,000 times slower than this one would see it: each reading
    of the clock is 0.1 s after the one before."""

    def __init__(self) -> None:
        self.now = 0.0

    def perf_counter(self) -> float:
        self.now += 0.1
        return self.now


def test_the_plan_is_the_same_on_a_machine_far_slower_than_this_one(around_the_post, monkeypatch):
    from urdf2mjcf.runner import plan as plan_module

    assert around_the_post.iterations > 20  # RRT* read the clock at least that often
    slow = _SlowMachine()
    monkeypatch.setattr(plan_module, "time", slow)
    m = arm()
    again = planner(m).plan(full(m, START), GOAL)
    assert slow.now > 2.0  # the old budget, 2 s of wall time, would have stopped it
    assert again.iterations == around_the_post.iterations
    np.testing.assert_array_equal(again.path, around_the_post.path)
    np.testing.assert_array_equal(again.q, around_the_post.q)


def test_a_move_with_no_path_in_its_budget_fails_naming_the_budget():
    m = arm()
    with pytest.raises(PlanningError, match="within its budget of 3 iterations"):
        planner(m, max_iterations=3).plan(full(m, START), GOAL)


def test_the_wall_clock_safety_net_says_it_stopped_the_move(monkeypatch):
    from urdf2mjcf.runner import plan as plan_module

    monkeypatch.setattr(plan_module, "time", _SlowMachine())
    m = arm()
    with pytest.raises(PlanningError, match=r"wall-clock safety net of 1 s .* not the seed's"):
        planner(m, wall_limit=1.0).plan(full(m, START), GOAL)


def test_a_free_straight_line_is_the_path():
    m = arm()
    mv = planner(m).plan(full(m, START), [-0.6, -0.6])  # folding away from the post
    assert mv.planner == "straight" and mv.straight_line_free
    np.testing.assert_array_equal(mv.path, [START, [-0.6, -0.6]])
    assert mv.path_length == pytest.approx(np.linalg.norm([0.6, 0.6]))
    np.testing.assert_allclose(mv.q[-1], [-0.6, -0.6], atol=1e-9)


def test_a_start_in_collision_names_the_two_bodies():
    m = arm(post=0.75)
    start = np.array([0.0, 0.0])  # link2 through the post
    assert penetrations(m, full(m, start), {"link2"})
    with pytest.raises(PlanningError, match=r"start state is in collision: 'link2'.*'post'") as e:
        planner(m).plan(full(m, start), GOAL)
    assert isinstance(e.value, RunError) and isinstance(e.value, ForgeError)  # the tree
    # a facility names the link a folded fixture was described on, not its weld body
    def link(g: int) -> str:
        return f"{m.body(m.geom_bodyid[g]).name}_link"

    named = JointPlanner(m, [0, 1], VMAX, AMAX, link_of_geom=link)
    with pytest.raises(PlanningError, match=r"collision: 'link2_link'.*'post_link'"):
        named.plan(full(m, start), GOAL)


def test_a_goal_out_of_range_is_refused():
    m = arm()
    with pytest.raises(PlanningError, match=r"goal has joint 'j2' at 3\.0000, outside its range"):
        planner(m).plan(full(m, START), [1.2, 3.0])


def test_a_held_box_is_checked_with_the_arm():
    # the tip reaches 0.93 m, the held box 1.04 m: a post at 1.05 m (front face 1.0)
    m = arm(post=1.05, extra=HELD.format(x=0.96))
    held = m.body("held").id
    start = m.qpos0.copy()
    start[:2] = START
    # the box where the tip carries it at the start
    c, s = np.cos(START[0]), np.sin(START[0])
    start[2:5] = [0.96 * c, 0.96 * s, 0.3]
    start[5:9] = [np.cos(START[0] / 2), 0, 0, np.sin(START[0] / 2)]
    alone = planner(m, ignore=(held,)).plan(start, GOAL)
    assert alone.planner == "straight"
    carried = planner(m).plan(start, GOAL, attached_body=held)
    assert carried.planner == "RRTstar" and not carried.straight_line_free
    # independent check: the box moved with link2 along the timed motion
    d = mujoco.MjData(m)
    for q in fine(carried.q, 0.004):
        qpos = start.copy()
        qpos[:2] = q
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        link = m.body("link2").id
        tip, R = d.xpos[link], d.xmat[link].reshape(3, 3)
        qpos[2:5] = tip + R @ [0.46, 0, 0]
        mujoco.mju_mat2Quat(qpos[5:9], R.ravel())
        hits = penetrations(m, qpos, {"held", "link1", "link2"})
        assert [h for h in hits if "post" in h] == [], q


SLIDES = """
<mujoco>
  <worldbody>
    <body name="leader" pos="0 0 0.5">
      <joint name="leader" type="slide" axis="1 0 0" range="0 1"/>
      <geom type="box" size="0.05 0.05 0.05"/>
      <body name="follower" pos="0 0.3 0">
        <joint name="follower" type="slide" axis="1 0 0" range="-1 1"/>
        <geom type="box" size="0.05 0.05 0.05"/>
      </body>
    </body>
    <body name="wall" pos="0.45 0.3 0.5">
      <geom type="box" size="0.02 0.1 0.1"/>
    </body>
  </worldbody>
  <equality>
    <joint joint1="follower" joint2="leader" polycoef="0 -0.5 0 0 0"/>
  </equality>
</mujoco>
"""


def test_a_mimic_joint_follows_its_leader_in_the_checks():
    # the leader slides 1 m along x; the follower, on it, slides back half as much: it
    # ends 0.5 m out, in the wall at 0.45 m, where it would be 1 m out without its
    # equality (past the wall, and the straight line would hit the wall on the way)
    m = mujoco.MjModel.from_xml_string(SLIDES)
    p = JointPlanner(m, [m.joint("leader").id], 0.5, 1.0)
    assert set(penetrations(m, [1.0, -0.5], {"follower"})) == {("follower", "wall")}
    with pytest.raises(PlanningError, match="goal state is in collision: 'follower'.*'wall'"):
        p.plan(m.qpos0.copy(), [1.0])
    mv = p.plan(m.qpos0.copy(), [0.6])  # follower at 0.3 m: short of the wall
    assert mv.planner == "straight"


def test_only_pairs_with_the_robot_are_computed_and_they_are_mujocos_own():
    # a free crate in the arm's way, sunk 5 mm in the floor: that pair is not computed
    crate = '<body name="crate" pos="0.3 0.3 0.245"><freejoint/>'
    crate += '<geom type="box" size="0.05 0.05 0.25"/></body>'
    m = arm(extra=crate)
    p = planner(m)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    robot = {m.body("link1").id, m.body("link2").id}
    hits = 0
    for _ in range(200):
        q = rng.uniform(m.jnt_range[:2, 0], m.jnt_range[:2, 1])
        qpos = full(m, q)
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        pairs = {tuple(sorted(c.geom)) for c in d.contact[: d.ncon] if c.dist < 0}
        ours = {g for g in pairs if robot & {m.geom_bodyid[g[0]], m.geom_bodyid[g[1]]}}
        p.is_free(qpos)  # its private data now holds the state's contacts
        theirs = {tuple(sorted(c.geom)) for c in p.d.contact[: p.d.ncon] if c.dist < 0}
        assert theirs == ours, q
        assert p.is_free(qpos) == (penetrations(m, qpos, {"link1", "link2"}) == [])
        hits += bool(ours)
    assert 20 < hits < 180  # both kinds of state were seen


def test_the_robot_plans_from_the_bench_seat_to_stow_in_the_default_facility(imetro_bundle):
    from urdf2mjcf.runner.load import load

    fac = load(imetro_bundle)
    m, d = fac.model, fac.data
    joints = [m.joint(n).id for n in fac.manifest.components["robot"].roles["joints"]]
    adr = m.jnt_qposadr[joints]
    vmax = [0.15, 0.25, 0.8, 0.8, 1.0, 1.2, 1.2, 1.2]
    amax = [0.3, 0.5, 1.5, 1.5, 2.0, 3.0, 3.0, 3.0]
    # the paper's published waypoints: the arm in front of the bench seat's lid, and
    # its stow pose after the rail has moved to 0.5 m
    approach = np.array([0.0, 0.0, 2.443, -2.670, -1.571, -0.419, -1.500, -0.925])
    stow = np.array([0.5, 0.0, 1.5010, -0.3316, -2.2515, -3.6477, -1.5533, 1.5708])
    start = d.qpos.copy()
    start[adr] = approach
    robot = {
        m.body(b).name
        for b in range(m.nbody)
        if m.body_rootid[b] == m.body_rootid[m.jnt_bodyid[joints[0]]]
    }

    def hits(q: np.ndarray) -> list[tuple[str, str]]:
        qpos = start.copy()
        qpos[adr] = q
        qpos[m.joint("lift_middle").qposadr] = 0.5 * q[1]  # the lift's equality, by hand
        return penetrations(m, qpos, robot)

    mv = JointPlanner(m, joints, vmax, amax, seed=1).plan(start, stow)
    np.testing.assert_allclose(mv.q[0], approach, atol=1e-9)
    np.testing.assert_allclose(mv.q[-1], stow, atol=1e-9)
    for q in fine(mv.q, 0.01):
        assert hits(q) == [], q
    straight_hits = [h for q in fine(np.stack([approach, stow]), 0.01) for h in hits(q)]
    # the straight interpolation, checked by MuJoCo alone, decides what the planner did
    assert mv.planner == ("RRTstar" if straight_hits else "straight"), straight_hits[:1]
