"""Benchmark: conversion time against the number of links (deep kinematic trees).

    python bench/deep_chain.py                    # print the table
    python bench/deep_chain.py --write-docs       # also update docs/benchmarks.md
    python bench/deep_chain.py --links 100 400    # other sizes
    python bench/deep_chain.py --profile 1600 --kinds tree   # cProfile one robot

Three generated robots per size: a chain of revolute joints hanging down
with a small box or cylinder and an inertial per link (a cable, a rope, a
snake robot); the same chain with a mesh per link, the links sharing three
STL files; and a tree of 20-link branches, each hanging off the middle of an
earlier branch in a column of its own. Each is timed twice: the passes in
memory (``api.build``: xacro to MJCF text), then the whole ``convert``
(MuJoCo compiling the model for the scene floor, then validating it with one
simulated second). A chain deeper than MuJoCo reads is a conversion error;
its row gives the time to that error.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import platform
import pstats
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")  # steady timings on a shared machine
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SIZES = (100, 400, 496, 1600, 5000)
KINDS = ("chain", "mesh-chain", "tree")
LINK_LENGTH = 0.05
DAMPING = 0.01  # N m s/rad: without it the tree's tips, resting on the floor, shake it


def _inertial(mass: float = 0.1) -> str:
    i = mass * LINK_LENGTH**2 / 12
    return (
        f'<inertial><origin xyz="0 0 {-LINK_LENGTH / 2}"/><mass value="{mass}"/>'
        f'<inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i / 10}"/></inertial>'
    )


def _geometry(k: int, kind: str) -> str:
    if kind == "mesh-chain":
        return f'<mesh filename="meshes/part{k % 3}.stl"/>'
    if k % 2:
        return f'<cylinder radius="0.01" length="{LINK_LENGTH}"/>'
    return f'<box size="0.02 0.02 {LINK_LENGTH}"/>'


def _link(k: int, kind: str) -> str:
    geom = _geometry(k, kind)
    origin = f'<origin xyz="0 0 {-LINK_LENGTH / 2}"/>'
    return (
        f'<link name="link{k}">{_inertial()}'
        f"<visual>{origin}<geometry>{geom}</geometry></visual>"
        f"<collision>{origin}<geometry>{geom}</geometry></collision></link>"
    )


def _joint(k: int, parent: int, xyz: str, kind: str) -> str:
    # The tree's hinges all turn about x, the axis its branches are offset along, so
    # the hanging branches put no torque on them: the tree is at rest as converted.
    axis = "1 0 0" if k % 2 or kind == "tree" else "0 1 0"
    return (
        f'<joint name="joint{k}" type="revolute"><parent link="link{parent}"/>'
        f'<child link="link{k}"/><origin xyz="{xyz}"/><axis xyz="{axis}"/>'
        f'<limit lower="-1" upper="1" effort="1" velocity="1"/>'
        f'<dynamics damping="{DAMPING}"/></joint>'
    )


FORK_EVERY = 20
FORK_GAP = 0.04  # between the hanging branches of the tree: their geoms never touch


def _parents(n: int, kind: str) -> list[tuple[int, str]]:
    """(parent index, joint origin) of links 1..n-1: a hanging chain, or a tree."""
    down = f"0 0 {-LINK_LENGTH}"
    if kind != "tree":
        return [(k - 1, down) for k in range(1, n)]
    # Branch b hangs off the middle of branch (b - 1) // 2, in its own column x = b * gap.
    out = []
    for k in range(1, n):
        branch, pos = divmod(k - 1, FORK_EVERY)
        if pos:
            out.append((k - 1, down))
        elif branch == 0:
            out.append((0, down))
        else:
            parent_branch = (branch - 1) // 2
            parent = parent_branch * FORK_EVERY + FORK_EVERY // 2
            out.append((parent, f"{(branch - parent_branch) * FORK_GAP} 0 0"))
    return out


def write_meshes(folder: Path) -> None:
    """Three small convex STL parts shared by every link of the mesh variant."""
    import trimesh

    folder.mkdir(parents=True, exist_ok=True)
    parts = [
        trimesh.creation.box((0.02, 0.02, LINK_LENGTH)),
        trimesh.creation.cylinder(0.01, LINK_LENGTH, sections=16),
        trimesh.creation.icosphere(1, 0.012),
    ]
    for k, part in enumerate(parts):
        part.export(folder / f"part{k}.stl")


def robot_urdf(n: int, kind: str = "chain") -> str:
    """URDF text of an ``n``-link robot of the given kind (see the module docstring)."""
    parts = [f'<robot name="{kind}{n}">', _link(0, kind)]
    for k, (parent, xyz) in enumerate(_parents(n, kind), start=1):
        parts += [_link(k, kind), _joint(k, parent, xyz, kind)]
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


def write_robot(folder: Path, n: int, kind: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if kind == "mesh-chain":
        write_meshes(folder / "meshes")
    path = folder / f"{kind}{n}.urdf"
    path.write_text(robot_urdf(n, kind))
    return path


def _depth(n: int, kind: str) -> int:
    """Bodies from the world to the deepest link."""
    depth = {0: 1}
    for k, (parent, _) in enumerate(_parents(n, kind), start=1):
        depth[k] = depth[parent] + 1
    return max(depth.values())


def measure(urdf: Path, out: Path, cache: Path) -> tuple[float, float | None, str]:
    """(seconds of the passes in memory, seconds of the whole convert or None, error)."""
    import urdf2mjcf
    from urdf2mjcf import api

    options = api.make_options(cache_dir=cache, overwrite=True)
    start = time.perf_counter()
    try:
        api.build(urdf, options)
    except urdf2mjcf.ConversionError as exc:
        return time.perf_counter() - start, None, str(exc.detail)
    passes = time.perf_counter() - start
    start = time.perf_counter()
    urdf2mjcf.convert(urdf, out, options)
    return passes, time.perf_counter() - start, ""


def main() -> int:
    from bench.docs_table import write_section
    from urdf2mjcf.passes.emit import MAX_BODY_DEPTH

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--write-docs", action="store_true")
    parser.add_argument("--links", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    parser.add_argument("--profile", type=int, metavar="LINKS", help="cProfile one conversion")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        cache = base / "cache"
        if args.profile:
            urdf = write_robot(base / "robot", args.profile, args.kinds[0])
            profiler = cProfile.Profile()
            profiler.runcall(measure, urdf, base / "out" / "robot.xml", cache)
            pstats.Stats(profiler).sort_stats("cumulative").print_stats(40)
            return 0
        warm = write_robot(base / "warm-up", 10, "tree")  # imports out of the first row
        measure(warm, base / "warm-up" / "out" / "robot.xml", cache)
        rows: list[list[object]] = []
        header = ["robot", "links", "depth", "passes (s)", "ms/link", "convert (s)", "ms/link"]
        print(" | ".join(header))
        for kind in args.kinds:
            for n in args.links:
                folder = base / f"{kind}{n}"
                urdf = write_robot(folder, n, kind)
                passes, total, error = measure(urdf, folder / "out" / "robot.xml", cache)
                row: list[object] = [kind, n, _depth(n, kind), f"{passes:.2f}"]
                row.append(f"{1000 * passes / n:.2f}")
                if total is None:
                    limit = f"{MAX_BODY_DEPTH} nested bodies"
                    row += [f"error: deeper than MuJoCo reads ({limit})", ""]
                    print(f"  ({error})", file=sys.stderr)
                else:
                    row += [f"{total:.2f}", f"{1000 * total / n:.2f}"]
                print(" | ".join(str(v) for v in row), flush=True)
                rows.append(row)
    machine = f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}"
    if args.write_docs:
        date = time.strftime("%Y-%m-%d")
        write_section(
            "deep-chain-bench",
            [*header, "machine", "date"],
            intro=INTRO,
            rows=[row + [machine, date] for row in rows],
        )
    return 0


INTRO = """\
## Deep kinematic trees (`bench/deep_chain.py`)

`python bench/deep_chain.py --write-docs` converts generated robots of 100 to
5,000 links: a hanging chain of revolute joints with a box or cylinder and an
inertial per link (`chain`), the same chain with a mesh per link, all links
sharing three STL files (`mesh-chain`), and a tree of 20-link branches, each
hanging off the middle of an earlier one (`tree`). *passes* is `api.build`:
every pass in memory, xacro to MJCF text; *convert* is the whole command,
MuJoCo compiling the model for the scene floor and again to validate it with
one simulated second.

Kinematic trees are walked without recursion: the passes take about the same
time per link from 100 to 5,000 links (0.3-0.7 ms), chains included. MuJoCo
has limits of its own: it reads at most 496 nested bodies from one MJCF file
(its XML reader stops at 500 nested elements; its compiler at 1023 nested
bodies), so a deeper chain is one error naming the first link past the limit;
its row gives the time to that error (every pass up to emit's body tree). The
rest of *convert* is MuJoCo's and grows faster than the link count: its
compile time grows with bodies times depth, and a step of a chain of n hinges
costs about n^3 (its joint-space inertia is dense)."""


if __name__ == "__main__":
    sys.exit(main())
