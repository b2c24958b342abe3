"""Seeded trials: each rebuilds the facility with ``build_facility(..., seed=...)``
(the recipe's jitter moves the CTB within 5 cm / 15 deg and the mockups within
2 cm / 1 deg) into a temporary folder and runs the demo there, in parallel processes."""

from __future__ import annotations

import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path


def _trial(args: tuple) -> dict:
    recipe_path, root, seed, waypoints, frames = args
    from .. import headless

    headless.configure()
    from ..facility.build import build_facility
    from ..facility.recipe import load_recipe
    from .demo import run_demo

    with tempfile.TemporaryDirectory(prefix="imetro-trial-") as tmp:
        rep = build_facility(
            load_recipe(Path(recipe_path)),
            Path(tmp) / "facility",
            root=Path(root),
            seed=seed,
            components=False,
        )
        lines: list[str] = []
        res = run_demo(
            rep.output,
            waypoints,
            frames=Path(frames) / f"seed-{seed}" if frames else None,
            log=lines.append,
        )
        out = res.to_json()
        out["seed"] = seed
        out["offsets"] = rep.manifest.get("offsets")
        out["log"] = lines
        return out


def run_trials(
    recipe_path: Path,
    root: Path,
    waypoints: Path,
    seeds: list[int],
    *,
    workers: int | None = None,
    frames: Path | None = None,
) -> list[dict]:
    jobs = [
        (str(recipe_path), str(root), s, str(waypoints), str(frames) if frames else None)
        for s in seeds
    ]
    if len(jobs) == 1:
        return [_trial(jobs[0])]
    import multiprocessing as mp

    with ProcessPoolExecutor(
        max_workers=workers or min(len(jobs), 8), mp_context=mp.get_context("spawn")
    ) as pool:
        return list(pool.map(_trial, jobs))
