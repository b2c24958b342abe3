"""``urdf2mjcf batch PATHS... -o OUT``: many robot descriptions, one output tree, one summary.

Each source is one job on an executor (:mod:`urdf2mjcf.runner.executors`: the local
process pool, or a Ray cluster). A job converts into a temporary folder of its worker
and returns the files as bytes; this process writes them into a staging folder beside
OUT, then moves the tree into place with ``batch.json`` (the summary, and the list of
the files we wrote) last. So:

* bad input (a PATH that does not exist, a folder with no robot, two sources that
  would land on the same output, an OUT that is not ours) is one ``error:`` line, exit
  2, before anything is converted or written;
* a robot that fails to convert is a line of the summary, not the end of the batch
  (exit 1 when any failed, 0 when all converted);
* files in OUT that we did not write are never replaced (``--overwrite`` lets us write
  into a folder that is not an earlier batch, still keeping them; see output.py);
* the tree does not depend on which worker converted what: every job's options are
  resolved here (absolute paths, the ROS package environment) and travel with it.

Layout: a file ``a/b/robot.urdf`` named on the command line goes to
``OUT/robot/robot.xml``; a folder ``D`` contributes every ``*.urdf`` and
``*.urdf.xacro`` under it (not ``x.urdf.xacro`` beside ``x.urdf``: see :func:`plan`),
``D/pkg/urdf/arm.urdf`` going to ``OUT/pkg/urdf/arm/arm.xml``. Plain ``*.xacro``
files are mostly macro libraries, so a folder does not contribute them: name a
top-level ``.xacro`` file explicitly.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import click

from . import output as out
from .cli_common import QUIET, converter_keywords, converter_params
from .cli_types import BoundedInt
from .errors import ConversionError, InputError
from .runner.executors import EXECUTORS, Kind, import_ray, run_jobs

GENERATOR = "urdf2mjcf batch"
SUMMARY = "batch.json"
"""Written last into OUT: the summary and the files we wrote (what a later run replaces)."""
FOLDER_SUFFIXES = (".urdf", ".urdf.xacro")
ROS_ENV = ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH")
_STRIP = (".urdf.xacro", ".xacro", ".urdf", ".xml")


def stem(path: Path) -> str:
    """``arm.urdf.xacro`` -> ``arm``: the name of a robot's output folder and file."""
    name = path.name
    for suffix in _STRIP:
        if name.lower().endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)]
    return path.stem or name


def plan(paths: Sequence[Path]) -> tuple[list[tuple[Path, str]], list[dict[str, str]]]:
    """(source, MJCF path relative to OUT) for every robot the PATHS name, sorted by
    output, and the files of a folder left out (why); a bad PATH, or two sources with
    one output, is an :class:`InputError`.

    In a folder, ``x.urdf.xacro`` beside ``x.urdf`` is left out: the ``.urdf`` is what the
    package ships expanded (as example-robot-data does), needing no xacro arguments."""
    found: dict[str, Path] = {}
    skipped: list[dict[str, str]] = []

    def add(source: Path, rel: str) -> None:
        other = found.get(rel)
        if other is not None and other.resolve() != source.resolve():
            raise InputError(
                f"would be written to the same output '{rel}' as {other}; "
                "convert them in separate batches or rename one",
                file=source,
            )
        found[rel] = source

    for path in paths:
        if path.is_dir():
            sources = sorted(
                p
                for p in path.rglob("*")
                if p.is_file()
                and p.name.lower().endswith(FOLDER_SUFFIXES)
                and not any(part.startswith(".") for part in p.relative_to(path).parts)
            )
            if not sources:
                raise InputError(
                    f"folder holds no robot description ({' or '.join(FOLDER_SUFFIXES)} file); "
                    "name .xacro files explicitly",
                    file=path,
                )
            for src in sources:
                expanded = src.with_name(f"{stem(src)}.urdf")
                if src.name.lower().endswith(".xacro") and expanded in sources:
                    skipped.append({"source": str(src), "reason": f"{expanded.name} beside it"})
                    continue
                parent = src.relative_to(path).parent
                add(src, (parent / stem(src) / f"{stem(src)}.xml").as_posix())
        elif path.is_file():
            add(path, f"{stem(path)}/{stem(path)}.xml")
        else:
            raise InputError("does not exist", file=path)
    return sorted(((src, rel) for rel, src in found.items()), key=lambda item: item[1]), skipped


@dataclass(frozen=True)
class BatchJob:
    """One conversion, with everything it depends on resolved by the caller."""

    source: str
    """Absolute path of the URDF or xacro file (the same on every worker)."""
    output: str
    """The MJCF file, relative to OUT (POSIX)."""
    options: dict[str, Any] = field(default_factory=dict)
    """Keyword options of :func:`urdf2mjcf.api.make_options`."""
    env: dict[str, str | None] = field(default_factory=dict)
    """The ROS package variables as the caller saw them (None: unset)."""


def convert_one(job: BatchJob) -> dict[str, Any]:
    """Convert one robot; its files come back as bytes under ``"files"`` (paths relative to
    OUT). Bad input or a bug makes a failed entry, ``"error"`` saying why, never a raise."""
    from . import headless

    headless.configure()  # before mujoco is imported in this worker
    from . import api

    for key, value in job.env.items():  # the caller's package environment, not the worker's
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value
    start = time.perf_counter()
    entry: dict[str, Any] = {"source": job.source, "output": job.output}
    rel = Path(job.output)
    with tempfile.TemporaryDirectory(prefix="urdf2mjcf-batch-") as tmp:
        target = Path(tmp) / rel
        try:
            report = api.convert(job.source, target, api.make_options(**job.options))
        except Exception as exc:  # noqa: BLE001 - one robot's failure is a line of the summary
            message = " ".join(str(exc).split()).replace(str(target.parent), str(rel.parent))
            if not isinstance(exc, ConversionError):
                message = f"internal error: {type(exc).__name__}: {message}"
            return {**entry, "ok": False, "error": message, "wall_time": _since(start)}
        files = {
            (rel.parent / name).as_posix(): (target.parent / name).read_bytes()
            for name in out.list_files(target.parent)
        }
    notes = [
        f"{n.kind}: {n.element}: {n.message}"
        for n in report.notes
        if n.kind in ("warning", "repaired", "decimated")
    ]
    return {
        **entry,
        "ok": True,
        "robot": report.robot,
        "links": report.links,
        "joints": report.joints,
        "bodies": report.bodies,
        "geoms": report.geoms,
        "meshes": report.meshes,
        "notes": notes,
        "wall_time": _since(start),
        "files": files,
    }


def _since(start: float) -> float:
    return round(time.perf_counter() - start, 3)


def resolve_options(options: dict[str, Any]) -> dict[str, Any]:
    """Paths made absolute (a worker runs in another folder) and one decomposition
    process per conversion (the executor already runs one conversion per CPU)."""
    resolved = dict(options)
    for key in ("cache_dir", "actuator_config"):
        if resolved.get(key) is not None:
            resolved[key] = str(Path(resolved[key]).resolve())
    resolved["package_paths"] = [str(Path(p).resolve()) for p in options.get("package_paths", ())]
    resolved["packages"] = {
        k: str(Path(v).resolve()) for k, v in dict(options.get("packages") or {}).items()
    }
    resolved.setdefault("workers", 1)
    resolved["overwrite"] = False  # each job writes into an empty folder of its own
    return resolved


def run_batch(
    paths: Sequence[Path],
    output: Path,
    options: dict[str, Any] | None = None,
    *,
    executor: Kind = "local",
    workers: int | None = None,
    address: str | None = None,
    overwrite: bool = False,
    on_done: Callable[[int, int, dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Convert every robot PATHS name into the tree ``output``; returns the summary (also
    written as ``output/batch.json``). ``on_done(finished, total, entry)`` as each ends."""
    sources, skipped = plan(paths)
    previous = out.check_folder(output, overwrite, SUMMARY, GENERATOR)
    if executor == "ray":
        import_ray()  # a missing Ray is bad input, said before anything runs
    opts = resolve_options(options or {})
    env = {} if opts.get("use_environment") is False else {k: os.environ.get(k) for k in ROS_ENV}
    jobs = [BatchJob(str(src.resolve()), rel, opts, env) for src, rel in sources]
    start = time.perf_counter()
    with out.staged_folder(output) as stage:
        finished = 0

        def done(_: int, entry: dict[str, Any]) -> None:
            nonlocal finished
            finished += 1
            for rel, data in entry.pop("files", {}).items():
                path = stage / rel
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(data)
            if on_done:
                on_done(finished, len(jobs), entry)

        entries = run_jobs(
            convert_one, jobs, executor=executor, workers=workers, address=address, on_done=done
        )
        failed = [e for e in entries if not e["ok"]]
        summary = {
            "generator": GENERATOR,
            "robots": entries,
            "skipped": skipped,
            "converted": len(entries) - len(failed),
            "failed": len(failed),
            "executor": executor,
            "wall_time": _since(start),
            "files": [*out.list_files(stage), SUMMARY],
        }
        out.write_json(stage / SUMMARY, summary, GENERATOR)
        out.install_folder(stage, output, previous, overwrite=overwrite, last=SUMMARY)
    return summary


# -- the command -------------------------------------------------------------------------


def _progress(finished: int, total: int, entry: dict[str, Any]) -> None:
    if entry["ok"]:
        click.echo(
            f"[{finished}/{total}] ok    {entry['source']} -> {entry['output']} "
            f"({entry['wall_time']:.1f} s)",
            err=True,
        )
    else:
        click.echo(f"[{finished}/{total}] FAIL  {entry['source']}: {entry['error']}", err=True)


def _batch(
    paths: tuple[Path, ...],
    output: Path,
    executor: Kind,
    address: str | None,
    workers: int | None,
    overwrite: bool,
    quiet: bool,
    **converter: Any,
) -> None:
    """Convert many URDF and xacro files (PATHS: files, or folders searched for *.urdf and
    *.urdf.xacro) into one output tree OUT, with one summary, OUT/batch.json.

    Each robot goes to OUT/<folder>/<name>/<name>.xml (with its assets/ and scene.xml).
    Exit 0 when every robot converted, 1 when any failed (the summary says why)."""
    import sys

    if address and executor != "ray":
        raise click.UsageError("--address needs --executor ray")
    if address and workers:
        raise click.UsageError("--workers sizes a pool started here, not the cluster at --address")
    summary = run_batch(
        paths,
        output,
        converter_keywords(converter),
        executor=executor,
        workers=workers,
        address=address,
        overwrite=overwrite,
        on_done=None if quiet else _progress,
    )
    if not quiet:
        for e in summary["skipped"]:
            click.echo(f"skipped: {e['source']} ({e['reason']})")
    for e in summary["robots"]:
        if not e["ok"]:
            click.echo(f"failed: {e['source']}: {e['error']}")
    if not quiet:
        click.echo(
            f"converted {summary['converted']}/{len(summary['robots'])} robots into {output} "
            f"in {summary['wall_time']:.1f} s (summary: {output / SUMMARY})"
        )
    sys.exit(1 if summary["failed"] else 0)


def _make_command() -> click.Command:
    params: list[click.Parameter] = [
        click.Argument(
            ["paths"], nargs=-1, required=True, type=click.Path(path_type=Path), metavar="PATHS..."
        ),
        click.Option(
            ["-o", "--output"],
            required=True,
            type=click.Path(path_type=Path, file_okay=False),
            help="Output folder: one sub-folder per robot, and batch.json.",
        ),
        click.Option(
            ["--executor"],
            type=click.Choice(EXECUTORS),
            default="local",
            show_default=True,
            help="Where the conversions run: the local process pool, or Ray "
            "(pip install 'mjcf-forge[ray]').",
        ),
        click.Option(
            ["--address"],
            help="Ray cluster to run on (ray start --head prints it; 'auto': the local one); "
            "default: a Ray instance started here.",
        ),
        click.Option(
            ["--workers"],
            type=BoundedInt(1, 1024),
            help="Parallel conversions: processes of the local pool, or CPUs of a Ray instance "
            "started here (default: one per robot, at most 8).",
        ),
        click.Option(
            ["--overwrite"],
            is_flag=True,
            help="Write into a non-empty folder that is not an earlier batch "
            "(its other files are kept).",
        ),
        click.Option(list(QUIET[0]), **QUIET[1]),
        *converter_params(),  # the converter's options that apply to every robot
    ]
    return click.Command(
        "batch",
        callback=_batch,
        params=params,
        help=_batch.__doc__,
        context_settings={"help_option_names": ["-h", "--help"]},
    )


batch_command = _make_command()
