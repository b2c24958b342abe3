"""Benchmark: contacts with fitted primitives against today's collision meshes.

    python bench/contacts.py                   # every example-robot-data robot, 3 pairs each
    python bench/contacts.py --every 4 --pairs 1
    python bench/contacts.py --json out.json   # also the per-robot figures
    python bench/contacts.py --shape primitive # primitives whatever their deviation

Each example-robot-data robot is converted twice into its own scene (floor through
its lowest point): with the default collision shapes (``decompose``: hulls, CoACD
parts where a mesh is concave) and with ``--collision-shape auto`` (a fitted primitive
where one is within the tolerance, else the same hull or parts; ``--shape`` picks
another strategy to compare). Each scene is then
stepped for ``--seconds`` of simulated time from its home keyframe, on one core, with
random controls (each actuator's target uniform in its control range, drawn anew
every 0.1 s, seed 0: both variants get the same sequence); a robot without actuators
simply settles on the floor. Steps per second are timed in alternating pairs
(default, auto) and each robot's speed-up is the median of its pairs' ratios.

The deviation of what each variant collides with comes from the conversion's own
certificate, measured independently of the fit (per link: the one-sided Hausdorff
distance from the collision surface to the description's, and the volume ratio).
Printed: the median and spread of the speed-ups, how many meshes became which shape,
the worst link deviation under ``auto``, and the robots whose certificate fails.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.machine import line as machine_line  # noqa: E402

BASE = "decompose"
CONTROL_PERIOD = 0.1
"""Seconds between two draws of the random controls."""


def label(urdf: Path) -> str:
    return f"{urdf.parent.parent.name}__{urdf.stem}"


def steps_per_second(scene: Path, seconds: float, seed: int = 0) -> tuple[float, int]:
    """(steps per second, steps) of ``seconds`` simulated from home under random controls."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(scene))
    d = mujoco.MjData(m)
    if m.nkey:
        mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    steps = max(1, round(seconds / m.opt.timestep))
    period = max(1, round(CONTROL_PERIOD / m.opt.timestep))
    rng = np.random.default_rng(seed)
    low, high = m.actuator_ctrlrange[:, 0], m.actuator_ctrlrange[:, 1]
    limited = m.actuator_ctrllimited.astype(bool)
    draws = [
        np.where(limited, rng.uniform(low, high), d.ctrl) for _ in range(steps // period + 1)
    ]
    t = time.perf_counter()
    for i in range(0, steps, period):
        d.ctrl[:] = draws[i // period]
        mujoco.mj_step(m, d, nstep=min(period, steps - i))
    return steps / (time.perf_counter() - t), steps


def shapes(notes: list) -> dict[str, int]:
    """How many meshes became which shape, from the conversion's notes."""
    out: dict[str, int] = {}
    for note in notes:
        kind = note.kind
        if kind in ("hull", "decomposed", "cached") or kind.startswith("primitive"):
            key = "decomposed" if kind == "cached" else kind
            out[key] = out.get(key, 0) + 1
    return out


def worst_link(certificate: dict) -> tuple[float, float, str]:
    """(largest Hausdorff mm, largest volume ratio, its link) over the measured links."""
    worst = (0.0, 0.0, "")
    for link, fig in certificate.get("collision", {}).get("links", {}).items():
        h = float(fig.get("hausdorff_mm") or 0.0)
        ratio = float(fig.get("volume_ratio") or 0.0)
        if h > worst[0]:
            worst = (h, max(ratio, worst[1]), link)
        else:
            worst = (worst[0], max(ratio, worst[1]), worst[2])
    return worst


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=3, help="timed (default, auto) pairs")
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated per timing")
    parser.add_argument("--every", type=int, default=1, help="take every N-th robot")
    parser.add_argument("--json", type=Path, help="also write the per-robot figures here")
    parser.add_argument(
        "--shape", default="auto", choices=("auto", "primitive", "hull"), help="against default"
    )
    args = parser.parse_args()
    variants = (BASE, args.shape)

    import urdf2mjcf
    from tests.corpus import example_robot_data_share, example_robot_data_urdfs, first_line

    share = example_robot_data_share()
    robots = example_robot_data_urdfs()[:: args.every]
    figures: dict[str, dict] = {}
    refused: dict[str, str] = {}
    totals: dict[str, dict[str, int]] = {v: {} for v in variants}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        scenes: dict[str, dict[str, Path]] = {}
        for urdf in robots:
            name = label(urdf)
            try:
                for variant in variants:
                    out = tmp / variant / name / "robot.xml"
                    report = urdf2mjcf.convert(
                        urdf,
                        out,
                        package_paths=[share],
                        use_environment=False,
                        collision_shape=variant,
                    )
                    scenes.setdefault(name, {})[variant] = out.with_name("scene.xml")
                    cert = report.certificate.to_dict() if report.certificate else {}
                    entry = figures.setdefault(name, {})
                    entry[variant] = {
                        "shapes": shapes(list(report.notes)),
                        "worst_hausdorff_mm": worst_link(cert)[0],
                        "worst_volume_ratio": worst_link(cert)[1],
                        "worst_link": worst_link(cert)[2],
                        "certificate_passed": bool(cert.get("passed")),
                    }
                    for kind, n in entry[variant]["shapes"].items():
                        totals[variant][kind] = totals[variant].get(kind, 0) + n
            except urdf2mjcf.ConversionError as exc:
                refused[name] = first_line(exc)
                scenes.pop(name, None)
                figures.pop(name, None)
        for name, pair in scenes.items():
            ratios = []
            for _ in range(args.pairs):
                base, _n = steps_per_second(pair[BASE], args.seconds)
                auto, _n = steps_per_second(pair[args.shape], args.seconds)
                ratios.append(auto / base)
                figures[name].setdefault("steps_per_s", []).append([base, auto])
            figures[name]["speedup"] = statistics.median(ratios)

    speedups = sorted(f["speedup"] for f in figures.values())
    worst = max(figures.items(), key=lambda kv: kv[1][args.shape]["worst_hausdorff_mm"])
    print(f"machine: {machine_line()}")
    print(f"robots: {len(figures)} (refused: {len(refused)}), pairs: {args.pairs}, "
          f"{args.seconds:g} s simulated per timing")  # fmt: skip
    for name, why in refused.items():
        print(f"  refused {name}: {why}")
    q = np.percentile(speedups, [0, 25, 50, 75, 100]) if speedups else [float("nan")] * 5
    lo, q1, median, q3, hi = (float(x) for x in q)
    print(
        f"speed-up {args.shape} / default: median {median:.2f}x (min {lo:.2f}, "
        f"quartiles {q1:.2f}-{q3:.2f}, max {hi:.2f})"
    )
    for variant in variants:
        parts = ", ".join(f"{n} {k}" for k, n in sorted(totals[variant].items()))
        print(f"shapes with {variant}: {parts}")
    print(
        f"worst link under {args.shape}: {worst[0]} {worst[1][args.shape]['worst_link']}: "
        f"{worst[1][args.shape]['worst_hausdorff_mm']:.1f} mm "
        f"(default: {worst[1][BASE]['worst_hausdorff_mm']:.1f} mm)"
    )
    failing = [n for n, f in figures.items() if not f[args.shape]["certificate_passed"]]
    print(f"certificates failing under {args.shape}: {len(failing)} {failing}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
