"""Benchmark: converting example-robot-data against MuJoCo loading the same URDFs itself.

    python bench/convert_ratio.py                 # cold pass, 3 warm rounds, print
    python bench/convert_ratio.py --rounds 5      # more alternating rounds
    python bench/convert_ratio.py --cache DIR --no-cold   # warm only, on a filled cache
    python bench/convert_ratio.py --write-docs    # also a row of docs/benchmarks.md's history

Native: MuJoCo's own URDF import, ``mujoco.MjModel.from_xml_path(urdf)``, of
each file with its mesh references made absolute (MuJoCo cannot resolve
``package://``; our resolver does it, before the clock starts) and
``<mujoco><compiler strippath="false"/></mujoco>`` added so MuJoCo keeps
those paths. That is all native does: it reads the collision meshes (URDF
import discards visuals), repairs nothing and steps nothing. Files it
rejects (DAE meshes, inertias it refuses, an STL over 200000 faces) are
left out of both sides; the script lists them with MuJoCo's reason.

Ours: ``urdf2mjcf.convert`` of the original file, the corpus' share folder
as the only package path, defaults otherwise, so the validation (compiling
scene.xml and stepping it for one simulated second) is included. Cold: an
empty cache (every concave collision mesh through CoACD, every mesh
decoded); warm: the same cache again.

Each pass runs in a fresh process (MuJoCo's own mesh cache and ours in
memory start empty), native and warm alternating in ``--rounds`` rounds; a
side's time is the median over rounds of its per-file times summed over the
files both load. Libraries both sides need are imported before the clock
starts. The machine line says CPU, cores, load average, Python and MuJoCo:
on a shared machine read the spread too.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.machine import describe as machine  # noqa: E402
from bench.machine import line as machine_line  # noqa: E402

HISTORY_COLUMN = "warm conversion / native load"


def label(urdf: Path) -> str:
    """A file's name in this benchmark: its folder and stem (two robots of the
    corpus are called anymal.urdf), safe as a file name."""
    return f"{urdf.parent.parent.name}__{urdf.stem}"


# -- the two sides, each run in a worker process -----------------------------------


def native_copy(urdf: Path, share: Path, dest: Path) -> str | None:
    """Write ``urdf`` with absolute mesh paths that MuJoCo keeps to ``dest``; None,
    or why not (a mesh our resolver cannot find either)."""
    from lxml import etree

    from tests.corpus import LENIENT, first_line
    from urdf2mjcf.packages import PackageResolver

    resolver = PackageResolver(urdf, package_paths=(share,), use_environment=False)
    root = etree.parse(str(urdf), LENIENT).getroot()
    for mesh in root.iter("mesh"):
        try:
            mesh.set("filename", str(resolver.resolve(mesh.get("filename", ""))))
        except Exception as exc:  # an unknown package or a missing file
            return f"mesh {mesh.get('filename')}: {first_line(exc)}"
    mj = root.find("mujoco")
    if mj is None:
        mj = etree.SubElement(root, "mujoco")
    compiler = mj.find("compiler")
    if compiler is None:
        compiler = etree.SubElement(mj, "compiler")
    compiler.set("strippath", "false")
    dest.write_bytes(etree.tostring(root))
    return None


def work_native(files: list[Path]) -> dict:
    import mujoco

    from tests.corpus import first_line

    times: dict[str, float] = {}
    errors: dict[str, str] = {}
    start = time.perf_counter()
    for f in files:  # named <label>.urdf by main()
        t = time.perf_counter()
        try:
            mujoco.MjModel.from_xml_path(str(f))
        except Exception as exc:  # MuJoCo's ValueError: the file is left out
            errors[f.stem] = first_line(exc)
            continue
        times[f.stem] = time.perf_counter() - t
    return {"total": time.perf_counter() - start, "times": times, "errors": errors}


def work_ours(files: list[Path], share: Path, cache: Path, out: Path) -> dict:
    import mujoco  # noqa: F401  # imported by both sides before the clock
    import scipy.spatial  # noqa: F401
    import trimesh  # noqa: F401

    import urdf2mjcf
    from tests.corpus import first_line

    times: dict[str, float] = {}
    errors: dict[str, str] = {}
    start = time.perf_counter()
    for urdf in files:
        t = time.perf_counter()
        try:
            urdf2mjcf.convert(
                urdf,
                out / label(urdf) / "robot.xml",
                package_paths=[share],
                use_environment=False,
                cache_dir=cache,
                overwrite=True,
            )
        except urdf2mjcf.ConversionError as exc:
            errors[label(urdf)] = first_line(exc)
            continue
        times[label(urdf)] = time.perf_counter() - t
    return {"total": time.perf_counter() - start, "times": times, "errors": errors}


def worker(args: argparse.Namespace) -> int:
    files = [Path(line) for line in Path(args.list).read_text().splitlines() if line]
    if args.worker == "native":
        result = work_native(files)
    else:
        result = work_ours(files, Path(args.share), Path(args.cache), Path(args.out))
    print(json.dumps(result))
    return 0


def run_worker(kind: str, files: list[Path], tmp: Path, **paths: Path) -> dict:
    listing = tmp / f"{kind}.list"
    listing.write_text("\n".join(str(f) for f in files) + "\n")
    cmd = [sys.executable, __file__, "--worker", kind, "--list", str(listing)]
    for key, value in paths.items():
        cmd += [f"--{key}", str(value)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{kind} worker failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


# -- the report -----------------------------------------------------------------------


def summed(run: dict, names: list[str]) -> float:
    return sum(run["times"][n] for n in names)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rounds", type=int, default=3, help="alternating native/warm rounds")
    parser.add_argument("--cache", type=Path, help="cache folder (default: a new empty one)")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold pass")
    parser.add_argument("--write-docs", action="store_true")
    parser.add_argument("--note", default="", help="a note for the history row")
    parser.add_argument("--json", type=Path, help="also write every per-file time here")
    parser.add_argument("--worker", choices=["native", "ours"], help=argparse.SUPPRESS)
    parser.add_argument("--list", help=argparse.SUPPRESS)
    parser.add_argument("--share", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(args)
    if args.no_cold and args.cache is None:
        parser.error("--no-cold measures a filled cache: name it with --cache")

    from tests.corpus import example_robot_data_share, example_robot_data_urdfs

    share = example_robot_data_share()
    urdfs = example_robot_data_urdfs()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        cache = args.cache or tmp / "cache"
        native_dir = tmp / "native"
        native_dir.mkdir()
        native_files, excluded = [], {}
        for urdf in urdfs:
            dest = native_dir / f"{label(urdf)}.urdf"
            why = native_copy(urdf, share, dest)
            if why is None:
                native_files.append(dest)
            else:
                excluded[label(urdf)] = why
        runs: dict[str, list[dict]] = {"native": [], "warm": []}
        cold = None
        if not args.no_cold:
            cold = run_worker("ours", urdfs, tmp, share=share, cache=cache, out=tmp / "out")
        for r in range(args.rounds):
            order = ["native", "warm"] if r % 2 == 0 else ["warm", "native"]
            for side in order:
                if side == "native":
                    runs["native"].append(run_worker("native", native_files, tmp))
                else:
                    runs["warm"].append(
                        run_worker("ours", urdfs, tmp, share=share, cache=cache, out=tmp / "out")
                    )
    for name, reason in runs["native"][0]["errors"].items():
        excluded[name] = reason
    ours_failed = set().union(*(r["errors"] for r in runs["warm"]))
    both = sorted(n for n in runs["native"][0]["times"] if n not in ours_failed)
    native = [summed(r, both) for r in runs["native"]]
    warm = [summed(r, both) for r in runs["warm"]]
    warm_all = [r["total"] for r in runs["warm"]]
    native_all = [r["total"] for r in runs["native"]]  # its refusals' time included
    ratio = statistics.median(warm) / statistics.median(native)
    result: dict = {
        "corpus": "example-robot-data",
        "files": len(urdfs),
        "both_load": len(both),
        "excluded": dict(sorted(excluded.items())),
        "ours_failed": sorted(ours_failed),
        "rounds": args.rounds,
        "native_s": [round(x, 2) for x in native],
        "warm_s": [round(x, 2) for x in warm],
        "warm_over_native": round(ratio, 2),
        "warm_over_native_range": [
            round(min(w / n for w, n in zip(warm, native, strict=True)), 2),
            round(max(w / n for w, n in zip(warm, native, strict=True)), 2),
        ],
        "warm_all_files_s": [round(x, 1) for x in warm_all],
        # the first reading: every file on both sides, native's refusals included
        # (it stops at the first thing it cannot load, which is no conversion)
        "native_all_files_s": [round(x, 2) for x in native_all],
        "warm_all_over_native_all": round(
            statistics.median(warm_all) / statistics.median(native_all), 2
        ),
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
    }
    if cold is not None:
        cold_both = summed(cold, both)
        result["cold_s"] = round(cold_both, 1)
        result["cold_over_native"] = round(cold_both / statistics.median(native), 1)
        result["cold_all_files_s"] = round(cold["total"], 1)

    def median_time(side: str, name: str) -> float:
        return statistics.median(r["times"][name] for r in runs[side])

    slowest = sorted(both, key=lambda n: -median_time("warm", n))[:5]
    result["slowest_warm"] = {
        n: [round(median_time("warm", n), 2), round(median_time("native", n), 3)] for n in slowest
    }
    print(json.dumps(result, indent=2))
    print(
        f"\nwarm / native: {result['warm_over_native']} "
        f"(rounds {result['warm_over_native_range'][0]}-{result['warm_over_native_range'][1]})"
        + (f", cold / native: {result['cold_over_native']}" if cold is not None else "")
        + f"; {len(both)} of {len(urdfs)} files (native loads {len(both)}); "
        + f"all {len(urdfs)} files, native's refusals included: "
        + f"{result['warm_all_over_native_all']}; "
        + machine_line(result["machine"])
    )
    if args.json:
        args.json.write_text(json.dumps({"result": result, "runs": runs, "cold": cold}, indent=1))
    if args.write_docs:
        write_docs(result, args.note)
    return 1 if ours_failed else 0


def write_docs(result: dict, note: str) -> None:
    """The ratio into the history table (one row per date and commit, shared with
    bench/facility.py, which owns that table)."""
    from bench.facility import record_history

    spread = result["warm_over_native_range"]
    detail = (
        f"{result['both_load']} of {result['files']} files (native rejects the rest); "
        f"median of {result['rounds']} rounds, spread {spread[0]}-{spread[1]}; "
        f"native {statistics.median(result['native_s']):.1f} s, "
        f"warm {statistics.median(result['warm_s']):.1f} s"
    )
    if "cold_over_native" in result:
        detail += f", cold {result['cold_s']} s ({result['cold_over_native']}x)"
    record_history(
        {
            HISTORY_COLUMN: result["warm_over_native"],
            "machine": machine_line(result["machine"]),
            "note": "; ".join(x for x in (detail, note) if x),
        }
    )


if __name__ == "__main__":
    sys.exit(main())
