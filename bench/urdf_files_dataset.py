"""The public urdf_files_dataset (320 URDFs): ours vs MuJoCo's own URDF import vs
urdfdom, into docs/corpus.md.

    git clone https://github.com/Daniella1/urdf_files_dataset /tmp/urdf_files_dataset
    python bench/urdf_files_dataset.py /tmp/urdf_files_dataset          # print the summary
    URDF2MJCF_URDF_FILES_DATASET=/tmp/urdf_files_dataset python bench/urdf_files_dataset.py
    python bench/urdf_files_dataset.py DIR --write-docs   # also update docs/corpus.md
    python bench/urdf_files_dataset.py DIR --json out.json --jobs 2

Nothing of the dataset is copied into this repository: the script reads the
copy it is given. Each file is tried four ways:

- urdfdom: pinocchio's ``buildModelFromUrdf`` (the ROS reference parser);
- ours: ``urdf2mjcf.convert`` as a user runs ``urdf2mjcf FILE`` (no package
  path, no environment: packages are found by the enclosing folders and the
  resolver's fallbacks, each a warning), validation included (``scene.xml``
  compiled and stepped by MuJoCo); where urdfdom reads the file, every link
  frame must match pinocchio within 1e-9 at random configurations, and
  gravity torques within 1e-6;
- MuJoCo native, as is: ``mujoco.MjModel.from_xml_path(urdf)`` (meshes looked
  up by file name in the URDF's folder);
- MuJoCo native, meshes supplied: the same with every referenced mesh that
  our resolver finds handed over by file name, as if copied beside the URDF.

Speed: ``--decompose-timeout`` bounds each CoACD decomposition (a mesh past it
gets its convex hull, with a warning; the model still compiles and frames are
unaffected); the decomposition cache (``--cache``, default the user cache)
makes a second run warm. ``--jobs`` files run at once, each in its own process.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

DOCS = ROOT / "docs" / "corpus.md"
KNOWN = ROOT / "tests" / "data" / "urdf_files_dataset_known_failures.yaml"
ENV = "URDF2MJCF_URDF_FILES_DATASET"
FRAME_TOL, GRAVITY_TOL = 1e-9, 1e-6
FILES = 320
FLOOR = 305
"""Issue 24: at least this many of the 320 files convert."""
USD_CONVERTER = "296 of 306"
"""urdf-usd-converter's published figure on its copy of the dataset (not run here)."""


def dataset_root(arg: str | None) -> Path | None:
    """The copy named by ``arg``, else by ``$URDF2MJCF_URDF_FILES_DATASET``; None if neither."""
    value = arg or os.environ.get(ENV)
    if not value:
        return None
    root = Path(value).expanduser()
    return root if (root / "urdf_files").is_dir() else None


def dataset_files(root: Path) -> list[Path]:
    return sorted((root / "urdf_files").rglob("*.urdf"))


def _reference_source(urdf: Path, out: Path) -> Path:
    """What urdfdom and pinocchio read: the xacro package's expansion of a xacro
    file named .urdf; the file itself when that fails (leftover macro calls whose
    definitions are not shipped: urdfdom ignores the elements)."""
    from tests.corpus import xacro_expanded

    try:
        return xacro_expanded(urdf, out)
    except Exception:  # xacro raises its own errors for unknown macros
        return urdf


def check_file(
    root: Path, urdf: Path, out: Path, cache: Path | None, decompose_timeout: float
) -> dict:
    """One file, four ways (see the module docstring)."""
    import urdf2mjcf
    from tests.corpus import (
        check_robot,
        first_line,
        gathered_meshes,
        mujoco_native_error,
        urdfdom_error,
    )

    name = str(urdf.relative_to(root / "urdf_files"))
    source = _reference_source(urdf, out / "reference")
    urdfdom = urdfdom_error(source)
    options = dict(
        cache_dir=cache,
        decompose_timeout=decompose_timeout,
        workers=1,
        overwrite=True,
    )
    row: dict = {"file": name, "urdfdom": urdfdom, "ours": None, "warnings": 0, "frames": None}
    start = time.perf_counter()
    try:
        if urdfdom is None:
            s = check_robot(urdf, out, [], root / "urdf_files", source, **options)
            row["warnings"] = len(s["warnings"])
            row["frames"] = max(s["pos_err"], s["rot_err"])
            if row["frames"] > FRAME_TOL:
                row["ours"] = f"frames differ from pinocchio: {row['frames']:.1e}"
            elif s["gravity_rel_err"] > GRAVITY_TOL:
                row["ours"] = f"gravity torques differ from pinocchio: {s['gravity_rel_err']:.1e}"
        else:
            report = urdf2mjcf.convert(
                urdf, out / "robot.xml", package_paths=[], use_environment=False, **options
            )
            row["warnings"] = len(report.warnings)
    except urdf2mjcf.ConversionError as exc:
        row["ours"] = f"error: {first_line(exc)}"
    except Exception as exc:  # a crash is what this benchmark looks for
        row["ours"] = f"crash: {type(exc).__name__}: {first_line(exc)}"
    row["seconds"] = round(time.perf_counter() - start, 2)
    row["native"] = mujoco_native_error(urdf) if source == urdf else "holds xacro"
    meshes = gathered_meshes(urdf, [], source)
    row["native_meshes"] = (
        mujoco_native_error(source, meshes) if isinstance(meshes, dict) else meshes
    )
    for key in ("ours", "urdfdom", "native", "native_meshes"):
        if row[key]:
            row[key] = scrub(row[key].replace(f"{urdf}: ", ""), root, out)  # the row names it
    return row


def scrub(text: str, root: Path, out: Path) -> str:
    """A reason without this machine's paths, fit for a table cell."""
    text = text.replace(str(out), "<out>").replace(str(root / "urdf_files"), "<dataset>")
    text = text.replace(str(root), "<dataset>").replace(sys.prefix, "<prefix>")
    text = " ".join(text.replace("|", "\\|").split())
    return text if len(text) <= 160 else text[:157] + "..."


def _work(args: tuple[str, str, str, str | None, float]) -> dict:
    root, urdf, out, cache, timeout = args
    import logging

    logging.disable(logging.WARNING)  # warnings are counted in the row, not printed
    return check_file(Path(root), Path(urdf), Path(out), Path(cache) if cache else None, timeout)


def run(
    root: Path,
    files: list[Path],
    cache: Path | None,
    decompose_timeout: float,
    jobs: int,
    progress: bool = True,
) -> list[dict]:
    """Every file's row, in the order of ``files``."""
    with tempfile.TemporaryDirectory() as tmp:
        tasks = [
            (
                str(root),
                str(f),
                str(Path(tmp) / str(i)),
                str(cache) if cache else None,
                decompose_timeout,
            )
            for i, f in enumerate(files)
        ]
        rows = []
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for row in pool.map(_work, tasks):
                rows.append(row)
                if progress:
                    print(
                        f"{row['seconds']:7.1f}s {row['file']}: {row['ours'] or 'ok'}",
                        file=sys.stderr,
                        flush=True,
                    )
    return rows


def known_failures(path: Path = KNOWN) -> dict[str, str]:
    """File -> a part of the reason it does not convert (tests/data/...known_failures.yaml)."""
    import yaml

    data = yaml.safe_load(path.read_text()) or {}
    return {str(k): str(v) for k, v in (data.get("files") or {}).items()}


def unexpected(rows: list[dict], known: dict[str, str]) -> list[str]:
    """What differs from the list of known failures: a file failing that is not on it,
    a listed file failing for another reason, a listed file that now converts."""
    problems = []
    for r in rows:
        expected = known.get(r["file"])
        if r["ours"] and expected is None:
            problems.append(f"{r['file']}: fails, not on the list: {r['ours']}")
        elif r["ours"] and expected not in r["ours"]:
            problems.append(f"{r['file']}: listed for '{expected}', fails with: {r['ours']}")
        elif not r["ours"] and expected is not None:
            problems.append(f"{r['file']}: converts now; take it off the list")
    return problems


def totals(rows: list[dict]) -> dict[str, int]:
    accepted = [r for r in rows if r["urdfdom"] is None]
    return {
        "files": len(rows),
        "urdfdom": len(accepted),
        "ours": sum(r["ours"] is None for r in rows),
        "ours_urdfdom": sum(r["ours"] is None for r in accepted),
        "compared": sum(r["frames"] is not None for r in rows),
        "native": sum(r["native"] is None for r in rows),
        "native_meshes": sum(r["native_meshes"] is None for r in rows),
    }


HEADING = "## The urdf_files_dataset"
INTRO = f"""{HEADING}

[urdf_files_dataset](https://github.com/Daniella1/urdf_files_dataset) gathers 320
URDF files from six collections (Drake, MATLAB, OEMs, ROS-Industrial, the Robotics
Toolbox, assorted repositories); the "Understanding URDF" survey and
urdf-usd-converter's benchmark use it. Generated by
`python bench/urdf_files_dataset.py DIR --write-docs` from a clone of it (nothing of
it is in this repository); `tests/test_corpus_urdf_files_dataset.py` runs the same
checks when `$URDF2MJCF_URDF_FILES_DATASET` names the clone, and fails when a file
outside `tests/data/urdf_files_dataset_known_failures.yaml` fails or a listed
file's reason changes.

- **ours**: `urdf2mjcf FILE` as a user runs it: no package path, packages found
  through the enclosing folders and the resolver's fallbacks (each a warning);
  a mesh the dataset does not ship is dropped with a warning; the written
  `scene.xml` compiled and stepped by MuJoCo. Where urdfdom reads the file,
  every link frame matches pinocchio within 1e-9 at random configurations and
  gravity torques within 1e-6. CoACD decompositions are bounded by
  `--decompose-timeout` (a mesh past it keeps its convex hull, with a warning);
  the decomposition cache makes later runs warm;
- **urdfdom**: pinocchio's `buildModelFromUrdf` (kinematics; meshes not opened);
  a xacro file named `.urdf` is expanded by the xacro package first;
- **MuJoCo native, as is**: `mujoco.MjModel.from_xml_path(urdf)` (meshes looked
  up by file name in the URDF's folder); **meshes supplied**: the same with
  every mesh our resolver finds handed over by file name;
- **urdf-usd-converter**: its published figure on its own copy of the dataset
  ({USD_CONVERTER}; all its failures invalid files); we do not run it.

Some of the files reference meshes the dataset does not ship; such robots
convert without those geoms (the warning names each). The run below used a copy
whose 64 largest mesh files (Git objects our mirror lacks) were absent, so those
geoms were dropped the same way; frames and the count are unaffected."""


def write_docs(rows: list[dict], t: dict[str, int], meta: dict[str, str]) -> None:
    from bench.docs_table import write_section

    write_section(
        "urdf-files-dataset",
        [
            "files",
            "ours",
            "ours (of urdfdom's)",
            "frames checked (1e-9)",
            "urdfdom",
            "MuJoCo native, as is",
            "MuJoCo native, meshes supplied",
            "urdf-usd-converter (published)",
            "dataset commit",
            "run",
        ],
        [
            t["files"],
            t["ours"],
            f"{t['ours_urdfdom']} of {t['urdfdom']}",
            t["compared"],
            t["urdfdom"],
            t["native"],
            t["native_meshes"],
            USD_CONVERTER,
            meta["commit"],
            meta["run"],
        ],
        intro=INTRO,
        docs=DOCS,
    )
    failing = [r for r in rows if r["ours"] or r["urdfdom"]]
    write_section(
        "urdf-files-dataset-files",
        ["file", "ours", "urdfdom", "MuJoCo native, as is", "MuJoCo native, meshes supplied"],
        rows=[
            [f"`{r['file']}`"]
            + [r[k] or "ok" for k in ("ours", "urdfdom", "native", "native_meshes")]
            for r in failing
        ],
        intro="The files that fail for us or for urdfdom, with the first line of each reason:",
        docs=DOCS,
    )


def _commit(root: Path) -> str:
    head = root / ".git" / "HEAD"
    try:
        ref = head.read_text().strip()
        if ref.startswith("ref: "):
            ref = (root / ".git" / ref[5:]).read_text().strip()
        return ref[:7]
    except OSError:
        return "-"


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", nargs="?", help=f"the clone (default: ${ENV})")
    parser.add_argument("--write-docs", action="store_true")
    parser.add_argument("--json", type=Path, help="write every file's result here")
    parser.add_argument("--cache", type=Path, help="decomposition cache (default: the user's)")
    parser.add_argument("--decompose-timeout", type=float, default=30.0)
    parser.add_argument("--jobs", type=int, default=max(1, (os.cpu_count() or 1) // 2))
    parser.add_argument("--only", nargs="*", help="substrings of the files to run")
    args = parser.parse_args()
    root = dataset_root(args.dataset)
    if root is None:
        parser.error(f"name the dataset clone (argument or ${ENV}); it must hold urdf_files/")
    files = [f for f in dataset_files(root) if not args.only or any(s in str(f) for s in args.only)]
    start = time.perf_counter()
    rows = run(root, files, args.cache, args.decompose_timeout, args.jobs)
    seconds = time.perf_counter() - start
    t = totals(rows)
    from bench.machine import line as machine_line

    meta = {
        "commit": _commit(root),
        "run": f"{seconds:.0f} s, {args.jobs} jobs, decompose timeout "
        f"{args.decompose_timeout:g} s, {machine_line()}",
    }
    if args.write_docs:
        write_docs(rows, t, meta)
    print(
        f"{t['files']} files; ours {t['ours']} ({t['ours_urdfdom']} of urdfdom's {t['urdfdom']}; "
        f"frames checked on {t['compared']}); MuJoCo native {t['native']} as is, "
        f"{t['native_meshes']} with meshes; {meta['run']}"
    )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
