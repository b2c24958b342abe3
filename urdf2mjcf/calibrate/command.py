"""``urdf2mjcf calibrate MODEL.xml LOG... -o OUT/``: fit a converted model to the robot's logs.

Exit 0 with ``OUT/robot.xml``, ``calibration.yaml``, ``report.json`` and ``report.html``
written; 2 on bad input (one ``error:`` line naming the file and element; nothing written).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import click

from ..cli_common import configure_logging, quiet_option
from ..cli_types import FiniteFloat
from ..errors import InputError
from . import params
from .excite import CONTROLLER, ExciteConfig
from .fit import FitConfig
from .report import improvement
from .run import GENERATOR, CalibrateConfig, calibrate


@click.command("calibrate", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("model", type=click.Path(path_type=Path, dir_okay=False))
@click.argument("logs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path, file_okay=False),
    help="Folder to write robot.xml, calibration.yaml, report.json and report.html into.",
)
@click.option(
    "--free",
    default=",".join(params.DEFAULT_FREE),
    show_default=True,
    help=f"Parameters fitted, for every joint, actuator or body: any of {','.join(params.KINDS)}.",
)
@click.option(
    "--params",
    "params_file",
    type=click.Path(path_type=Path, dir_okay=False),
    help="YAML file freeing, fixing or bounding single parameters (see docs/calibrate.md).",
)
@click.option(
    "--holdout",
    multiple=True,
    type=click.Path(path_type=Path),
    help="A whole log kept out of the fit to judge it (repeatable); default: the last "
    "--holdout-fraction of each log.",
)
@click.option(
    "--holdout-fraction",
    type=FiniteFloat(0.05, 0.9),
    default=0.2,
    show_default=True,
    help="The part of each log held out when no --holdout is given.",
)
@click.option(
    "--window",
    type=FiniteFloat(0.01, 60.0),
    default=FitConfig.window,
    show_default=True,
    help="Seconds of each open-loop replay from a measured state.",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Write into a non-empty folder that no earlier calibrate wrote.",
)
@click.option("-v", "--verbose", count=True, help="More detail on stderr.")
@quiet_option()
def calibrate_command(
    model: Path,
    logs: tuple[Path, ...],
    output: Path,
    free: str,
    params_file: Path | None,
    holdout: tuple[Path, ...],
    holdout_fraction: float,
    window: float,
    overwrite: bool,
    verbose: int,
    quiet: bool,
) -> None:
    """Fit MODEL.xml's joint damping, friction, armature, servo gains, masses, payload or
    sensor delay to LOG... (CSV: t, q.<joint>, v.<joint>, u.<actuator>) by replaying the
    logged commands in MuJoCo. See docs/calibrate.md."""
    from ..output import check_folder, install_folder, staged_folder

    configure_logging(verbose, quiet)
    kinds = tuple(k.strip() for k in free.split(",") if k.strip())
    bad = [k for k in kinds if k not in params.KINDS]
    if bad:
        unknown = ", ".join(repr(b) for b in bad)
        raise InputError(f"--free: unknown {unknown}; choose from {', '.join(params.KINDS)}")
    previous = check_folder(output, overwrite, "report.json", GENERATOR)
    cfg = CalibrateConfig(
        free=kinds,
        params_file=params_file,
        holdout=holdout,
        holdout_fraction=holdout_fraction,
        fit=FitConfig(window=window),
    )
    done = calibrate(model, logs, output, cfg)
    with staged_folder(output) as stage:
        for name, data in done.files.items():
            (stage / name).write_bytes(data)
        install_folder(stage, output, previous, overwrite=overwrite, last="report.json")
    if not quiet:
        s = done.summary
        times = improvement(s.before_held, s.after_held)
        click.echo(
            f"calibrated {len(s.fit.params)} parameters in {s.seconds:.1f} s; held-out RMS "
            f"position error {times}x smaller -> {output}"
        )


@click.command("excite", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("model", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path, dir_okay=False),
    help="The CSV to write (t, u.<actuator>...).",
)
@click.option(
    "--duration",
    type=FiniteFloat(1.0, 3600.0),
    default=ExciteConfig.duration,
    show_default=True,
    help="Seconds.",
)
@click.option(
    "--amplitude",
    type=FiniteFloat(0.0, 10.0),
    default=ExciteConfig.amplitude,
    show_default=True,
    help="Largest amplitude about each joint's centre (rad or m).",
)
@click.option(
    "--max-velocity",
    type=FiniteFloat(0.0, 100.0),
    default=ExciteConfig.max_velocity,
    show_default=True,
    help="Largest setpoint speed (rad/s or m/s).",
)
@click.option(
    "--bag",
    type=click.Path(path_type=Path),
    help="Also write the setpoints as a rosbag2 folder (MCAP) holding one "
    "trajectory_msgs/JointTrajectory on /<controller>/joint_trajectory, for 'ros2 bag play'.",
)
@click.option(
    "--controller",
    default=CONTROLLER,
    show_default=True,
    help="The joint trajectory controller the bag's topic is for.",
)
@click.option("--overwrite", is_flag=True, help="Replace an existing output file (or bag).")
@quiet_option()
def excite_command(
    model: Path,
    output: Path,
    duration: float,
    amplitude: float,
    max_velocity: float,
    bag: Path | None,
    controller: str,
    overwrite: bool,
    quiet: bool,
) -> None:
    """Write a multi-sine of position setpoints for MODEL.xml's servos, within 80 % of each
    joint's range, under --max-velocity and 90 % of each servo's force range in the model's
    replay, its bodies clear of each other at the sampled configurations: run it on the
    robot (or play --bag to its trajectory controller) and log it for 'urdf2mjcf calibrate'."""
    from ..errors import OutputError
    from ..mjcf_input import load_model
    from .excite import csv_text, excite

    configure_logging(0, quiet)
    if os.path.lexists(output) and not overwrite:
        raise OutputError("already exists; pass --overwrite to replace it", file=output)
    if bag is not None:
        _check_bag_target(bag, overwrite)
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*", controller):
            raise click.BadParameter("not a ROS 2 name", param_hint="--controller")
    m = load_model(model)
    try:
        e = excite(
            m, ExciteConfig(duration=duration, amplitude=amplitude, max_velocity=max_velocity)
        )
    except InputError as exc:  # the model cannot be excited as asked: name it
        raise InputError(exc.detail, file=model) from None
    if bag is not None:
        _write_bag(e, m, bag, controller)
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = output.with_name(f".{output.name}.tmp")
    tmp.write_text(csv_text(e))
    os.replace(tmp, output)
    if not quiet:
        click.echo(
            f"{len(e.t)} setpoints over {duration:g} s, amplitude {e.amplitude:.3g}, "
            f"peak servo force {e.peak_force.max():.0%} of its range -> {output}"
            + (f" and {bag} (/{controller}/joint_trajectory)" if bag is not None else "")
        )


BAG_FILES = re.compile(r"metadata\.yaml|[^/]*\.(mcap|db3)")
"""What a rosbag2 folder we write holds: only such a folder is replaced (--overwrite)."""


def _check_bag_target(bag: Path, overwrite: bool) -> None:
    from ..errors import OutputError

    if not os.path.lexists(bag):
        return
    if not overwrite:
        raise OutputError("already exists; pass --overwrite to replace it", file=bag)
    if bag.is_symlink() or not bag.is_dir():
        raise OutputError("is not a rosbag2 folder; not replaced", file=bag)
    names = [p.name for p in bag.iterdir()]
    if "metadata.yaml" not in names or not all(BAG_FILES.fullmatch(n) for n in names):
        raise OutputError(
            "holds files a rosbag2 folder does not (not replaced: remove it yourself)", file=bag
        )


def _write_bag(e: Any, m: Any, bag: Path, controller: str) -> None:
    """The bag written beside ``bag`` and moved into place (the old one, ours, removed)."""
    import shutil
    import tempfile

    from .excite import bag as write

    bag.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f".{bag.name}.", dir=bag.parent) as tmp:
        staged = Path(tmp) / bag.name
        write(e, m, staged, controller)
        if os.path.lexists(bag):
            shutil.rmtree(bag)
        os.replace(staged, bag)
