"""``rover-drive``: drive the rovers of a built facility straight, then turn in place, or
run a task plan (``--plan``); both make their tasks through ``tasks.TASKS``."""

from __future__ import annotations

import contextlib
from dataclasses import asdict
from pathlib import Path
from typing import Any

import click

from ...cli_types import BoundedInt, FiniteFloat
from ...command_runner import DefaultGroup
from ...limits import SEED_MAX
from ...ros2.options import Transport, ros2_options, transport
from ..executors import Kind
from ..live_options import check_allow_origin, live_options
from ..task_kinds import STRAIGHT, TURN
from ..trial_options import trial_options
from .deliver_cli import TASKS, TaskRun, check_task_options, task_command
from .drift import PathLog, check_plot, drift_line, write_plot
from .plan_file import (
    Plan,
    check_plan,
    options_plan,
    past_bound,
    read_plan,
    run_seconds,
)
from .roles import RoverError
from .sim import SETTLE_MAX, TASK_TIMEOUT, RoverSim
from .tasks import DISTANCE_MAX, DRIVES, RATE_MAX, SPEED_MAX, TURN_MAX

PLAN_EXCLUDES = ("distance", "speed", "turn", "rate", "arm", "task")
"""The options a ``--plan`` replaces (its tasks are the file's)."""


@click.command("rover-drive", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("scene", type=click.Path(exists=True, path_type=Path))
@click.option(
    "--rover",
    "names",
    multiple=True,
    help="rover (component) to drive, repeatable; default: every rover",
)
@click.option(
    "--distance",
    type=FiniteFloat(-DISTANCE_MAX, DISTANCE_MAX),
    default=10.0,
    show_default=True,
    help=f"m to drive straight, -{DISTANCE_MAX:g} .. {DISTANCE_MAX:g} (wheel odometry; "
    "negative: backwards; 0: none)",
)
@click.option(
    "--speed",
    type=FiniteFloat(0.0, SPEED_MAX, low_open=True),
    default=STRAIGHT.default("speed"),
    show_default=True,
    help=f"m/s, above 0 and at most {SPEED_MAX:g}",
)
@click.option(
    "--turn",
    type=FiniteFloat(-TURN_MAX, TURN_MAX),
    default=0.0,
    show_default=True,
    help=f"deg to turn in place after the drive, -{TURN_MAX:g} .. {TURN_MAX:g} "
    "(positive: left; 0: none)",
)
@click.option(
    "--rate",
    type=FiniteFloat(0.0, RATE_MAX, low_open=True),
    default=TURN.default("rate_deg"),
    show_default=True,
    help=f"deg/s while turning, above 0 and at most {RATE_MAX:g}",
)
@click.option(
    "--arm/--no-arm",
    default=False,
    show_default=True,
    help="swing the shoulder pan joint +-0.4 rad while driving",
)
@click.option(
    "--plan",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="run the tasks of this YAML task plan (straight, turn, hold; an arm motion) "
    "instead of --distance/--turn/--arm (docs/mira3d.md, Task plans)",
)
@click.option(
    "--settle",
    type=FiniteFloat(0.0, SETTLE_MAX),
    default=1.0,
    show_default=True,
    help=f"s standing still before the first command, 0 .. {SETTLE_MAX:g}",
)
@click.option(
    "--report",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="write the reports as JSON",
)
@click.option(
    "--record",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="write a ROS 2 recording (.mcap): joint states, TF, every rover's IMU "
    "(pip install 'mjcf-forge[ros]')",
)
@click.option(
    "--plot",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="draw each rover's odometry against its true path (.png; the sim extra's matplotlib)",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="replace a --report, --record or --plot file we did not write",
)
@live_options("drive", "--view, --console, --foxglove or --ros2")
@ros2_options(
    "publish the drive to ROS 2 over rmw_zenoh while it runs (/clock, /joint_states, /tf, "
    "each rover's /<rover>/imu/data and /<rover>/odom), paced by --pace "
    "(pip install 'mjcf-forge[ros2]')"
)
@click.option(
    "--console",
    is_flag=True,
    help="serve a browser console (cameras, IMU, odometry, wheel and arm sliders, "
    "emergency stop) and its HTTP/JSON API on 127.0.0.1 until Ctrl-C, instead of driving",
)
@click.option(
    "--port",
    type=BoundedInt(0, 65535),
    default=0,
    show_default=True,
    help="with --console: the port (0: a free one)",
)
@click.option(
    "--task",
    type=click.Choice(TASKS),
    default=None,
    help="instead of driving: a task of the pair (deliver: the collector brings regolith to "
    "the printer, which prints a layer; recipes/mira3d-pair*.yaml)",
)
@click.option(
    "--trials",
    type=BoundedInt(1, 10_000),
    default=None,
    help="with --task: seeded trials (seeds S..S+N-1), success rate and its interval",
)
@click.option(
    "--seed",
    type=BoundedInt(0, SEED_MAX),
    default=None,
    help="with --task: the seed (the pile's grains, the collector's start); first of --trials",
)
@trial_options()
def rover_drive_command(
    scene: Path,
    names: tuple[str, ...],
    distance: float,
    speed: float,
    turn: float,
    rate: float,
    arm: bool,
    plan: Path | None,
    settle: float,
    report: Path | None,
    record: Path | None,
    plot: Path | None,
    overwrite: bool,
    view: bool,
    pace: float,
    console: bool,
    port: int,
    foxglove: int | None,
    foxglove_wait: bool,
    ros2: bool = False,
    zenoh_connect: tuple[str, ...] = (),
    zenoh_listen: tuple[str, ...] = (),
    ros_domain: int | None = None,
    allow_origins: tuple[str, ...] = (),
    task: str | None = None,
    trials: int | None = None,
    seed: int | None = None,
    workers: int | None = None,
    executor: Kind = "local",
) -> None:
    """Drive the rovers of a built facility (SCENE: its folder or scene.xml) straight, then
    turn in place; print wheel odometry against the true pose."""
    from ... import output as out
    from .console import check_console_options, serve_console

    if check_console_options(click.get_current_context(), console):
        serve_console(scene, names, settle, pace, port, allow_origins)
        return
    check_allow_origin(
        allow_origins, view or foxglove is not None, "--view, --console or --foxglove"
    )
    if plan is not None:
        _check_plan_options(click.get_current_context())
    check_task_options(click.get_current_context(), task, trials, seed)
    if task is not None:
        if ros2:
            raise click.UsageError("--ros2 publishes a drive, not a --task run")
        run = TaskRun(scene, task, trials or 0, seed, workers, executor)
        task_command(run, report, overwrite)
        return

    if foxglove_wait and foxglove is None:
        raise click.UsageError("--foxglove-wait needs --foxglove")
    if foxglove is not None:
        from ...extras import require

        require("live", "rover-drive --foxglove")
    ros = transport(ros2, zenoh_connect, zenoh_listen, ros_domain, "rover-drive --ros2")
    if report is not None:
        out.check_file(report, overwrite, "rover-drive")  # before driving, not after
    if record is not None:
        from ..record import check_recording

        check_recording(record, overwrite, "rover-drive")
        out.check_not_dangling(record, overwrite)
    if plot is not None:
        check_plot(plot, overwrite, report)
    to_run = (
        read_plan(plan) if plan is not None else _options_plan(distance, speed, turn, rate, arm)
    )
    if to_run.rovers is not None and names:
        raise click.UsageError(f"--rover does not go with a plan that names its rovers ({plan})")
    logs: list[PathLog] = []
    with contextlib.ExitStack() as files:
        # All or nothing: both files are made before driving (a folder we cannot write in
        # fails first), and renamed into place together at the end.
        report_to = files.enter_context(out.reserved_file(report)) if report else None
        record_to = files.enter_context(out.reserved_file(record)) if record else None
        plot_to = files.enter_context(out.reserved_file(plot)) if plot else None
        view_pace = pace if view else None
        results, warnings = _drive(
            scene,
            names,
            to_run,
            settle,
            record,
            record_to,
            view_pace,
            paths=logs if plot else None,
            stream=(foxglove, pace, foxglove_wait) if foxglove is not None else None,
            origins=allow_origins,
            ros=(ros, pace) if ros is not None else None,
        )
        if plot_to is not None:
            write_plot(logs[0], results, plot_to.tmp)
        if report_to is not None:
            data = {"scene": str(scene), "tasks": results, "warnings": warnings}
            report_to.write(out.json_bytes(data, "rover-drive"))
        for done in (record_to, plot_to, report_to):
            if done is not None:
                done.commit()
    if warnings:
        raise click.ClickException(f"MuJoCo warned while driving: {warnings}")


def _check_plan_options(ctx: click.Context) -> None:
    """``--plan`` with an option whose tasks it replaces: a usage error."""
    src = click.core.ParameterSource
    for name in PLAN_EXCLUDES:
        if ctx.get_parameter_source(name) not in (src.DEFAULT, None):
            raise click.UsageError(f"--{name} does not go with --plan (the plan gives the tasks)")


def _options_plan(distance: float, speed: float, turn: float, rate: float, arm: bool) -> Plan:
    """The plan of ``--distance``/``--turn``/``--arm``: drive straight, then turn in place
    (a 0 is no task), the arm swinging during both."""
    tasks: list[dict] = []
    if distance:
        tasks.append({"kind": "straight", "distance": distance, "speed": speed})
    if turn:
        tasks.append({"kind": "turn", "angle_deg": turn, "rate_deg": rate})
    return options_plan(tasks, {"kind": "arm_wave"} if arm else None, "rover-drive options")


def _drive(
    scene: Path,
    names: tuple[str, ...],
    plan: Plan,
    settle: float,
    record: Path | None,
    record_to: Any,
    pace: float | None = None,
    paths: list[PathLog] | None = None,
    stream: tuple[int, float, bool] | None = None,
    origins: tuple[str, ...] = (),
    ros: tuple[Transport, float] | None = None,
) -> tuple[list[dict], dict[str, int]]:
    """Run ``plan``'s tasks in order, print each task's summary; the results and MuJoCo's
    warnings. ``names``: the rovers (--rover) where the plan names none. The
    recording of ``record`` goes to ``record_to`` (its reserved file); with ``pace``,
    the drive is shown live at that pace (it only reads the state); ``paths`` gets a
    :class:`PathLog` of the drive; ``stream`` (port, pace, wait): the recording's
    messages are served to Foxglove while it drives; ``origins``: those the viewer and
    the stream answer besides our own page (``--allow-origin``); ``ros`` (transport,
    pace): the recording's messages and each rover's odometry published to ROS 2."""
    recorder = live = foxglove = ros2 = None
    try:
        sim = RoverSim(scene)
        for n in names:
            sim.rover(n)
        chosen = check_plan(plan, sim.rovers, names)  # the whole plan, before anything runs
        if stream is not None:
            from ..foxglove_live import FoxgloveStream

            foxglove = FoxgloveStream(
                sim.d, stream[0], pace=stream[1], name="rover-drive", origins=origins
            )
        if ros is not None:
            ros2 = _ros2_stream(sim, *ros)
        if record is not None or foxglove is not None or ros2 is not None:
            from ..record import Recorder, rover_sources

            sources = rover_sources(sim.m, sim.manifest, sim.rovers)
            to = record_to if record is not None else None
            recorder = Recorder(
                sim.m,
                sim.d,
                sources,
                to,
                generator="rover-drive",
                sinks=[s for s in (foxglove, ros2) if s is not None],
            )
            recorder.step()  # the start
            sim.on_step.append(recorder.step)
        if ros2 is not None:
            click.echo(f"publishing to ROS 2 as node /rover_drive ({ros2.where})", err=True)
            sim.on_step.append(ros2.step)
        if foxglove is not None and stream is not None:
            # Once every topic has its channel: a client sees them all when it connects.
            click.echo(f"streaming to Foxglove at {foxglove.address}", err=True)
            if stream[2]:
                click.echo("waiting for a Foxglove client to subscribe", err=True)
            foxglove.start(wait=stream[2])
            sim.on_step.append(foxglove.step)
        if pace is not None:
            from ...view.live import LiveView

            what = f"rover-drive {scene}"
            live = LiveView(sim.m, sim.d, pace=pace, what=what, origins=origins)
            sim.on_step.append(live.step)
        sim.settle(settle)
        if paths is not None:  # from where the odometry starts: the end of the settle
            paths.append(PathLog(sim, sim.rovers))
            sim.on_step.append(paths[-1].step)
        results: list[dict] = []
        start = sim.d.time
        for i, spec in enumerate(plan.tasks):
            left = run_seconds(sim.d.time - start, TASK_TIMEOUT)
            try:
                reports = DRIVES[spec["kind"]].run(sim, spec, chosen, plan.arm, timeout=left)
            except RoverError:
                if left < TASK_TIMEOUT:  # stopped by the plan's bound, not the task's
                    raise past_bound(plan, i) from None
                raise
            for r in reports.values():
                click.echo(r.summary())
                click.echo(drift_line(r.rover, r.task, r.drift))
                results.append(asdict(r))
        warnings = sim.warnings()
        if recorder is not None and record is not None:
            recorder.close()
            click.echo(f"recorded {sum(recorder.counts.values())} messages to {record}")
    except RoverError as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        if recorder is not None:
            recorder.abort()  # after close(): nothing to do; else nothing is left behind
        if live is not None:
            live.close()
        if foxglove is not None:
            foxglove.close()
        if ros2 is not None:
            ros2.close()
    return results, warnings


def _ros2_stream(sim: RoverSim, ros: Transport, pace: float) -> Any:
    """The drive's node: the recording's messages, /clock and each rover's odometry."""
    from ...ros2.live import Ros2Stream
    from ...ros2.rovers import odometry
    from ...ros2.server import ros_time
    from ...ros2.session import Endpoints

    odom: dict[str, Any] = {}

    def publish_odometry(node: Any) -> None:
        stamp = ros_time(float(sim.d.time))
        for name in sim.rovers:
            if name not in odom:
                odom[name] = node.publisher(f"/{name}/odom", "nav_msgs/msg/Odometry")
            odom[name].publish(odometry(sim, name, stamp))

    endpoints = Endpoints(listen=ros.listen, connect=ros.connect)
    return Ros2Stream(sim.d, endpoints, ros.domain, "rover_drive", publish_odometry, pace)


# -- sub-commands -----------------------------------------------------------------

_DRIVE_OUTPUTS = (
    "settle", "report", "record", "plot", "overwrite", "view", "pace", "foxglove",
    "foxglove_wait", "allow_origins", "ros2", "zenoh_connect", "zenoh_listen", "ros_domain",
)  # fmt: skip
SUBCOMMANDS: dict[str, tuple[tuple[str, ...], dict[str, Any], str]] = {
    "drive": (
        ("scene", "names", "distance", "speed", "turn", "rate", "arm", *_DRIVE_OUTPUTS),
        {},
        "Drive the rovers of a built facility (SCENE: its folder or scene.xml) straight, "
        "then turn in place; print wheel odometry against the true pose.",
    ),
    "plan": (
        ("scene", "plan", "names", *_DRIVE_OUTPUTS),
        {},
        "Run the tasks of a YAML task plan (PLAN: straight, turn, hold, an arm motion; "
        "checked whole against the bundle first) with the rovers of SCENE; print wheel "
        "odometry against the true pose.",
    ),
    "deliver": (
        ("scene", "seed", "report", "overwrite", "trials", "workers", "executor"),
        {"task": "deliver"},
        "The collector brings regolith to the printer, which prints a layer, judged from "
        "the physics (a pair built with recipes/mira3d-pair*.yaml; exit 1 when it fails); "
        "--trials: seeded trials with their success rate and Wilson interval.",
    ),
    "console": (
        ("scene", "names", "settle", "pace", "port", "allow_origins"),
        {"console": True},
        "Serve a browser console and its HTTP/JSON API on 127.0.0.1 for the rovers of "
        "SCENE (cameras, IMU, odometry, wheel and arm sliders, latched emergency stop) "
        "until Ctrl-C or SIGTERM (exit 0).",
    ),
}
"""rover-drive's sub-commands: name -> (the options of ``rover_drive_command`` it takes,
the values it sets, its help). Each takes only its own options, so none needs the old
command's option-exclusion checks."""


def _param(name: str) -> click.Parameter:
    if name == "plan":  # the plan file is the sub-command's argument
        return click.Argument(["plan"], type=click.Path(path_type=Path, dir_okay=False))
    (param,) = [p for p in rover_drive_command.params if p.name == name]
    return param


def _subcommand(name: str) -> click.Command:
    params, fixed, doc = SUBCOMMANDS[name]

    def run(**kwargs: Any) -> None:
        ctx = click.get_current_context()
        ctx.invoke(rover_drive_command, **kwargs, **fixed)

    return click.Command(
        name,
        callback=run,
        params=[_param(p) for p in params],
        help=doc,
        context_settings={"help_option_names": ["-h", "--help"]},
    )


_LEGACY = "legacy"
"""The hidden sub-command that is the spelling from before sub-commands
(``rover-drive SCENE [--plan F | --task deliver | --console] ...``), which keeps
working, with its option checks, for a release."""

rover_drive_group = DefaultGroup(
    "rover-drive",
    default=_LEGACY,
    hidden_default=True,
    commands={name: _subcommand(name) for name in SUBCOMMANDS},
    help="""Drive the MIRA3D rovers of a built world: a straight drive and a turn, a task
    plan, the deliver task, or a browser console.

    'rover-drive SCENE [options]' (without a sub-command) is the spelling from before
    sub-commands and keeps working for a release: --plan FILE is 'plan', --task deliver
    is 'deliver', --console is 'console', anything else 'drive'.""",
    context_settings={"help_option_names": ["-h", "--help"]},
)
rover_drive_group.add_command(
    click.Command(
        _LEGACY,
        callback=rover_drive_command.callback,
        params=list(rover_drive_command.params),
        help=rover_drive_command.help,
        hidden=True,
        context_settings={"help_option_names": ["-h", "--help"]},
    )
)
