"""Benchmark: build the default facility cold and warm, and simulate it against its robot.

    python bench/facility.py                    # build, measure, print
    python bench/facility.py --profile          # also MuJoCo's timers, and the unfiltered twin
    python bench/facility.py --scene build/x    # measure a facility built earlier (no build)
    python bench/facility.py --write-docs       # also update docs/benchmarks.md (latest + history)
    python bench/facility.py --collision-baseline decompose   # also the recipe's old shapes

Build: `make-facility` on recipes/imetro.yaml with an empty decomposition
cache (cold) and again with that cache (warm); once more without folding the
fixtures (``fold_fixtures=False``), measured beside it. Simulation: steps per second
on one core with cameras off (no rendering), from the home keyframe with the
servos holding it, of the whole facility and of the robot compiled on its own
(components/imetro_robot), in ``--runs`` alternating pairs; the ratio is the
median of the pairs' ratios (a shared machine is noisy: read the spread).

Collision: what the recipe's collision meshes became (the conversion's notes: meshes
per shape, the primitive geoms, the largest deviation of one); with
``--collision-baseline SHAPE`` the recipe is also built with ``collision.default``
set to SHAPE (``decompose``: the converter's default, the setting before the recipe
had the key) and stepped in the same alternation.

The history table in docs/benchmarks.md has a column for each ratio we track:
this script fills "facility / robot steps"; another benchmark fills "warm
conversion / native load" through :func:`record_history`.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.machine import line as machine  # noqa: E402  (the one-line description)

DOCS = ROOT / "docs" / "benchmarks.md"

HISTORY = "facility-history"
HISTORY_COLUMNS = [
    "date",
    "commit",
    "facility / robot steps",
    "warm conversion / native load",
    "facility steps/s",
    "robot steps/s",
    "machine",
    "note",
]
"""Columns of the history table; a benchmark fills the ones it measures, '-' elsewhere."""


def steps_per_second(xml: Path | str, seconds: float = 3.0) -> tuple[float, float]:
    """(steps per wall second, real-time factor) stepping ``seconds`` of simulated time."""
    import mujoco

    return _steps(mujoco.MjModel.from_xml_path(str(xml)), seconds)


def _steps(m, seconds: float = 3.0) -> tuple[float, float]:
    import mujoco

    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    n = int(seconds / m.opt.timestep)
    start = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d)
    wall = time.perf_counter() - start
    return n / wall, seconds / wall


def unfiltered(scene: Path):
    """The facility with every geom in MuJoCo's default contact class (contype and
    conaffinity 1): the model as it was before the facility's fixture class."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(scene))
    for g in spec.geoms:
        if (g.contype, g.conaffinity) == (2, 1):
            g.contype = 1
    return spec.compile()


def alternate(models: dict, runs: int) -> dict[str, list[float]]:
    """Steps per second of each model, ``runs`` times, in turn (a, b, a, b, ...)."""
    out: dict[str, list[float]] = {k: [] for k in models}
    for _ in range(runs):
        for name, m in models.items():
            out[name].append(_steps(m)[0])
    return out


def profile(m, steps: int = 3000) -> dict[str, float]:
    """Share of a step (%) per MuJoCo timer, the microseconds of a step, and the
    contacts at the end (``data.timer`` after stepping from the home keyframe)."""
    import mujoco

    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    for _ in range(steps):
        mujoco.mj_step(m, d)
    t = mujoco.mjtTimer

    def us(timer) -> float:
        return d.timer[timer].duration / max(d.timer[timer].number, 1) * 1e6

    step = us(t.mjTIMER_STEP)
    shares = {
        "collision": t.mjTIMER_POS_COLLISION,
        "broad phase": t.mjTIMER_COL_BROAD,
        "narrow phase": t.mjTIMER_COL_NARROW,
        "kinematics": t.mjTIMER_POS_KINEMATICS,
        "constraint make": t.mjTIMER_POS_MAKE,
        "constraint solve": t.mjTIMER_CONSTRAINT,
    }
    out = {"step (us)": round(step, 1)}
    out |= {f"{k} (%)": round(100 * us(v) / step, 1) for k, v in shares.items()}
    out["contacts"] = d.ncon
    out["geoms"], out["bodies"] = m.ngeom, m.nbody
    return out


def commit() -> str:
    """Short HEAD, with '+' when the simulated sources differ from it."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "facility", "recipes", "urdf2mjcf"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        ).stdout.strip()
    except OSError:
        return "-"
    return (head + "+" if dirty else head) or "-"


def record_history(values: dict[str, object], docs: Path = DOCS) -> None:
    """Fill ``values`` (column -> value) into today's row for this commit of the
    history table in ``docs``, appending that row when there is none: each
    benchmark fills its own columns and keeps the others'."""
    begin, end = f"<!-- {HISTORY}:begin -->", f"<!-- {HISTORY}:end -->"
    text = docs.read_text()
    if begin not in text:
        raise ValueError(f"{docs}: no {begin} ... {end} block for the history table")
    block = re.search(re.escape(begin) + "(.*?)" + re.escape(end), text, flags=re.S)
    assert block is not None
    rows = [
        [c.strip() for c in line.strip().strip("|").split("|")]
        for line in block.group(1).strip().splitlines()[2:]
        if line.strip()
    ]
    key = {"date": time.strftime("%Y-%m-%d"), "commit": commit()}
    unknown = set(values) - set(HISTORY_COLUMNS)
    if unknown:
        raise ValueError(f"unknown history columns: {sorted(unknown)}")
    cells = {**key, **{k: str(v) for k, v in values.items()}}
    for row in rows:
        if row[:2] == [key["date"], key["commit"]]:
            for k, v in cells.items():
                row[HISTORY_COLUMNS.index(k)] = v
            break
    else:
        rows.append([cells.get(c, "-") for c in HISTORY_COLUMNS])
    table = "\n".join(
        [
            begin,
            "| " + " | ".join(HISTORY_COLUMNS) + " |",
            "|" + "---|" * len(HISTORY_COLUMNS),
            *("| " + " | ".join(r) + " |" for r in rows),
            end,
        ]
    )
    docs.write_text(text[: block.start()] + table + text[block.end() :])


UNFOLDED = "facility, fixtures not folded"
BASELINE = "facility, collision baseline"
DEVIATION = re.compile(r"Hausdorff ([0-9.]+) mm, volume ratio ([0-9.]+)")


def collision_figures(report) -> dict:
    """What the conversion made of the collision meshes, from its notes (``api.Report``):
    distinct meshes per shape, the geoms that are fitted primitives (a set counts each),
    and the largest one-sided Hausdorff distance (mm) and volume ratio of a fit."""
    primitive = report.primitive
    kinds = [n.message.split(" ", 1)[0] for n in primitive]
    deviations = [DEVIATION.search(n.message) for n in primitive]
    figures = [(float(d.group(1)), float(d.group(2))) for d in deviations if d]
    return {
        "meshes": {
            "primitive": len(primitive),
            "hull": len(report.of_kind("hull")),
            "decomposed": len(report.of_kind("decomposed")) + len(report.of_kind("cached")),
        },
        "primitive_geoms": sum(len(k.split("+")) for k in kinds),
        "worst_hausdorff_mm": max((h for h, _ in figures), default=None),
        "worst_volume_ratio": max((v for _, v in figures), default=None),
    }


def measure(
    scene: Path,
    robot: Path | None,
    runs: int,
    with_profile: bool,
    unfolded: Path | None = None,
    baseline: Path | None = None,
) -> dict:
    """``unfolded``: the same facility built with ``fold_fixtures=False``, measured in
    the same alternation (the gain of urdf2mjcf.facility.fold); ``baseline``: the same
    facility built with the baseline collision shapes, likewise."""
    import mujoco

    models = {"facility": mujoco.MjModel.from_xml_path(str(scene))}
    if robot is not None:
        models["robot"] = mujoco.MjModel.from_xml_path(str(robot))
    if unfolded is not None:
        models[UNFOLDED] = mujoco.MjModel.from_xml_path(str(unfolded))
    if baseline is not None:
        models[BASELINE] = mujoco.MjModel.from_xml_path(str(baseline))
    if with_profile:
        models["facility, every geom colliding"] = unfiltered(scene)
    sps = alternate(models, runs)
    med = {k: statistics.median(v) for k, v in sps.items()}
    out: dict = {
        "facility_steps_per_s": round(med["facility"]),
        "facility_steps_per_s_range": [round(min(sps["facility"])), round(max(sps["facility"]))],
    }
    if robot is not None:
        ratios = [f / r for f, r in zip(sps["facility"], sps["robot"], strict=True)]
        out |= {
            "robot_steps_per_s": round(med["robot"]),
            "robot_steps_per_s_range": [round(min(sps["robot"])), round(max(sps["robot"]))],
            "facility_vs_robot": round(statistics.median(ratios), 3),
            "facility_vs_robot_range": [round(min(ratios), 3), round(max(ratios), 3)],
        }
    if unfolded is not None and robot is not None:
        ratios = [f / r for f, r in zip(sps[UNFOLDED], sps["robot"], strict=True)]
        out["unfolded_steps_per_s"] = round(med[UNFOLDED])
        out["unfolded_vs_robot"] = round(statistics.median(ratios), 3)
    if baseline is not None:
        ratios = [f / b for f, b in zip(sps["facility"], sps[BASELINE], strict=True)]
        out["baseline_steps_per_s"] = round(med[BASELINE])
        out["baseline_steps_per_s_range"] = [
            round(min(sps[BASELINE])),
            round(max(sps[BASELINE])),
        ]
        out["facility_vs_baseline"] = round(statistics.median(ratios), 3)
        out["facility_vs_baseline_range"] = [round(min(ratios), 3), round(max(ratios), 3)]
    out["conversion_vs_native_load"] = None  # another benchmark's: see record_history
    out["runs"] = runs
    if with_profile:
        twin = "facility, every geom colliding"
        out["unfiltered_steps_per_s"] = round(med[twin])
        if robot is not None:
            ratios = [f / r for f, r in zip(sps[twin], sps["robot"], strict=True)]
            out["unfiltered_vs_robot"] = round(statistics.median(ratios), 3)
        out["profile"] = {k: profile(m) for k, m in models.items()}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--write-docs", action="store_true")
    parser.add_argument("--runs", type=int, default=5, help="alternating pairs (default 5)")
    parser.add_argument(
        "--profile", action="store_true", help="MuJoCo timers and the unfiltered twin"
    )
    parser.add_argument("--scene", type=Path, help="a built facility folder: measure it, no build")
    parser.add_argument("--note", default="", help="a note for the history row")
    parser.add_argument(
        "--collision-baseline",
        choices=("decompose", "hull", "primitive", "auto"),
        help="also build the recipe with collision.default set to this and step it in "
        "the same alternation (decompose: the converter's default)",
    )
    args = parser.parse_args()

    result: dict = {}
    if args.scene is not None:
        manifest = json.loads((args.scene / "facility.json").read_text())
        robot = manifest.get("component_mjcf", {}).get("imetro_robot")
        result |= measure(
            args.scene / "scene.xml", args.scene / robot if robot else None, args.runs, args.profile
        )
    else:
        from urdf2mjcf.facility.build import build_facility
        from urdf2mjcf.facility.recipe import load_recipe

        recipe = load_recipe(ROOT / "recipes" / "imetro.yaml")
        with tempfile.TemporaryDirectory() as tmp:
            cache, out = Path(tmp) / "cache", Path(tmp) / "imetro"
            t = time.perf_counter()
            report = build_facility(recipe, out, root=ROOT, cache_dir=cache)
            cold = time.perf_counter() - t
            t = time.perf_counter()
            build_facility(recipe, out, root=ROOT, cache_dir=cache)
            warm = time.perf_counter() - t
            counts = report.manifest["counts"]
            result |= {"cold_s": round(cold, 1), "warm_s": round(warm, 1)}
            plain = build_facility(
                recipe,
                Path(tmp) / "unfolded",
                root=ROOT,
                cache_dir=cache,
                components=False,
                fold_fixtures=False,
            )
            result["collision"] = {
                "setting": dict(recipe.collision) or "the converter's default",
                **collision_figures(report.conversion),
            }
            baseline = None
            if args.collision_baseline is not None:
                sets = {"collision.default": args.collision_baseline}
                old = build_facility(
                    load_recipe(ROOT / "recipes" / "imetro.yaml", sets),
                    Path(tmp) / "baseline",
                    root=ROOT,
                    cache_dir=cache,
                    components=False,
                )
                baseline = old.scene
                result["collision_baseline"] = {
                    "setting": args.collision_baseline,
                    **collision_figures(old.conversion),
                    "same_scene": old.scene.read_bytes() == report.scene.read_bytes(),
                }
            result |= measure(
                report.scene,
                report.components.get("imetro_robot"),
                args.runs,
                args.profile,
                unfolded=plain.scene,
                baseline=baseline,
            )
            result |= {"bodies": counts["bodies"], "dofs": counts["dofs"]}
    result |= {"machine": machine(), "commit": commit(), "date": time.strftime("%Y-%m-%d")}
    print(json.dumps(result, indent=2))
    if args.write_docs:
        write_docs(result, args.note)
    return 0


def write_docs(result: dict, note: str) -> None:
    from bench.docs_table import write_section

    ratio = result.get("facility_vs_robot")
    spread = result.get("facility_vs_robot_range")
    if "cold_s" in result:
        write_section(
            "facility-bench",
            [
                "build cold (s)",
                "build warm (s)",
                "facility steps/s",
                "robot alone steps/s",
                "facility / robot (median of pairs)",
                "bodies",
                "dofs",
                "machine",
                "date",
                "commit",
            ],
            [
                result["cold_s"],
                result["warm_s"],
                result["facility_steps_per_s"],
                result.get("robot_steps_per_s", "-"),
                f"{ratio} ({spread[0]}-{spread[1]}, {result['runs']} pairs)" if ratio else "-",
                result["bodies"],
                result["dofs"],
                result["machine"],
                result["date"],
                result["commit"],
            ],
        )
    if result.get("unfolded_vs_robot") is not None:
        same_run = f"fixtures not folded, same run: {result['unfolded_vs_robot']}"
        note = f"{note}; {same_run}" if note else same_run
    if result.get("baseline_steps_per_s") is not None:
        shape = result["collision_baseline"]["setting"]
        same_run = (
            f"collision {shape}, same run: {result['baseline_steps_per_s']} steps/s "
            f"(facility / it {result['facility_vs_baseline']})"
        )
        note = f"{note}; {same_run}" if note else same_run
    record_history(
        {
            "facility / robot steps": ratio if ratio is not None else "-",
            "facility steps/s": result["facility_steps_per_s"],
            "robot steps/s": result.get("robot_steps_per_s", "-"),
            "machine": result["machine"],
            "note": note or "-",
        }
    )


if __name__ == "__main__":
    sys.exit(main())
