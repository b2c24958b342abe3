"""What a calibration costs (issue 33): a seven-joint arm, converted with position servos;
a copy of it with every joint's damping tripled and friction and armature added (the
truth, its MJCF edited), logged for ``--seconds`` at 500 Hz under a multi-sine with sensor
noise (2e-4 rad, 5e-3 rad/s); ``urdf2mjcf calibrate`` from the nominal model with
damping, friction and armature free (21 values). Writes its row into docs/benchmarks.md
with ``--write``.

    python bench/calibrate.py [--seconds 60] [--write]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

JOINTS = 7
AXES = ("0 0 1", "0 1 0", "0 1 0", "0 0 1", "0 1 0", "0 0 1", "0 1 0")


def chain() -> str:
    """The arm's URDF: seven revolute joints, each link a box, lighter towards the tool."""
    links = ['<link name="world"/>', '<link name="base"><inertial><mass value="5"/>'
             '<inertia ixx="0.05" iyy="0.05" izz="0.05" ixy="0" ixz="0" iyz="0"/></inertial>'
             "</link>",
             '<joint name="fix" type="fixed"><parent link="world"/><child link="base"/></joint>']  # fmt: skip
    parent = "base"
    for k in range(JOINTS):
        mass, length = 3.5 - 0.4 * k, 0.3 - 0.025 * k
        i = mass * length**2 / 12
        links.append(
            f'<link name="l{k}"><inertial><origin xyz="0 0 {length / 2}"/>'
            f'<mass value="{mass}"/><inertia ixx="{i}" iyy="{i}" izz="{i / 6}" ixy="0" '
            f'ixz="0" iyz="0"/></inertial><collision><origin xyz="0 0 {length / 2}"/>'
            f'<geometry><box size="0.05 0.05 {length * 0.8}"/></geometry></collision></link>'
        )
        links.append(
            f'<joint name="j{k}" type="revolute"><parent link="{parent}"/><child link="l{k}"/>'
            f'<origin xyz="0 0 {0.1 if k == 0 else 0.3 - 0.025 * (k - 1)}"/>'
            f'<axis xyz="{AXES[k]}"/><limit lower="-2.5" upper="2.5" effort="{120 - 15 * k}" '
            f'velocity="3"/><dynamics damping="0.5"/></joint>'
        )
        parent = f"l{k}"
    return '<robot name="chain7">' + "".join(links) + "</robot>"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--write", action="store_true", help="write the row into docs/benchmarks.md")
    args = ap.parse_args()

    import urdf2mjcf
    from bench.docs_table import write_section
    from bench.machine import line
    from tests.calibrate import arm

    folder = Path(tempfile.mkdtemp(prefix="calibrate-bench-"))
    (folder / "chain.urdf").write_text(chain())
    (folder / "act.yaml").write_text('joints:\n  "*": {type: position}\n')
    nominal = folder / "out" / "chain7.xml"
    urdf2mjcf.convert(folder / "chain.urdf", nominal, actuator_config=folder / "act.yaml",
                      use_environment=False)  # fmt: skip
    truth = {
        f"j{k}": {"damping": 1.5, "frictionloss": 0.4 + 0.1 * k, "armature": 0.02 + 0.005 * k}
        for k in range(JOINTS)
    }
    real = arm.perturbed(nominal, folder / "real.xml", truth, {})
    log = arm.record(real, folder / "log.csv", seconds=args.seconds, amplitude=0.3)
    start = time.perf_counter()
    res = subprocess.run(
        ["urdf2mjcf", "calibrate", str(nominal), str(log), "-o", str(folder / "cal"),
         "--free", "damping,frictionloss,armature", "-q"],
        capture_output=True, text=True,
    )  # fmt: skip
    wall = time.perf_counter() - start
    if res.returncode != 0:
        sys.exit(f"calibrate failed: {res.stderr.strip()}")
    report = json.loads((folder / "cal" / "report.json").read_text())
    off = []
    for p in report["parameters"]:
        joint, field = p["name"].split(".")
        off.append(abs(p["after"] - truth[joint][field]) / truth[joint][field])
    within = sum(e <= 0.10 for e in off)
    row = [
        f"{JOINTS} joints, {len(off)} values free",
        f"{args.seconds:g} s at 500 Hz",
        f"{wall:.0f}",
        report["cost"]["rollouts"],
        f"{report['held_out_improvement']:.1f}x",
        f"{within} of {len(off)}",
        f"{100 * sorted(off)[len(off) // 2]:.1f} %",
        len(report["warnings"]),
        line(),
    ]
    header = ["arm", "log", "wall (s)", "replays", "held-out error smaller", "within 10 %",
              "median error", "warnings", "machine"]  # fmt: skip
    print(dict(zip(header, row, strict=True)))
    if args.write:
        write_section(
            "calibrate",
            header,
            row,
            intro="## Calibration (`bench/calibrate.py`, issue 33)\n\n"
            + __doc__.split("\n\n")[0].replace("\n", " "),
        )


if __name__ == "__main__":
    main()
