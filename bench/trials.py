"""Benchmark: seeded demo trials per minute (``facility-demo --trials N``).

    python bench/trials.py [--trials 8] [--workers N]    # measure, print JSON

Runs ``N`` trials of the iMETRO demo (``recipes/imetro.yaml``, ``recipes/demo/imetro.yaml``,
seeds 0 .. N-1) on the local pool as ``facility-demo --trials`` does (each trial builds
its jittered facility without components and replays the demo) and reports the wall
time, trials per minute and the verdicts. To compare two versions, run it from each
checkout in turn on the same machine (``PYTHONPATH=<checkout>``), alternating.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(os.environ.get("CHECKOUT", Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=8)
    parser.add_argument("--workers", type=int, default=None)
    args = parser.parse_args()

    from bench.machine import describe
    from urdf2mjcf.runner.trials import run_trials

    start = time.perf_counter()
    results = run_trials(
        ROOT / "recipes" / "imetro.yaml",
        ROOT,
        ROOT / "recipes" / "demo" / "imetro.yaml",
        list(range(args.trials)),
        workers=args.workers,
    )
    wall = time.perf_counter() - start
    print(
        json.dumps(
            {
                "trials": args.trials,
                "workers": args.workers,
                "wall_s": round(wall, 1),
                "trials_per_minute": round(60 * args.trials / wall, 2),
                "verdicts": {str(r["seed"]): bool(r["ok"]) for r in results},
                "failed_steps": {str(r["seed"]): r["failed_step"] for r in results},
                "machine": describe(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
