"""Benchmark: convert the whole example-robot-data corpus cold and warm.

Cold: an empty cache (every mesh decoded, every non-convex collision mesh
through CoACD). Warm: the same cache again (no decoding, no decomposition).
bench/convert_ratio.py compares the warm run with MuJoCo's own URDF load.

    python bench/convert_corpus.py                 # print the table
    python bench/convert_corpus.py --write-docs    # also update docs/benchmarks.md

Needs the test extras (example-robot-data).
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import urdf2mjcf  # noqa: E402
from bench.docs_table import write_section  # noqa: E402
from tests.corpus import example_robot_data_share, example_robot_data_urdfs  # noqa: E402


def run_pass(
    urdfs: list[Path], share: Path, cache: Path, out_root: Path, jobs: int
) -> tuple[float, dict]:
    stats = {"decomposed": 0, "cached": 0, "failed": []}
    start = time.perf_counter()
    for urdf in urdfs:
        out = out_root / urdf.parent.parent.name / urdf.stem / "robot.xml"  # two anymal.urdf
        try:
            report = urdf2mjcf.convert(
                urdf,
                out,
                package_paths=[share],
                use_environment=False,
                cache_dir=cache,
                workers=jobs,
                overwrite=True,
            )
        except urdf2mjcf.ConversionError as exc:
            stats["failed"].append(f"{urdf.name}: {exc}")
            continue
        stats["decomposed"] += len(report.decomposed)
        stats["cached"] += len(report.cached)
    return time.perf_counter() - start, stats


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--write-docs", action="store_true")
    parser.add_argument("-j", "--jobs", type=int, default=0)
    args = parser.parse_args()
    urdfs = example_robot_data_urdfs()
    share = example_robot_data_share()
    with tempfile.TemporaryDirectory() as tmp:
        cache, out = Path(tmp) / "cache", Path(tmp) / "out"
        cold, cold_stats = run_pass(urdfs, share, cache, out, args.jobs)
        warm, warm_stats = run_pass(urdfs, share, cache, out, args.jobs)
    result = {
        "robots": len(urdfs),
        "cold_s": round(cold, 1),
        "warm_s": round(warm, 1),
        "cold": cold_stats,
        "warm": warm_stats,
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}",
        "date": time.strftime("%Y-%m-%d"),
    }
    print(json.dumps(result, indent=2))
    if args.write_docs:
        write_section(
            "corpus-bench",
            [
                "corpus",
                "robots",
                "cold (s)",
                "warm (s)",
                "decompositions cold / warm",
                "machine",
                "date",
            ],
            [
                "example-robot-data",
                len(urdfs),
                result["cold_s"],
                result["warm_s"],
                f"{cold_stats['decomposed']} / {warm_stats['decomposed']}",
                result["machine"],
                result["date"],
            ],
        )
    return 1 if cold_stats["failed"] or warm_stats["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
