"""``facility-demo SCENE``: replay the logistics demo in a built facility and judge it.

Exit 0 only when the demo succeeds (every trial, with ``--trials``), 1 when it fails,
2 on bad input (checked before anything runs: the facility, its robot, the waypoints
file, where the report and pictures go)."""

from __future__ import annotations

import contextlib
import json
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ..bundle import MANIFEST
from ..cli_types import BoundedInt
from ..limits import SEED_MAX
from ..ros2.options import Transport, ros2_options, transport
from .aggregate import aggregate, check_plot, plot_outcomes, plot_path, summary_lines
from .executors import Kind, import_ray
from .live_options import check_allow_origin, live_options
from .trial_options import trial_options

if TYPE_CHECKING:
    from ..output import Reserved
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
TRIALS_MAX = 100_000
"""Most trials one run may ask for: days of work, and each one can be stopped."""
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
    help="demo file (default: the facility's own copy, demo.yaml, which make-facility "
    "bundles: recipes/demo/<recipe name>.yaml, else recipes/demo/imetro.yaml)",
)
@click.option(
    "--trials",
    type=BoundedInt(1, TRIALS_MAX),
    default=None,
    help=f"N trials (1 .. {TRIALS_MAX:,}), each on the facility rebuilt with seeded pose "
    "jitter (parallel; Ctrl-C or SIGTERM stops them)",
)
@click.option(
    "--seed",
    type=BoundedInt(0, SEED_MAX),
    default=0,
    help="first seed of the trials (seeds S..S+N-1, each 0 .. 2**32-1)",
)
@click.option(
    "--recipe",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="recipe rebuilt per trial (default: the facility's own copy, recipe.yaml)",
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
@trial_options()
@click.option(
    "--address",
    default=None,
    help="Ray cluster to run --trials on (ray start --head prints it; 'auto': the local one); "
    "default: a Ray instance started here",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="replace a --report file, or write into a --frames folder, that we did not write",
)
@live_options("run", "--view, --foxglove or --ros2", "; not with --trials")
@ros2_options(
    "publish the run to ROS 2 over rmw_zenoh while it runs (/clock and the --record "
    "topics), paced by --pace; not with --trials (pip install 'mjcf-forge[ros2]')"
)
def facility_demo_command(
    scene: Path,
    waypoints: Path | None,
    trials: int | None,
    seed: int,
    recipe: Path | None,
    report: Path | None,
    frames: Path | None,
    record: Path | None,
    workers: int | None,
    executor: Kind,
    address: str | None,
    overwrite: bool,
    view: bool,
    pace: float,
    foxglove: int | None,
    foxglove_wait: bool,
    ros2: bool = False,
    zenoh_connect: tuple[str, ...] = (),
    zenoh_listen: tuple[str, ...] = (),
    ros_domain: int | None = None,
    allow_origins: tuple[str, ...] = (),
) -> None:
    """Replay the iMETRO logistics demo in SCENE (a built facility folder or its scene.xml)."""
    from .. import headless

    headless.configure()
    from .. import output as out
    from .load import LoadError, bundled_file, load
    from .waypoints import check_names, read_waypoints

    # Everything the user gave is checked before anything runs or is written.
    if trials and seed + trials - 1 > SEED_MAX:
        raise click.BadParameter(
            f"the last trial's seed {seed + trials - 1} is over {SEED_MAX}", param_hint="'--seed'"
        )
    trials = trials or 0
    spec = read_waypoints(waypoints) if waypoints else None  # a file given: before the facility
    fac = load(scene)
    # Only the bundle: the demo it was built for (make-facility copied it in).
    if spec is None or waypoints is None:
        waypoints = bundled_file(fac.folder, fac.manifest, "demo")
        if waypoints is None:
            raise LoadError(
                "the facility was built without a demo (its recipe places no robot); "
                "give --waypoints FILE",
                file=fac.folder / MANIFEST,
                element="bundle.demo",
            )
        spec = read_waypoints(waypoints)
    check_names(spec, waypoints, fac)
    if report:
        out.check_file(report, overwrite, GENERATOR)
    if executor != "local" and not trials:
        raise click.UsageError(f"--executor {executor} runs --trials; give --trials N")
    if view and trials:
        raise click.UsageError("--view shows one run, not --trials")
    if foxglove is not None and trials:
        raise click.UsageError("--foxglove streams one run, not --trials")
    if foxglove_wait and foxglove is None:
        raise click.UsageError("--foxglove-wait needs --foxglove")
    check_allow_origin(allow_origins, view or foxglove is not None, "--view or --foxglove")
    if foxglove is not None:
        from ..extras import require

        require("live", "facility-demo --foxglove")
    if ros2 and trials:
        raise click.UsageError("--ros2 publishes one run, not --trials")
    ros = transport(ros2, zenoh_connect, zenoh_listen, ros_domain, "facility-demo --ros2")
    if address and executor != "ray":
        raise click.UsageError("--address needs --executor ray")
    if address and workers:
        raise click.UsageError("--workers sizes a pool started here, not the cluster at --address")
    if trials and report:
        check_plot(plot_path(report), report, overwrite, GENERATOR)
    if trials and executor == "ray":
        import_ray()  # a missing Ray is bad input, said before anything runs
    if record:
        if trials:
            raise click.UsageError(
                "--record records one run, not --trials: build the facility with the trial's "
                "--seed (make-facility) and record the demo there"
            )
        from .record import check_recording

        check_recording(record, overwrite, GENERATOR)
        out.check_not_dangling(record, overwrite)
    previous = out.check_folder(frames, overwrite, FRAMES_MANIFEST, GENERATOR) if frames else []
    trial_recipe = root = None
    if trials:
        from .trials import check_recipe

        trial_recipe = recipe or bundled_file(fac.folder, fac.manifest, "recipe")
        if trial_recipe is None:
            raise LoadError("names no recipe", file=fac.folder / MANIFEST, element="bundle.recipe")
        root = check_recipe(trial_recipe)  # here, not in each trial's process
    with contextlib.ExitStack() as files:
        # All or nothing: the report, plot and recording files are made now (a folder we
        # cannot write in fails before the run), written when it ends, and renamed only
        # once the pictures are in place.
        reserve = lambda path: files.enter_context(out.reserved_file(path))  # noqa: E731
        report_to = reserve(report) if report else None
        plot_to = reserve(plot_path(report)) if report and trials else None
        record_to = reserve(record) if record else None
        with _frames_folder(frames, previous, overwrite) as staged:
            if trial_recipe is not None and root is not None:
                run = TrialRun(trial_recipe, root, waypoints, workers, executor, address, scene)
                result, success = _trials(run, seed, trials, staged)
            else:
                result, success = _once(
                    fac,
                    spec,
                    staged,
                    record,
                    record_to,
                    pace if view else None,
                    _Live(foxglove, pace, foxglove_wait, allow_origins)
                    if foxglove is not None
                    else None,
                    allow_origins,
                    (ros, pace) if ros is not None else None,
                )
            if report and plot_to is not None:
                plot_outcomes(result["aggregate"], plot_to)
                result = {**result, "plot": plot_path(report).name}
            if report_to is not None:
                report_to.write(out.json_bytes(result, GENERATOR))
        for done in (record_to, plot_to, report_to):
            if done is not None:
                done.commit()
    sys.exit(0 if success else 1)


@dataclass(frozen=True)
class TrialRun:
    """What every trial of one ``--trials`` run shares, and how the command was called."""

    recipe: Path
    root: Path
    waypoints: Path
    workers: int | None
    executor: Kind
    address: str | None
    scene: Path

    def replay(self, seed: int) -> list[str]:
        """The command line that runs the trial of ``seed`` again, alone, with its pictures."""
        return [
            "facility-demo",
            str(self.scene.resolve()),
            "--trials",
            "1",
            "--seed",
            str(seed),
            "--recipe",
            str(self.recipe.resolve()),
            "--waypoints",
            str(self.waypoints.resolve()),
            "--frames",
            f"replay-seed-{seed}",
        ]


def _trial_line(r: dict) -> str:
    """One trial's outcome: seed, verdict, message, the localization errors (each
    component the robot located from its tags, against the truth) and the times."""
    where = "" if r["ok"] else f" at '{r['failed_step']}'"
    located = "".join(
        f"; {name} located {1000 * e['position_error_m']:.1f} mm, {e['yaw_error_deg']:+.3f} deg off"
        for name, e in sorted((r.get("localization") or {}).items())
    )
    return (
        f"seed {r['seed']:>4}: {'success' if r['ok'] else 'FAIL'}{where}: {r['message']}"
        f"{located}  ({r['trial_wall']:.1f} s wall, {r['sim_time']:.1f} s simulated)"
    )


def _trials(run: TrialRun, seed: int, trials: int, frames: Path | None) -> tuple[dict, bool]:
    from .trials import run_trials

    seeds = list(range(seed, seed + trials))
    finished = 0

    def progress(r: dict) -> None:  # on stderr as each trial ends, in the order they end
        nonlocal finished
        finished += 1
        click.echo(f"[{finished}/{trials}] {_trial_line(r)}", err=True)

    start = time.perf_counter()
    results = run_trials(
        run.recipe,
        run.root,
        run.waypoints,
        seeds,
        workers=run.workers,
        frames=frames,
        executor=run.executor,
        address=run.address,
        on_done=progress,
    )
    agg = aggregate(results, wall_time=time.perf_counter() - start, replay=run.replay)
    for r in results:  # in seed order, whichever worker ran what
        click.echo(_trial_line(r))
    for line in summary_lines(agg):
        click.echo(line)
    result = {
        "trials": results,
        "successes": agg["successes"],
        "success_rate": agg["success_rate"],
        "aggregate": agg,
        "executor": run.executor,
    }
    return result, agg["successes"] == len(results)


@dataclass(frozen=True)
class _Live:
    """``--foxglove PORT``, ``--pace``, ``--foxglove-wait``, ``--allow-origin``."""

    port: int
    pace: float
    wait: bool
    origins: tuple[str, ...] = ()


def _once(
    fac: Facility,
    spec: dict,
    frames: Path | None,
    record: Path | None = None,
    record_to: Reserved | None = None,
    pace: float | None = None,
    stream: _Live | None = None,
    origins: tuple[str, ...] = (),
    ros: tuple[Transport, float] | None = None,
) -> tuple[dict, bool]:
    """One run of the demo; the recording of ``record`` is written to ``record_to`` (its
    reserved file, renamed by the caller) when given; with ``pace``, the run is shown live
    at that pace (the view only reads the state; ``origins``: those its viewer answers
    besides its own page); with ``stream``, the recording's messages are served to
    Foxglove while it runs; with ``ros`` (transport, pace), published to ROS 2."""
    from .demo import Demo

    demo = Demo(fac, spec, frames=frames, log=lambda *_: None)
    recorder = foxglove = ros2 = None
    if ros is not None:
        from ..ros2.live import Ros2Stream
        from ..ros2.session import Endpoints

        try:
            endpoints = Endpoints(listen=ros[0].listen, connect=ros[0].connect)
            ros2 = Ros2Stream(fac.data, endpoints, ros[0].domain, "facility_demo", pace=ros[1])
        except BaseException:
            demo.close()
            raise
    if stream is not None:
        from .foxglove_live import FoxgloveStream

        try:
            foxglove = FoxgloveStream(
                fac.data, stream.port, pace=stream.pace, name=GENERATOR, origins=stream.origins
            )
        except BaseException:
            demo.close()
            raise
    if record or foxglove is not None or ros2 is not None:
        from .noise import SensorNoise
        from .record import Recorder, facility_sources

        # Its own noise streams (the facility's settings and seed): recording draws
        # nothing from the demo's, so a recorded run is the run without --record.
        noise = SensorNoise.from_manifest(fac.manifest, fac.manifest.seed or 0)
        recorder = Recorder(
            fac.model,
            fac.data,
            facility_sources(fac),
            (record_to or record) if record else None,
            generator=GENERATOR,
            noise=noise,
            sinks=[s for s in (foxglove, ros2) if s is not None],
        )
        recorder.step()  # the start
        demo.sim.on_step.append(recorder.step)
    if ros2 is not None:
        click.echo(f"publishing to ROS 2 as node /facility_demo ({ros2.where})", err=True)
        demo.sim.on_step.append(ros2.step)
    live = None
    try:
        if foxglove is not None and stream is not None:
            # Once every topic has its channel: a client sees them all when it connects.
            click.echo(f"streaming to Foxglove at {foxglove.address}", err=True)
            if stream.wait:
                click.echo("waiting for a Foxglove client to subscribe", err=True)
            foxglove.start(wait=stream.wait)
            demo.sim.on_step.append(foxglove.step)
        if pace is not None:
            from ..view.live import LiveView

            what = f"facility-demo {fac.folder}"
            live = LiveView(fac.model, fac.data, pace=pace, what=what, origins=origins)
            demo.sim.on_step.append(live.step)
        res = demo.run()
    except BaseException:
        if recorder is not None:
            recorder.abort()
        raise
    finally:
        demo.close()
        if live is not None:
            live.close()
        if foxglove is not None:
            foxglove.close()
        if ros2 is not None:
            ros2.close()
    if recorder is not None and record:  # a failed demo is recorded too: that is when one looks
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
