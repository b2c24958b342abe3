"""Seeded trials: each rebuilds the facility with ``build_facility(..., seed=...)``
(the recipe's jitter moves the CTB within 5 cm / 15 deg and the mockups within
2 cm / 2 deg, found by their tags) into a temporary folder of its worker and runs the demo there.

Trials run on an executor (:mod:`.executors`: the local process pool or a Ray
cluster), one job per seed. A trial depends only on its seed and its inputs,
never on the worker that ran it: it builds into a folder of its own (a worker builds
the attached components once per run and moves them per seed, ``facility.build.Parts``:
the same bytes as a fresh build), the caches
it shares with other workers are written atomically (``urdf2mjcf.cache``), and
its pictures come back as bytes for the caller to write, so a worker on another
machine needs no shared folder for its output.

Trials sit above both the builder (``urdf2mjcf.facility``) and the runtime: they are the
one part of the runner that rebuilds facilities, so the one that needs the facility
data (a checkout, or the data installed with the package: ``facility.root.find_root``).
The recipe they rebuild is the bundle's own copy (``recipe.yaml``) unless one is given."""

from __future__ import annotations

import os
import tempfile
import time
import traceback
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..bundle_manifest import thaw
from .executors import Kind, removed_on_stop, run_jobs


@dataclass(frozen=True)
class TrialJob:
    """One trial: paths as strings, the same on every worker (see docs/scale.md)."""

    recipe: str
    root: str
    waypoints: str
    seed: int
    frames: bool
    """Whether to save the demo's pictures (returned as bytes under ``"frames"``)."""
    run: str = ""
    """The run the trial is one of (:func:`run_trials` gives each run its own): a worker
    keeps the parts it built for the other trials of its run (their files are the same),
    never for another run's."""


_PARTS: dict[tuple[str, str, str], Any] = {}
"""(run, recipe, root) -> the attached components this worker built for that run's
trials (``urdf2mjcf.facility.build.Parts``): each seed moves them, none changes them."""


def check_recipe(path: Path) -> Path:
    """The facility root the trials rebuild ``path`` from, after checking the recipe and
    that the files it names are there: an InputError naming the recipe (and the key)
    before any trial starts, not one failed trial per seed. A bundle's copy names its
    recipe's own files (beside the original) by the same relative paths: those are not
    in the bundle, so such a recipe must be given again (``--recipe``)."""
    from ..errors import InputError
    from ..facility.recipe import load_recipe
    from ..facility.root import data_path, find_root

    root = find_root()  # a checkout at or above the current folder, else the installed data
    recipe = load_recipe(Path(path), root=root)
    named = [("xacro", recipe.xacro), ("actuator_config", recipe.actuator_config)]
    for name, comp in recipe.components.items():
        if recipe.places(name):
            named += [(f"components.{name}.roles", comp.roles)]
            named += [(f"components.{name}.mechanisms", comp.mechanisms)]
    for key, rel in named:
        if rel is not None and not data_path(root, recipe.path, rel).is_file():
            raise InputError(
                f"'{rel}' is neither beside the recipe nor under the facility root {root} "
                "(a recipe's own files are not in a bundle: give --recipe the original)",
                file=path,
                element=key,
            )
    return root


def run_trial(job: TrialJob) -> dict:
    """The demo's result (``DemoResult.to_json()``) for one seed, with ``seed``, the jitter
    ``offsets``, the demo's ``log``, ``trial_wall`` (build and demo, seconds) and
    ``frames`` ({file name: PNG bytes}). A trial that raises is a failed trial, at step
    ``"error"``, not the end of the others."""
    from .. import headless

    headless.configure()  # before mujoco is imported in this worker
    from .. import output as out
    from ..facility.build import build_facility
    from ..facility.recipe import load_recipe
    from .demo import run_demo

    start = time.perf_counter()
    lines: list[str] = []
    with (
        tempfile.TemporaryDirectory(prefix="imetro-trial-") as tmp,
        removed_on_stop(Path(tmp)),  # a worker stopped mid-trial leaves no folder behind
    ):
        frames = Path(tmp) / "frames" if job.frames else None
        offsets = None
        try:
            rep = build_facility(
                load_recipe(Path(job.recipe), root=Path(job.root)),
                Path(tmp) / "facility",
                root=Path(job.root),
                seed=job.seed,
                components=False,
                workers=1,  # one CPU per trial: the executor runs the trials side by side
                parts=_parts(job),
            )
            offsets = thaw(rep.written.offsets) if rep.written is not None else None
            res = run_demo(rep.output, job.waypoints, frames=frames, log=lines.append)
            result = res.to_json()
        except Exception as exc:  # a crash fails this seed, reported with the others
            lines.extend(traceback.format_exc().splitlines())
            result = {
                "ok": False,
                "steps": [],
                "verdict": None,
                "sim_time": 0.0,
                "wall_time": time.perf_counter() - start,
                "failed_step": "error",
                "message": f"{type(exc).__name__}: {exc}",
                "handle": None,
                "real_time_factor": None,
            }
        pictures = (
            {rel: (frames / rel).read_bytes() for rel in out.list_files(frames)}
            if frames is not None and frames.is_dir()
            else {}
        )
    result["seed"] = job.seed
    result["offsets"] = offsets
    result["log"] = lines
    result["trial_wall"] = time.perf_counter() - start
    result["frames"] = pictures
    return result


def _parts(job: TrialJob) -> Any:
    """This worker's parts for ``job``'s run (only the latest run's are kept)."""
    from ..facility.build import Parts

    key = (job.run, job.recipe, job.root)
    if key not in _PARTS:
        _PARTS.clear()
        _PARTS[key] = Parts()
    return _PARTS[key]


def run_trials(
    recipe_path: Path,
    root: Path,
    waypoints: Path,
    seeds: list[int],
    *,
    workers: int | None = None,
    frames: Path | None = None,
    executor: Kind = "local",
    address: str | None = None,
    on_done: Callable[[dict], None] | None = None,
) -> list[dict]:
    """One trial per seed on ``executor``; results in the order of ``seeds``.

    With ``frames``, each trial's pictures are written to ``frames/seed-S/`` here, as
    the trial ends. ``on_done(result)`` is called as each trial ends (progress)."""
    run = uuid.uuid4().hex  # this run's trials share parts, no other run's do
    if executor == "local" and workers is None:
        workers = min(len(seeds), os.cpu_count() or 1, 8)  # one per CPU: parts reused
    jobs = [
        TrialJob(
            str(Path(recipe_path).resolve()),
            str(Path(root).resolve()),
            str(Path(waypoints).resolve()),
            s,
            frames is not None,
            run,
        )
        for s in seeds
    ]

    def done(_: int, result: dict) -> None:
        pictures = result.pop("frames", {})
        if frames is not None:
            for rel, data in sorted(pictures.items()):
                path = frames / f"seed-{result['seed']}" / rel
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(data)
        if on_done:
            on_done(result)

    return run_jobs(
        run_trial, jobs, executor=executor, workers=workers, address=address, on_done=done
    )
