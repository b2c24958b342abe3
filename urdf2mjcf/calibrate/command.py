"""``urdf2mjcf calibrate MODEL.xml LOG... -o OUT/``: fit a converted model to the robot's logs.

Exit 0 with ``OUT/robot.xml``, ``calibration.yaml``, ``report.json`` and ``report.html``
written; 2 on bad input (one ``error:`` line naming the file and element; nothing written).
"""

from __future__ import annotations

from pathlib import Path

import click

from ..cli_common import configure_logging, quiet_option
from ..cli_types import FiniteFloat
from ..errors import InputError
from . import params
from .excite import ExciteConfig
from .fit import FitConfig
from .report import improvement
from .run import GENERATOR, CalibrateConfig, calibrate


@click.command("urdf2mjcf calibrate", context_settings={"help_option_names": ["-h", "--help"]})
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


@click.command("urdf2mjcf excite", context_settings={"help_option_names": ["-h", "--help"]})
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
@click.option("--overwrite", is_flag=True, help="Replace an existing output file.")
@quiet_option()
def excite_command(
    model: Path,
    output: Path,
    duration: float,
    amplitude: float,
    max_velocity: float,
    overwrite: bool,
    quiet: bool,
) -> None:
    """Write a multi-sine of position setpoints for MODEL.xml's servos, within 80 % of each
    joint's range, under --max-velocity and 90 % of each servo's force range in the model's
    replay: run it on the robot and log it for 'urdf2mjcf calibrate'."""
    import os

    from ..errors import OutputError
    from ..mjcf_input import load_model
    from .excite import csv_text, excite

    configure_logging(0, quiet)
    if os.path.lexists(output) and not overwrite:
        raise OutputError("already exists; pass --overwrite to replace it", file=output)
    m = load_model(model)
    e = excite(m, ExciteConfig(duration=duration, amplitude=amplitude, max_velocity=max_velocity))
    output.parent.mkdir(parents=True, exist_ok=True)
    tmp = output.with_name(f".{output.name}.tmp")
    tmp.write_text(csv_text(e))
    os.replace(tmp, output)
    if not quiet:
        click.echo(
            f"{len(e.t)} setpoints over {duration:g} s, amplitude {e.amplitude:.3g}, "
            f"peak servo force {e.peak_force.max():.0%} of its range -> {output}"
        )
