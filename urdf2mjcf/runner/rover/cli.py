"""``rover-drive``: drive the rovers of a built facility straight, then turn in place."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import click

from ...cli_types import FiniteFloat
from ...view.live import PACE_MAX
from .roles import RoverError
from .sim import SETTLE_MAX, RoverSim
from .tasks import ArmWave, Straight, Task, Turn

DISTANCE_MAX = 1_000.0
"""m: the longest drive (it must also end within ``sim.TASK_TIMEOUT``
simulated seconds, 120 s: at 0.5 m/s, about 55 m)."""
SPEED_MAX = 10.0
"""m/s: the fastest drive asked for (the wheel servos' limits cap the real speed)."""
TURN_MAX = 3_600.0
"""deg: the largest turn in place (ten turns)."""
RATE_MAX = 360.0
"""deg/s: the fastest turn asked for."""


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
    default=0.5,
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
    default=30.0,
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
    "--overwrite", is_flag=True, help="replace a --report or --record file we did not write"
)
@click.option(
    "--view",
    is_flag=True,
    help="show the drive live in MuJoCo's browser viewer (its address goes to stderr)",
)
@click.option(
    "--pace",
    type=FiniteFloat(0.0, PACE_MAX, low_open=True),
    default=1.0,
    show_default=True,
    help="with --view: simulated seconds per wall-clock second",
)
def rover_drive_command(
    scene: Path,
    names: tuple[str, ...],
    distance: float,
    speed: float,
    turn: float,
    rate: float,
    arm: bool,
    settle: float,
    report: Path | None,
    record: Path | None,
    overwrite: bool,
    view: bool,
    pace: float,
) -> None:
    """Drive the rovers of a built facility (SCENE: its folder or scene.xml) straight, then
    turn in place; print wheel odometry against the true pose."""
    from ... import output as out

    if report is not None:
        out.check_file(report, overwrite, "rover-drive")  # before driving, not after
    if record is not None:
        from ..record import check_recording

        check_recording(record, overwrite, "rover-drive")
        out.check_not_dangling(record, overwrite)
    with contextlib.ExitStack() as files:
        # All or nothing: both files are made before driving (a folder we cannot write in
        # fails first), and renamed into place together at the end.
        report_to = files.enter_context(out.reserved_file(report)) if report else None
        record_to = files.enter_context(out.reserved_file(record)) if record else None
        view_pace = pace if view else None
        results, warnings = _drive(
            scene, names, distance, speed, turn, rate, arm, settle, record, record_to, view_pace
        )
        if report_to is not None:
            data = {"scene": str(scene), "tasks": results, "warnings": warnings}
            report_to.write(out.json_bytes(data, "rover-drive"))
        for done in (record_to, report_to):
            if done is not None:
                done.commit()
    if warnings:
        raise click.ClickException(f"MuJoCo warned while driving: {warnings}")


def _drive(
    scene: Path,
    names: tuple[str, ...],
    distance: float,
    speed: float,
    turn: float,
    rate: float,
    arm: bool,
    settle: float,
    record: Path | None,
    record_to: Any,
    pace: float | None = None,
) -> tuple[list[dict], dict[str, int]]:
    """Drive, print each task's summary; the results and MuJoCo's warnings. The
    recording of ``record`` goes to ``record_to`` (its reserved file); with ``pace``,
    the drive is shown live at that pace (it only reads the state)."""
    recorder = live = None
    try:
        sim = RoverSim(scene)
        chosen = list(names) or list(sim.rovers)
        for n in chosen:
            sim.rover(n)
        if record is not None:
            from ..record import Recorder, rover_sources

            sources = rover_sources(sim.m, sim.manifest, sim.rovers)
            to = record_to.tmp
            recorder = Recorder(sim.m, sim.d, sources, to, generator="rover-drive")
            recorder.step()  # the start
            sim.on_step.append(recorder.step)
        if pace is not None:
            from ...view.live import LiveView

            live = LiveView(sim.m, sim.d, pace=pace, what=f"rover-drive {scene}")
            sim.on_step.append(live.step)
        sim.settle(settle)
        results: list[dict] = []
        plans: list[tuple[str, Callable[[], Task]]] = []
        if distance:
            plans.append(("straight", lambda: Straight(distance, speed=speed)))
        if turn:
            plans.append(("turn", lambda: Turn(math.radians(turn), rate=math.radians(rate))))
        for _, make in plans:
            waves = {n: ArmWave() for n in chosen} if arm else None
            for r in sim.run({n: make() for n in chosen}, arm=waves).values():
                click.echo(r.summary())
                results.append(asdict(r))
        warnings = sim.warnings()
        if recorder is not None:
            recorder.close()
            click.echo(f"recorded {sum(recorder.counts.values())} messages to {record}")
    except RoverError as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        if recorder is not None:
            recorder.abort()  # after close(): nothing to do; else nothing is left behind
        if live is not None:
            live.close()
    return results, warnings
