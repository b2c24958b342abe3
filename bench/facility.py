"""Benchmark: build the default facility cold and warm, and simulate it.

    python bench/facility.py                 # print
    python bench/facility.py --write-docs    # also update docs/benchmarks.md

Build: `make-facility` on recipes/imetro.yaml with an empty decomposition
cache (cold) and again with that cache (warm). Simulation: steps per second
of the whole facility on one CPU core with cameras off (no rendering), from
the home keyframe with the servos holding it, compared with the robot alone.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def steps_per_second(xml: Path, seconds: float = 3.0) -> tuple[float, float]:
    """(steps per wall second, real-time factor) stepping ``seconds`` of simulated time."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    n = int(seconds / m.opt.timestep)
    start = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d)
    wall = time.perf_counter() - start
    return n / wall, seconds / wall


def main() -> int:
    from bench.docs_table import write_section
    from urdf2mjcf.facility.build import build_facility
    from urdf2mjcf.facility.recipe import load_recipe

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--write-docs", action="store_true")
    args = parser.parse_args()
    recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        cache, out = Path(tmp) / "cache", Path(tmp) / "imetro"
        t = time.perf_counter()
        report = build_facility(recipe, out, root=ROOT, cache_dir=cache)
        cold = time.perf_counter() - t
        t = time.perf_counter()
        build_facility(recipe, out, root=ROOT, cache_dir=cache)
        warm = time.perf_counter() - t
        facility_sps, facility_rtf = steps_per_second(report.scene)
        robot = report.components.get("imetro_robot")
        robot_sps, robot_rtf = steps_per_second(robot) if robot else (float("nan"), float("nan"))
        counts = report.manifest["counts"]
    result = {
        "cold_s": round(cold, 1),
        "warm_s": round(warm, 1),
        "facility_steps_per_s": round(facility_sps),
        "facility_realtime_factor": round(facility_rtf, 1),
        "robot_steps_per_s": round(robot_sps),
        "robot_realtime_factor": round(robot_rtf, 1),
        "bodies": counts["bodies"],
        "dofs": counts["dofs"],
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}",
        "date": time.strftime("%Y-%m-%d"),
    }
    print(json.dumps(result, indent=2))
    if args.write_docs:
        write_section(
            "facility-bench",
            [
                "build cold (s)",
                "build warm (s)",
                "facility steps/s (x real time)",
                "robot alone steps/s (x real time)",
                "bodies",
                "dofs",
                "machine",
                "date",
            ],
            [
                result["cold_s"],
                result["warm_s"],
                f"{result['facility_steps_per_s']} ({result['facility_realtime_factor']}x)",
                f"{result['robot_steps_per_s']} ({result['robot_realtime_factor']}x)",
                result["bodies"],
                result["dofs"],
                result["machine"],
                result["date"],
            ],
            intro="## Building and simulating the default facility\n\n`python bench/facility.py --write-docs`: `make-facility` cold (empty\ndecomposition cache) and warm, then steps per second of the whole facility\non one core with cameras off, against the robot alone.",
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
