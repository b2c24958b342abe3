"""Benchmark: the demo's planned joint moves on the default facility (runner/plan.py).

    python bench/planning.py                       # build the facility, run the demo, print
    python bench/planning.py --scene build/imetro  # a facility built earlier (no build)
    python bench/planning.py --pairs               # also: moves between published waypoints

The demo (recipes/demo/imetro.yaml, or ``--waypoints``) runs once as
``facility-demo`` runs it; every joint move it makes (its ``joints`` steps and
joint-space poses) is planned by ``JointPlanner`` from the state the robot is
in: the straight joint interpolation when it is free, else RRT*; then TOPP-RA
timing. For each: what produced the path, its joint-space length, the timed
duration, and the planning time (wall time of ``plan``: straight-line check,
RRT*, simplification, TOPP-RA and its collision check).

``--pairs`` also plans, outside the demo, between the paper's published joint
waypoints in both directions (the arm in front of the bench seat, the stow pose at
rail 0.5 m, home), several of which need RRT* because a mockup or the rail lies
across the straight line; seeded, so the paths are the same on every run.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.facility import commit, machine  # noqa: E402

# the paper's published joint waypoints (rail, lift, 6 arm joints; m and rad)
PUBLISHED = {
    "home": [0.0, 0.0, 3.1927, -2.3913, -1.7760, -0.4700, -1.6177, -1.6134],
    "approach_bench_seat": [0.0, 0.0, 2.443, -2.670, -1.571, -0.419, -1.500, -0.925],
    "stow (rail 0.5)": [0.5, 0.0, 1.5010, -0.3316, -2.2515, -3.6477, -1.5533, 1.5708],
}
HEADER = "| move | planner | path length | duration (s) | planning (s) |\n|---|---|---|---|---|"


def row(name: str, planner: str, length: float, duration: float, seconds: float) -> str:
    return f"| {name} | {planner} | {length:.2f} | {duration:.1f} | {seconds:.2f} |"


def demo_moves(folder: Path, waypoints: Path) -> tuple[list[str], str]:
    """Rows of the demo's planned moves, and a line on the run."""
    from urdf2mjcf.runner.demo import Demo, load_waypoints
    from urdf2mjcf.runner.load import load

    demo = Demo(load(folder), load_waypoints(waypoints), log=lambda *_: None)
    try:
        result = demo.run()
    finally:
        demo.close()
    rows, total = [], 0.0
    for step in result.steps:
        if step.plan:
            p = step.plan
            total += p["planning_time_s"]
            rows.append(
                row(
                    step.name, p["planner"], p["path_length"], p["duration_s"], p["planning_time_s"]
                )
            )
    outcome = "succeeded" if result.ok else f"failed at {result.failed_step}: {result.message}"
    line = (
        f"{len(rows)} planned moves, {total:.2f} s planning in all; the demo {outcome} "
        f"({result.sim_time:.1f} s simulated in {result.wall_time:.1f} s wall)"
    )
    return rows, line


def pair_moves(folder: Path, seed: int) -> list[str]:
    """Rows of moves between the published waypoints, both ways, from home's state."""
    import mujoco
    import numpy as np

    from urdf2mjcf.errors import PlanningError
    from urdf2mjcf.runner.demo import AMAX
    from urdf2mjcf.runner.load import load
    from urdf2mjcf.runner.plan import JointPlanner
    from urdf2mjcf.runner.waypoints import read_waypoints

    fac = load(folder)
    m, d, r = fac.model, fac.data, fac.robot
    vmax = read_waypoints(ROOT / "recipes" / "demo" / "imetro.yaml")["robot"]["vmax"]
    joints = [int(j) for j in r.joints]
    joint_eq = int(mujoco.mjtEq.mjEQ_JOINT)
    follower = [e for e in range(m.neq) if m.eq_type[e] == joint_eq and m.eq_obj2id[e] in joints]
    rows = []
    for a, qa in PUBLISHED.items():
        for b, qb in PUBLISHED.items():
            if a == b:
                continue
            start = d.qpos.copy()
            start[r.qpos] = qa
            for e in follower:  # a mimic joint at its leader's polynomial
                lead = start[m.jnt_qposadr[m.eq_obj2id[e]]]
                start[m.jnt_qposadr[m.eq_obj1id[e]]] = np.polyval(m.eq_data[e, 4::-1], lead)
            planner = JointPlanner(m, joints, vmax, AMAX, seed=seed, time_limit=30)
            t0 = time.perf_counter()
            try:
                mv = planner.plan(start, qb)
                rows.append(
                    row(f"{a} -> {b}", mv.planner, mv.path_length, mv.times[-1], mv.planning_time_s)
                )
            except PlanningError as exc:
                rows.append(f"| {a} -> {b} | failed: {exc} | | | {time.perf_counter() - t0:.2f} |")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, help="a built facility folder (default: build one)")
    ap.add_argument("--waypoints", type=Path, default=ROOT / "recipes" / "demo" / "imetro.yaml")
    ap.add_argument("--pairs", action="store_true", help="also plan between published waypoints")
    ap.add_argument("--seed", type=int, default=0, help="planner seed for --pairs")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.scene
        if folder is None:
            from urdf2mjcf.facility.build import build_facility
            from urdf2mjcf.facility.recipe import load_recipe

            folder = Path(tmp) / "imetro"
            recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
            build_facility(recipe, folder, root=ROOT, components=False)
        rows, line = demo_moves(folder, args.waypoints)
        pairs = pair_moves(folder, args.seed) if args.pairs else []

    print(f"machine: {machine()}; commit {commit()}; {time.strftime('%Y-%m-%d')}")
    print()
    print(f"The demo ({args.waypoints.name}): {line}")
    print()
    print(HEADER)
    print("\n".join(rows))
    if pairs:
        print()
        print(f"Between published waypoints (seed {args.seed}):")
        print()
        print(HEADER)
        print("\n".join(pairs))


if __name__ == "__main__":
    main()
