"""``rover-drive BUNDLE --task deliver``: the collector drives to the regolith pile, scoops
it into its hopper, drives to the printer around the rocks and hands the load over; the
printer prints a square layer with its printhead. Judged from the physics: where the
grains' mass is (MuJoCo's body masses and positions), the printed beads against the
planned path, and the time taken.

A seed varies the pile (moved up to ``PILE_SHIFT``, each grain up to ``GRAIN_JITTER``
more, in the plane) and the collector's start (``START_JITTER``, ``YAW_JITTER``): every
trial's physics differs."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import mujoco
import numpy as np

from .printhead import AHEAD, PrintLayer, distance_to, find_beads, square
from .regolith import Grains, Transfer, supported_weight
from .roles import RoverError
from .route import Pursue, length, plan
from .sim import RoverSim
from .tasks import Hold, Straight

PILE_SHIFT = 0.10
"""m: the most a seed moves the whole pile in x and y."""
GRAIN_JITTER = 0.004
"""m: the most a seed moves each grain in x and y besides (grains lie 1 cm apart)."""
START_JITTER = 0.05
"""m: the most a seed moves the collector's start in x and y."""
YAW_JITTER = math.radians(2.0)
"""rad: the most a seed turns the collector's start."""
SHORT = 1.3
"""m: where the collector stops before the pile's centre."""
BESIDE = 2.3
"""m east of the printer (in its frame: to its right) where the collector hands over."""
BALANCE = 0.01
"""The mass balance must close within this share of what was collected."""
PATH_TOLERANCE = 0.03
"""m: the largest mean distance of the printed beads from the planned path for success."""
LENGTH_TOLERANCE = 0.05
"""The printed length must be within this share of the planned one for success."""
LOAD_SETTLE = 1.5
"""s a rover stands braked before its supported weight is measured."""
LOAD_WINDOW = 0.2
"""s over which a rover's supported weight is averaged (braked)."""


@dataclass
class DeliverResult:
    """What the deliver task did (SI units)."""

    name: str
    success: bool
    collected_kg: float
    delivered_kg: float
    spilled_kg: float
    carried_kg: float
    printed_path_m: float
    planned_path_m: float
    path_error_m: float
    duration_s: float
    route_m: float
    rock_contacts: int
    wheel_load_empty_n: float
    wheel_load_loaded_n: float
    message: str

    def task_json(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        return (
            f"deliver: {'success' if self.success else 'FAILED'}; collected "
            f"{self.collected_kg:.2f} kg, delivered {self.delivered_kg:.2f} kg, spilled "
            f"{self.spilled_kg:.2f} kg, still carried {self.carried_kg:.2f} kg; printed "
            f"{self.printed_path_m:.3f} m of {self.planned_path_m:.3f} m (mean path error "
            f"{1000 * self.path_error_m:.1f} mm); {self.duration_s:.1f} s simulated"
            + (f"; {self.message}" if self.message else "")
        )


def check_pair(sim: RoverSim) -> None:
    missing = [n for n in ("collector", "printer") if n not in sim.rovers]
    if missing:
        raise RoverError(
            f"--task deliver needs a collector and a printer; the facility has "
            f"{', '.join(sim.rovers) or 'no rover'} (build recipes/mira3d-pair.yaml or "
            "recipes/mira3d-pair-floor.yaml)",
            file=sim.folder / "facility.json",
            element="components",
        )


def jitter(sim: RoverSim, grains: Grains, seed: int) -> None:
    """Move the pile's grains and the collector's start by the seed's draw."""
    rng = np.random.default_rng(seed)
    m, d = sim.m, sim.d
    shift = rng.uniform(-PILE_SHIFT, PILE_SHIFT, 2)
    for a in grains.qpos:
        d.qpos[a : a + 2] += shift + rng.uniform(-GRAIN_JITTER, GRAIN_JITTER, 2)
    base = sim.rovers["collector"]
    a = int(m.jnt_qposadr[m.body_jntadr[base.base]])
    d.qpos[a : a + 2] += rng.uniform(-START_JITTER, START_JITTER, 2)
    turn = np.zeros(4)
    mujoco.mju_axisAngle2Quat(turn, np.array([0.0, 0.0, 1.0]), rng.uniform(-YAW_JITTER, YAW_JITTER))
    q = np.zeros(4)
    mujoco.mju_mulQuat(q, turn, d.qpos[a + 3 : a + 7].copy())
    d.qpos[a + 3 : a + 7] = q
    mujoco.mj_forward(m, d)
    sim.reset_odometry()


def _obstacles(sim: RoverSim) -> list[tuple[float, float, float]]:
    """The rocks of facility.json (half their extent), the printer (0.6 m) and the layer
    it will print ahead of it (0.4 m)."""
    rocks = sim.manifest.rocks.rocks if sim.manifest.rocks is not None else ()
    out = [(float(r.x), float(r.y), 0.45 * float(r.size)) for r in rocks]
    prn = sim.rovers["printer"].base
    p, rot = sim.d.xpos[prn], sim.d.xmat[prn].reshape(3, 3)
    layer = p + rot @ np.array([AHEAD, 0.0, 0.0])
    out += [(float(p[0]), float(p[1]), 0.6), (float(layer[0]), float(layer[1]), 0.4)]
    return out


def _mean_load(sim: RoverSim, name: str) -> float:
    """N: ``name``'s supported weight averaged over ``LOAD_WINDOW`` after ``LOAD_SETTLE``,
    every rover braked (a rover still rocks after a stop in 1/6 g)."""
    rover = sim.rovers[name]
    settle = int(round(LOAD_SETTLE / sim.dt))
    n = max(1, int(round(LOAD_WINDOW / sim.dt)))
    total = 0.0
    for i in range(settle + n):
        for r in sim.rovers.values():
            sim.brake(r)
        sim.step()
        if i >= settle:
            total += supported_weight(sim.m, sim.d, rover)
    return total / n


def _rock_contacts(sim: RoverSim, counter: list[int]) -> Callable[[RoverSim], None]:
    """An ``on_step`` that counts the steps in which the collector touches a rock."""
    m = sim.m
    root = int(m.body_rootid[sim.rovers["collector"].base])
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, i) or "" for i in range(m.nbody)]
    rock = np.array([n.startswith("rock_") for n in names])
    mine = m.body_rootid == root

    def check(s: RoverSim) -> None:
        n = s.d.ncon
        if not n:
            return
        b1 = m.geom_bodyid[s.d.contact.geom1[:n]]
        b2 = m.geom_bodyid[s.d.contact.geom2[:n]]
        if np.any((mine[b1] & rock[b2]) | (mine[b2] & rock[b1])):
            counter[0] += 1

    return check


def run_deliver(
    sim: RoverSim, seed: int | None = None, log: Callable[[str], None] = print
) -> tuple[DeliverResult, list[dict]]:
    """The whole task on a fresh ``sim`` (home keyframe); the result and the drive phases'
    reports (``TaskReport`` dicts)."""
    check_pair(sim)
    grains = Grains.find(sim.m)
    beads = find_beads(sim.m)
    if seed is not None:
        jitter(sim, grains, seed)
    sim.settle(1.0)
    t0 = float(sim.d.time)
    reports: list[dict] = []
    col, prn = sim.rovers["collector"], sim.rovers["printer"]

    def phase(name: str, tasks: dict, **kw: Any) -> dict:
        out = sim.run(tasks, **kw)
        for r in out.values():
            if r.task not in ("transfer", "printlayer", "hold"):
                log(r.summary())
            reports.append({"phase": name, **asdict(r)})
        return out

    # 1. to the pile, along the collector's lane
    pile = sim.d.xpos[grains.bodies].mean(axis=0)
    here = sim.d.xpos[col.base]
    heading = sim.odometry["collector"].imu_yaw
    ahead = (pile[0] - here[0]) * math.cos(heading) + (pile[1] - here[1]) * math.sin(heading)
    phase("to the pile", {"collector": Straight(ahead - SHORT, speed=0.5)})
    empty = _mean_load(sim, "collector")
    # 2. scoop
    scoop = Transfer(grains, giver=None)
    phase("scoop", {"collector": scoop})
    loaded = _mean_load(sim, "collector")
    collected = float(grains.mass[scoop.taken].sum())
    log(
        f"collector: scooped {len(scoop.taken)} grains, {collected:.2f} kg; its wheels carry "
        f"{empty:.1f} N empty, {loaded:.1f} N loaded"
    )
    # 3. to the printer, around the rocks
    p_pos, p_rot = sim.d.xpos[prn.base], sim.d.xmat[prn.base].reshape(3, 3)
    goal = (p_pos + p_rot @ np.array([0.0, -BESIDE, 0.0]))[:2]
    start = sim.odometry["collector"].fused[:2]
    message = ""
    touches = [0]
    try:
        route = plan(start, goal, _obstacles(sim))
    except ValueError as exc:
        route, message = [], f"no route to the printer: {exc}"
    if route:
        phase("to the printer", {"collector": Pursue(route)}, on_step=_rock_contacts(sim, touches))
        # 4. hand-over
        handover = Transfer(grains, giver="collector")
        phase("hand-over", {"printer": handover})
        # 5. print the layer ahead of the printer
        centre = (p_pos + p_rot @ np.array([AHEAD, 0.0, 0.0]))[:2]
        yaw = math.atan2(p_rot[1, 0], p_rot[0, 0])
        layer = square(centre, yaw)
        printing = PrintLayer(layer, beads, ground=0.0)
        phase("print", {"printer": printing})
        phase("rest", {"printer": Hold(1.0), "collector": Hold(1.0)})
    else:
        layer = square(sim.d.xpos[prn.base][:2], 0.0)
    # where the mass is now
    taken = np.zeros(len(grains.bodies), bool)
    taken[scoop.taken] = True
    carried_mask = taken & grains.in_hopper(sim.d, col)
    delivered_mask = taken & grains.in_hopper(sim.d, prn) & ~carried_mask
    spilled_mask = taken & ~carried_mask & ~delivered_mask
    carried = float(grains.mass[carried_mask].sum())
    delivered = float(grains.mass[delivered_mask].sum())
    spilled = float(grains.mass[spilled_mask].sum())
    beads_xyz = sim.d.mocap_pos[beads]
    placed = beads_xyz[beads_xyz[:, 2] > -50.0]  # parked beads lie 100 m down
    printed = length(placed[:, :2]) if len(placed) > 1 else 0.0
    planned = length(layer)
    error = float(distance_to(layer, placed[:, :2]).mean()) if len(placed) else math.inf
    balance = abs(collected - (delivered + spilled + carried))
    pile = float(grains.mass.sum())
    success = bool(
        route
        and collected >= (1 - BALANCE) * pile  # the whole pile
        and balance <= BALANCE * collected
        and delivered >= (1 - BALANCE) * collected
        and abs(printed - planned) <= LENGTH_TOLERANCE * planned
        and error <= PATH_TOLERANCE
        and touches[0] == 0
    )
    result = DeliverResult(
        name="deliver",
        success=success,
        collected_kg=collected,
        delivered_kg=delivered,
        spilled_kg=spilled,
        carried_kg=carried,
        printed_path_m=printed,
        planned_path_m=planned,
        path_error_m=error,
        duration_s=float(sim.d.time) - t0,
        route_m=length(route) if route else 0.0,
        rock_contacts=touches[0],
        wheel_load_empty_n=empty,
        wheel_load_loaded_n=loaded,
        message=message,
    )
    log(result.summary())
    return result, reports


def deliver_trial(job: tuple[str, int]) -> dict:
    """One seeded trial on the bundle ``job[0]`` (a worker's job, :mod:`..executors`): a
    trial dict for :func:`..aggregate.aggregate`. A trial that raises is a failed trial."""
    from ... import headless

    headless.configure()
    folder, seed = job
    start = time.perf_counter()
    lines: list[str] = []
    try:
        sim = RoverSim(folder)
        res, _ = run_deliver(sim, seed=seed, log=lines.append)
        failed = None if res.success else "deliver"
        out: dict[str, Any] = {
            "ok": res.success,
            "sim_time": res.duration_s,
            "failed_step": failed,
            "message": res.message or ("" if res.success else res.summary()),
            "task": res.task_json(),
            "warnings": sim.warnings(),
        }
    except Exception as exc:  # a crash fails this seed, reported with the others
        out = {
            "ok": False,
            "sim_time": 0.0,
            "failed_step": "error",
            "message": f"{type(exc).__name__}: {exc}",
            "task": None,
        }
    out.update(seed=seed, log=lines, wall_time=time.perf_counter() - start, steps=[])
    out["trial_wall"] = out["wall_time"]
    return out
