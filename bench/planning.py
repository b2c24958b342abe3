"""Benchmark: plan the demo's joint moves on the default facility (runner/plan.py).

    python bench/planning.py                       # build the facility, plan, print a table
    python bench/planning.py --scene build/imetro  # a facility built earlier (no build)
    python bench/planning.py --repeat 3            # median planning time of 3 runs per move

The moves are the demo file's ``joints`` steps (recipes/demo/imetro.yaml, or
``--waypoints``) in their order, each from the previous goal, starting at the
home keyframe: goal ``q`` as written, or ``arm`` (the six arm joints) and ``set``
(named joints) applied to the previous goal, as the demo does. The steps between
them (Cartesian, hinge, gripper) are not run, so the robot plans from the previous
joint waypoint. Limits: the file's ``robot.vmax``; ``robot.amax`` when the file has
it, else twice vmax per second. Planning time is wall time of ``JointPlanner.plan``
(straight-line check, RRT*, shortcutting, TOPP-RA timing and its collision check).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.facility import commit, machine  # noqa: E402


def joint_moves(spec: dict, names: list[str], home: list[float]) -> list[tuple[str, list[float]]]:
    """(step name, goal of the robot's joints) for each ``joints`` step, chained."""
    q = list(home)
    out = []
    for step in spec.get("steps", []):
        if step.get("kind") != "joints":
            continue
        q = list(step["q"]) if "q" in step else list(q)
        if "arm" in step:
            q[2:] = step["arm"]
        for name, value in step.get("set", {}).items():
            q[names.index(name)] = value
        out.append((step["name"], [float(x) for x in q]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, help="a built facility folder (default: build one)")
    ap.add_argument("--waypoints", type=Path, default=ROOT / "recipes" / "demo" / "imetro.yaml")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--time-limit", type=float, default=30.0)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()

    import mujoco
    import numpy as np

    from urdf2mjcf.errors import PlanningError
    from urdf2mjcf.runner.demo import load_waypoints
    from urdf2mjcf.runner.load import load
    from urdf2mjcf.runner.plan import JointPlanner

    with tempfile.TemporaryDirectory() as tmp:
        folder = args.scene
        if folder is None:
            from urdf2mjcf.facility.build import build_facility
            from urdf2mjcf.facility.recipe import load_recipe

            folder = Path(tmp) / "imetro"
            recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
            build_facility(recipe, folder, root=ROOT, components=False)
        fac = load(folder)
    m, d, r = fac.model, fac.data, fac.robot
    spec = load_waypoints(args.waypoints)
    vmax = np.array(spec["robot"]["vmax"], float)
    amax = np.array(spec["robot"].get("amax", 2 * vmax), float)
    joints = [int(j) for j in r.joints]
    names = list(r.joint_names)
    state = d.qpos.copy()
    adr = m.jnt_qposadr[joints]
    moves = joint_moves(spec, names, state[adr].tolist())

    rows = []
    for name, goal in moves:
        times, result, error = [], None, ""
        for _ in range(args.repeat):
            planner = JointPlanner(
                m, joints, vmax, amax, seed=args.seed, time_limit=args.time_limit
            )
            t0 = time.perf_counter()
            try:
                result = planner.plan(state, goal)
            except PlanningError as exc:
                error = str(exc)
            times.append(time.perf_counter() - t0)
        if result is None:
            rows.append(f"| {name} | failed: {error} | | | | | {statistics.median(times):.2f} |")
            print(f"{name}: {error}", file=sys.stderr)
        else:
            rows.append(
                f"| {name} | {result.planner} | {result.path_length:.2f} | {len(result.path)} "
                f"| {result.times[-1]:.1f} | {'yes' if result.straight_line_free else 'no'} "
                f"| {statistics.median(times):.2f} |"
            )
        # the next move starts at this goal (the lift's middle stage follows the lift)
        state[adr] = goal
        for e in range(m.neq):
            if m.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT and m.eq_obj2id[e] in joints:
                lead = state[m.jnt_qposadr[m.eq_obj2id[e]]]
                state[m.jnt_qposadr[m.eq_obj1id[e]]] = np.polyval(m.eq_data[e, 4::-1], lead)

    print(
        f"{len(moves)} joint moves of {args.waypoints.relative_to(ROOT)}, seed {args.seed}, "
        f"time limit {args.time_limit:g} s, median of {args.repeat}"
    )
    print(f"machine: {machine()}; commit {commit()}; {time.strftime('%Y-%m-%d')}")
    print()
    print(
        "| move | planner | path length | waypoints | duration (s) | straight free | planning (s) |"
    )
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
