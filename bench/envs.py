"""Benchmark: reset and step rates of the Gymnasium environments.

    python bench/envs.py                  # measure, print JSON
    python bench/envs.py --write-docs     # also fill the table in docs/benchmarks.md

For each environment (``IMetro-v0``, ``Mira3D-v0``), without and with camera
observations (the robot's camera, RGB and depth at 128 x 96): the time to make it
(the facility already built: load and compile only), resets per second (each with a
new seed: keyframe, seeded poses, ``mj_forward``, the observation) and env steps per
second with uniformly random actions (each ``frame_skip`` physics steps; truncation
ignored). One process, one core for MuJoCo; the rates are medians of ``--runs`` runs.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

IDS = ("IMetro-v0", "Mira3D-v0")
SECTION = "envs-bench"
HEADER = [
    "environment",
    "camera obs",
    "make (s)",
    "resets/s",
    "env steps/s",
    "physics steps/s",
    "frame_skip",
    "machine",
    "date",
    "commit",
]

INTRO = """## Gymnasium environments

`python bench/envs.py --write-docs`: for `IMetro-v0` and `Mira3D-v0` (docs/envs.md),
without and with camera observations (RGB and depth of the robot's camera at
128 x 96, rendered offscreen on the CPU here: Mesa's EGL), the time to make the
environment once its facility is built (load and compile), resets per second (each
with a new seed: keyframe, seeded poses by model fields, `mj_forward`, the
observation; nothing is rebuilt) and env steps per second under uniformly random
actions (25 Hz control, 20 physics steps of 2 ms each). Medians of 3 runs of 50
resets and 200 steps, one process. The machine is shared: read the load.
The first `gym.make` of an id also builds its facility once (as make-facility
warm, above: seconds), never again while its inputs stay the same."""


def measure(eid: str, camera: bool, resets: int, steps: int, runs: int) -> dict:
    import gymnasium as gym

    start = time.perf_counter()
    env = gym.make(eid, camera_obs=camera, root=ROOT).unwrapped  # no wrappers in the timing
    made = time.perf_counter() - start
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(steps)]
    reset_rates, step_rates = [], []
    for run in range(runs):
        start = time.perf_counter()
        for i in range(resets):
            env.reset(seed=run * resets + i)
        reset_rates.append(resets / (time.perf_counter() - start))
        env.reset(seed=run)
        start = time.perf_counter()
        for a in actions:
            _, _, terminated, _, _ = env.step(a)
            if terminated:
                env.reset()
        step_rates.append(steps / (time.perf_counter() - start))
    env.close()
    rate = statistics.median(step_rates)
    return {
        "environment": eid,
        "camera_obs": camera,
        "make_s": round(made, 2),
        "resets_per_s": round(statistics.median(reset_rates), 1),
        "steps_per_s": round(rate, 1),
        "physics_steps_per_s": round(rate * env.frame_skip),
        "frame_skip": env.frame_skip,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resets", type=int, default=50)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--write-docs", action="store_true")
    args = parser.parse_args()

    import urdf2mjcf.envs  # noqa: F401  (registers the ids; picks the GL backend first)
    from bench.facility import commit, machine
    from urdf2mjcf.headless import gl_context_error

    cameras = (False, True) if gl_context_error() is None else (False,)
    for eid in IDS:  # build (or find) each facility before anything is timed
        import gymnasium as gym

        gym.make(eid, root=ROOT).close()
    results = [measure(e, c, args.resets, args.steps, args.runs) for e in IDS for c in cameras]
    stamp = {"machine": machine(), "commit": commit(), "date": time.strftime("%Y-%m-%d")}
    print(json.dumps({"results": results, **stamp}, indent=2))
    if args.write_docs:
        from bench.docs_table import write_section

        rows = [
            [
                r["environment"],
                "RGB-D 128 x 96" if r["camera_obs"] else "no",
                r["make_s"],
                r["resets_per_s"],
                r["steps_per_s"],
                r["physics_steps_per_s"],
                r["frame_skip"],
                stamp["machine"],
                stamp["date"],
                stamp["commit"],
            ]
            for r in results
        ]
        write_section(SECTION, HEADER, rows=rows, intro=INTRO)
    return 0


if __name__ == "__main__":
    sys.exit(main())
