"""Benchmark: what the certificate costs, as a fraction of a warm conversion.

    python bench/certificate.py                     # every example-robot-data robot, 4 rounds
    python bench/certificate.py --every 5 --rounds 2   # a fifth of them, two rounds
    python bench/certificate.py --cache DIR         # a filled cache (default: a new one, filled first)

For each robot of example-robot-data: a warm conversion without the
certificate (``urdf2mjcf.convert(..., certify=False)``: passes, writing,
validation, on a cache filled by a first conversion), then the certificate
of the files it wrote as the conversion computes it (``api._certificate`` on
the model validation compiled from the written ``scene.xml``, which the
conversion reuses; the reference read, every figure),
split into the certificate's own figures (frames, joints, masses, dynamics:
what ``certify`` computes before the collision and lint sections) and the
collision and lint sections. Rounds alternate which of a robot's two conversions
runs first (the second runs a little faster; an even number of rounds balances
it); a side's time is the median
over rounds of its per-robot times, summed over the robots. pinocchio
installed or not decides the dynamics (the machine line says which).
Robots the conversion refuses are left out (listed).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench.machine import line as machine_line  # noqa: E402


def label(urdf: Path) -> str:
    return f"{urdf.parent.parent.name}__{urdf.stem}"


def measure(
    urdf: Path, share: Path, cache: Path, out: Path, plain_first: bool = False
) -> dict[str, float]:
    """Seconds of one warm conversion, its whole certificate, and the certificate's parts.

    ``plain_first``: the conversion without the certificate runs first (the second of
    two conversions of a robot runs a little faster: rounds alternate the order)."""
    import urdf2mjcf
    from urdf2mjcf import api, certify
    from urdf2mjcf.certify import changes as changes_mod
    from urdf2mjcf.certify import dynamics, kinematics, mass
    from urdf2mjcf.certify.reference import load
    from urdf2mjcf.passes import xacro

    target = out / label(urdf) / "robot.xml"
    options = api.make_options(
        package_paths=[share], use_environment=False, cache_dir=cache, overwrite=True
    )
    plain = api.make_options(
        package_paths=[share], use_environment=False, cache_dir=cache, overwrite=True,
        certify=False,
    )  # fmt: skip
    seconds: dict[bool, float] = {}
    for certified in (False, True) if plain_first else (True, False):
        t = time.perf_counter()
        report = urdf2mjcf.convert(urdf, target, options if certified else plain)
        seconds[certified] = time.perf_counter() - t
    with_s, convert_s = seconds[True], seconds[False]
    doc = xacro.run(urdf, options.xacro)
    files = [str(f.relative_to(target.parent)) for f in report.files]
    assert report.model is not None

    # validation's model of the staged scene.xml, which the conversion hands the certificate
    scene = certify.compile_written(target.with_name("scene.xml"), files)
    t = time.perf_counter()
    cert = api._certificate(doc, report.model, target, files, options.certify, scene)
    whole_s = time.perf_counter() - t
    if not cert.computed:
        raise LookupError(cert.why_not)

    # the certificate's own figures, as certify computes them
    t = time.perf_counter()
    ref = load(doc)
    mt = kinematics.match(ref, scene)
    configs = kinematics.sample_configurations(ref, certify.SAMPLES)
    _, _, frames = kinematics.frames_section(mt, configs, 1e-6, 1e-6)
    kinematics.joints_section(mt, frames[0], certify.Tolerances())
    amended = changes_mod.amended_by_conversion(report.model)
    mass.mass_section(mt, frames[0], amended, 1e-9, 1e-6)
    dynamics.dynamics_section(mt, configs[: 1 + certify.DYNAMICS_SAMPLES], amended, 1e-6)
    own_s = time.perf_counter() - t
    return {
        "convert": convert_s,
        "with_certificate": with_s,
        "certificate": whole_s,
        "own": own_s,
        "collision_and_lint": max(0.0, whole_s - own_s),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--every", type=int, default=1, help="take every N-th robot")
    parser.add_argument("--cache", type=Path, help="a cache folder (default: new, filled first)")
    parser.add_argument("--json", type=Path, help="also write the per-robot times here")
    args = parser.parse_args()

    import mujoco  # noqa: F401  # imports before any clock
    import trimesh  # noqa: F401

    import urdf2mjcf
    from tests.corpus import example_robot_data_share, example_robot_data_urdfs, first_line
    from urdf2mjcf.certify import dynamics

    share = example_robot_data_share()
    robots = example_robot_data_urdfs()[:: args.every]
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        cache = args.cache or tmp / "cache"
        out = tmp / "out"
        refused: dict[str, str] = {}
        for urdf in robots:  # fill the cache; find what converts
            try:
                urdf2mjcf.convert(
                    urdf,
                    out / label(urdf) / "robot.xml",
                    package_paths=[share],
                    use_environment=False,
                    cache_dir=cache,
                    overwrite=True,
                )  # with its certificate: a warm one reads its collision figures back
            except urdf2mjcf.ConversionError as exc:
                refused[label(urdf)] = first_line(exc)
        robots = [u for u in robots if label(u) not in refused]
        times: dict[str, dict[str, list[float]]] = {label(u): {} for u in robots}
        for round_ in range(args.rounds):
            for urdf in robots:
                if label(urdf) in refused:
                    continue
                try:
                    figures = measure(urdf, share, cache, out, plain_first=round_ % 2 == 1)
                except LookupError as exc:  # no certificate: an empty robot, say
                    refused[label(urdf)] = f"certificate not computed: {exc}"
                    del times[label(urdf)]
                    continue
                for key, value in figures.items():
                    times[label(urdf)].setdefault(key, []).append(value)

    def total(key: str) -> float:
        return sum(statistics.median(t[key]) for t in times.values())

    convert_s, with_s, whole_s = total("convert"), total("with_certificate"), total("certificate")
    own_s, rest_s = total("own"), total("collision_and_lint")
    added_s = with_s - convert_s
    print(f"machine: {machine_line()}, pinocchio {'yes' if dynamics.available() else 'no'}")
    print(f"robots: {len(times)} (left out: {len(refused)}), rounds: {args.rounds}")
    for name, why in refused.items():
        print(f"  left out {name}: {why}")
    print("| warm conversion (s) | with certificate (s) | certificate / conversion | "
          "certificate alone (s) | own figures (s) | collision + lint (s) |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    print(
        f"| {convert_s:.2f} | {with_s:.2f} | {added_s / convert_s:.0%} | {whole_s:.2f} | "
        f"{own_s:.2f} | {rest_s:.2f} |"
    )
    worst = sorted(
        times.items(),
        key=lambda kv: statistics.median(kv[1]["own"]) / statistics.median(kv[1]["convert"]),
    )[-3:]
    for name, t in worst:
        c, o = statistics.median(t["convert"]), statistics.median(t["own"])
        print(f"  highest own share: {name}: {o:.3f} s of {c:.3f} s ({o / c:.0%})")
    if args.json:
        args.json.write_text(json.dumps(times, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
