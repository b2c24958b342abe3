"""``facility-demo SCENE``: replay the logistics demo in a built facility and judge it.

Exit 0 only when the demo succeeds (every trial, with ``--trials``), 1 when it fails,
2 on bad input (checked before anything runs: the facility, its robot, the waypoints
file, where the report and pictures go)."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

if TYPE_CHECKING:
    from .load import Facility


def _table(steps: list[dict]) -> str:
    lines = [f"{'step':<22} {'ok':<5} {'time':>7}  contacts"]
    for s in steps:
        lines.append(
            f"{s['name']:<22} {'ok' if s['ok'] else 'FAIL':<5} {s['duration']:6.2f}s  "
            f"{', '.join(s['contacts']) or '-'}"
        )
        if s["message"]:
            lines.append(f"{'':<22} {s['message']}")
    return "\n".join(lines)


GENERATOR = "facility-demo"
FRAMES_MANIFEST = "frames.json"
"""Written into --frames DIR, listing the pictures: a later run replaces only those."""


@contextmanager
def _frames_folder(
    frames: Path | None, previous: list[str], overwrite: bool
) -> Iterator[Path | None]:
    """A staging folder for the pictures, moved into ``frames`` when the run ends
    (failed demos included); on an error nothing is written."""
    from .. import output as out

    if frames is None:
        yield None
        return
    with out.staged_folder(frames) as stage:
        yield stage
        listing = {"generator": GENERATOR, "files": out.list_files(stage)}
        (stage / FRAMES_MANIFEST).write_text(json.dumps(listing, indent=2) + "\n")
        out.install_folder(stage, frames, previous, overwrite=overwrite, last=FRAMES_MANIFEST)


@click.command("facility-demo", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("scene", type=click.Path(exists=True, path_type=Path))
@click.option(
    "--waypoints",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="demo file (default: recipes/demo/imetro.yaml of the facility root)",
)
@click.option(
    "--trials",
    type=click.IntRange(min=0),
    default=0,
    help="N trials, each on the facility rebuilt with seeded pose jitter (parallel)",
)
@click.option("--seed", type=int, default=0, help="first seed of the trials (seeds S..S+N-1)")
@click.option(
    "--recipe",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="recipe rebuilt per trial (default: the one in facility.json)",
)
@click.option(
    "--report",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="write the JSON report here",
)
@click.option(
    "--frames",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="save PNGs of key moments (scene camera, wrist camera red mask)",
)
@click.option(
    "--record",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="write a ROS 2 recording (.mcap) of the run; not with --trials "
    "(pip install 'mjcf-forge[ros]')",
)
@click.option(
    "--workers", type=click.IntRange(min=1), default=None, help="parallel processes for --trials"
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="replace a --report file, or write into a --frames folder, that we did not write",
)
def facility_demo_command(
    scene: Path,
    waypoints: Path | None,
    trials: int,
    seed: int,
    recipe: Path | None,
    report: Path | None,
    frames: Path | None,
    record: Path | None,
    workers: int | None,
    overwrite: bool,
) -> None:
    """Replay the iMETRO logistics demo in SCENE (a built facility folder or its scene.xml)."""
    from .. import headless

    headless.configure()
    from .. import output as out
    from ..facility.recipe import load_recipe
    from ..facility.root import find_root
    from .load import load
    from .waypoints import check_names, read_waypoints

    # Everything the user gave is checked before anything runs or is written.
    fac = load(scene)
    root = find_root()  # a checkout here or above, else the installed data
    waypoints = waypoints or root / "recipes" / "demo" / "imetro.yaml"
    spec = read_waypoints(waypoints)
    check_names(spec, waypoints, fac)
    if report:
        out.check_file(report, overwrite, GENERATOR)
    if record:
        if trials:
            raise click.UsageError(
                "--record records one run, not --trials: build the facility with the trial's "
                "--seed (make-facility) and record the demo there"
            )
        from .record import check_recording

        check_recording(record, overwrite, GENERATOR)
    previous = out.check_folder(frames, overwrite, FRAMES_MANIFEST, GENERATOR) if frames else []
    trial_recipe = None
    if trials:
        trial_recipe = recipe or root / (fac.manifest.get("recipe_file") or "recipes/imetro.yaml")
        load_recipe(trial_recipe)  # here, not in each trial's process
    with _frames_folder(frames, previous, overwrite) as staged:
        if trial_recipe is not None:
            result, success = _trials(trial_recipe, root, waypoints, seed, trials, workers, staged)
        else:
            result, success = _once(fac, spec, staged, record)
    if report:
        out.write_json(report, result, GENERATOR)
    sys.exit(0 if success else 1)


def _trials(
    recipe: Path,
    root: Path,
    waypoints: Path,
    seed: int,
    trials: int,
    workers: int | None,
    frames: Path | None,
) -> tuple[dict, bool]:
    from .trials import run_trials

    seeds = list(range(seed, seed + trials))
    results = run_trials(recipe, root, waypoints, seeds, workers=workers, frames=frames)
    ok = sum(r["ok"] for r in results)
    for r in results:
        where = "" if r["ok"] else f" at '{r['failed_step']}'"
        click.echo(
            f"seed {r['seed']:>4}: {'success' if r['ok'] else 'FAIL'}{where}: {r['message']}"
            f"  ({r['wall_time']:.1f} s wall, {r['sim_time']:.1f} s simulated)"
        )
    click.echo(f"success rate: {ok}/{len(results)} ({100 * ok / len(results):.0f} %)")
    result = {"trials": results, "successes": ok, "success_rate": ok / len(results)}
    return result, ok == len(results)


def _once(
    fac: Facility, spec: dict, frames: Path | None, record: Path | None = None
) -> tuple[dict, bool]:
    from .demo import Demo

    demo = Demo(fac, spec, frames=frames, log=lambda *_: None)
    recorder = None
    if record:
        from .record import Recorder, facility_sources

        recorder = Recorder(fac.model, fac.data, facility_sources(fac), record, generator=GENERATOR)
        recorder.step()  # the start
        demo.ctl.on_step.append(recorder.step)
    try:
        res = demo.run()
    except BaseException:
        if recorder is not None:
            recorder.abort()
        raise
    finally:
        demo.close()
    if recorder is not None:  # a failed demo is recorded too: that is when one looks
        recorder.close()
        click.echo(f"recorded {sum(recorder.counts.values())} messages to {record}")
    result = res.to_json()
    click.echo(_table(result["steps"]))
    click.echo(
        f"{'SUCCESS' if res.ok else 'FAILED'}: {res.message}"
        f"  ({res.sim_time:.1f} s simulated in {res.wall_time:.1f} s wall, "
        f"real-time factor {res.sim_time / max(res.wall_time, 1e-9):.1f})"
    )
    return result, res.ok


def main() -> None:  # pragma: no cover
    facility_demo_command()


if __name__ == "__main__":  # pragma: no cover
    main()
