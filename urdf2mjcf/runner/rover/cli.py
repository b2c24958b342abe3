"""``rover-drive``: drive the rovers of a built facility straight, then turn in place."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import click

from .roles import RoverError
from .sim import RoverSim
from .tasks import ArmWave, Straight, Task, Turn


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
    type=float,
    default=10.0,
    show_default=True,
    help="m to drive straight (wheel odometry; negative: backwards; 0: none)",
)
@click.option("--speed", type=float, default=0.5, show_default=True, help="m/s")
@click.option(
    "--turn",
    type=float,
    default=0.0,
    show_default=True,
    help="deg to turn in place after the drive (positive: left; 0: none)",
)
@click.option("--rate", type=float, default=30.0, show_default=True, help="deg/s while turning")
@click.option(
    "--arm/--no-arm",
    default=False,
    show_default=True,
    help="swing the shoulder pan joint +-0.4 rad while driving",
)
@click.option(
    "--settle",
    type=float,
    default=1.0,
    show_default=True,
    help="s standing still before the first command",
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
) -> None:
    """Drive the rovers of a built facility (SCENE: its folder or scene.xml) straight, then
    turn in place; print wheel odometry against the true pose."""
    from ... import output as out

    if report is not None:
        out.check_file(report, overwrite, "rover-drive")  # before driving, not after
    if record is not None:
        from ..record import check_recording

        check_recording(record, overwrite, "rover-drive")
    recorder = None
    try:
        sim = RoverSim(scene)
        chosen = list(names) or list(sim.rovers)
        for n in chosen:
            sim.rover(n)
        if record is not None:
            from ..record import Recorder, rover_sources

            sources = rover_sources(sim.m, sim.manifest, sim.rovers)
            recorder = Recorder(sim.m, sim.d, sources, record, generator="rover-drive")
            recorder.step()  # the start
            sim.on_step.append(recorder.step)
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
    if report is not None:
        data = {"scene": str(scene), "tasks": results, "warnings": warnings}
        out.write_json(report, data, "rover-drive")
    if warnings:
        raise click.ClickException(f"MuJoCo warned while driving: {warnings}")
