"""Benchmark: cold conversion, robot by robot, of two source trees alternating.

    git worktree add /tmp/before <commit>
    python bench/cold_pairs.py /tmp/before [--rounds 2]

Each conversion runs in a fresh process with an empty cache (every mesh
decoded, every concave collision mesh through CoACD), the two trees
alternating per robot, on 12 robots of example-robot-data (every sixth of the
sorted list). Prints per-robot medians and the sums: "after" is this tree.
"""

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
parser = argparse.ArgumentParser()
parser.add_argument("before", help="the other source tree (a git worktree)")
parser.add_argument("--rounds", type=int, default=2)
args = parser.parse_args()
from tests.corpus import example_robot_data_share, example_robot_data_urdfs  # noqa: E402

urdfs = sorted(example_robot_data_urdfs())
pick = urdfs[:: max(1, len(urdfs) // 12)][:12]
share = example_robot_data_share()
TREES = {"before": str(Path(args.before).resolve()), "after": str(ROOT)}
CODE = """
import sys, time; sys.path.insert(0, sys.argv[1])
import mujoco, trimesh, scipy.spatial
import urdf2mjcf
assert urdf2mjcf.__file__.startswith(sys.argv[1]), urdf2mjcf.__file__
t = time.perf_counter()
urdf2mjcf.convert(sys.argv[2], sys.argv[3], package_paths=[sys.argv[4]], use_environment=False, cache_dir=sys.argv[5], overwrite=True)
print(time.perf_counter() - t)
"""
res = {"before": {}, "after": {}}
for rnd in range(args.rounds):
    for u in pick:
        order = ["before", "after"] if rnd % 2 == 0 else ["after", "before"]
        for side in order:
            with tempfile.TemporaryDirectory() as tmp:
                out = subprocess.run(
                    [
                        sys.executable,
                        "-c",
                        CODE,
                        TREES[side],
                        str(u),
                        f"{tmp}/o/robot.xml",
                        str(share),
                        f"{tmp}/cache",
                    ],
                    capture_output=True,
                    text=True,
                    cwd="/tmp",
                )
                if out.returncode:
                    print(side, u.stem, "FAILED", out.stderr[-300:])
                    continue
                t = float(out.stdout.strip().splitlines()[-1])
                res[side].setdefault(u.parent.parent.name + "/" + u.stem, []).append(t)
                print(rnd, side, u.parent.parent.name, u.stem, round(t, 2), flush=True)
names = sorted(set(res["before"]) & set(res["after"]))
b = sum(statistics.median(res["before"][n]) for n in names)
a = sum(statistics.median(res["after"][n]) for n in names)
print(
    json.dumps(
        {
            "robots": len(names),
            "before_s": round(b, 1),
            "after_s": round(a, 1),
            "after_over_before": round(a / b, 3),
            "per_robot": {
                n: [
                    round(statistics.median(res["before"][n]), 2),
                    round(statistics.median(res["after"][n]), 2),
                ]
                for n in names
            },
        },
        indent=1,
    )
)
