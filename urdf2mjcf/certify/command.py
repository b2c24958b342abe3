"""``urdf2mjcf verify SOURCE MODEL.xml``: the certificate of any model against any description.

Exit 0 when every figure is within its tolerance, 1 when one is not (each
failing figure on its own stderr line, then the summary), 2 on bad input (one
``error:`` line: a description or model that cannot be read, a bad name map or
tolerance, a model with no body for the description's root link).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from ..calibrate.against import AgainstTolerances
from ..cli_common import (
    configure_logging,
    converter_keywords,
    converter_option,
    converter_options,
    pairs,
    quiet_option,
)
from ..cli_types import BoundedInt, FiniteFloat
from ..errors import InputError
from ..untrusted import printable
from . import SAMPLES
from .kinematics import NameMap

GENERATOR = "urdf2mjcf verify"
"""``"generator"`` of the JSON reports this command writes (and replaces)."""

def load_name_map(path: Path) -> NameMap:
    """A YAML file ``{links: {LINK: BODY}, joints: {JOINT: MJCF_JOINT}}`` (both optional),
    read by our one YAML reader (:func:`urdf2mjcf.schema.parse`: no alias bomb, no key
    given twice, no YAML 1.1 guess)."""
    import yaml

    from ..schema import parse
    from ..untrusted import excerpt, read_file

    raw = read_file(path, "yaml", element="--name-map", what="name map")
    try:
        data, _ = parse(raw.decode("utf-8"))
    except UnicodeDecodeError:
        message = "not a YAML name map: not UTF-8 text"
        raise InputError(message, file=path, element="--name-map") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or (str(exc).strip().splitlines() or ["?"])[0]
        raise InputError(
            f"not a YAML name map: {excerpt(problem, 120)}{where}", file=path, element="--name-map"
        ) from None
    data = {} if data is None else data
    if not isinstance(data, dict) or set(data) - {"links", "joints"}:
        raise InputError(
            "a name map is a mapping with 'links' and 'joints' (each NAME: MJCF_NAME)",
            file=path,
            element="--name-map",
        )
    maps: dict[str, dict[str, str]] = {}
    for key in ("links", "joints"):
        section = data.get(key) or {}
        if not isinstance(section, dict) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in section.items()
        ):
            raise InputError(
                f"'{key}' must map names to names (NAME: MJCF_NAME)",
                file=path,
                element="--name-map",
            )
        maps[key] = section
    return NameMap(links=maps["links"], joints=maps["joints"])


def load_model(path: Path) -> Any:
    """``mujoco.MjModel`` of the MJCF file at ``path``: a stranger's model, so every file
    it names is checked before MuJoCo opens it and its size bounded before MuJoCo
    compiles it (:func:`urdf2mjcf.mjcf_input.load_model`)."""
    from ..mjcf_input import load_model as load_untrusted

    return load_untrusted(path, error=InputError, what="model")


@click.command("verify", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("source", type=click.Path(path_type=Path, dir_okay=False))
@click.argument("model", required=False, type=click.Path(path_type=Path, dir_okay=False))
@click.argument("xacro_args", nargs=-1, metavar="[NAME:=VALUE]...")
@click.option(
    "--report",
    "report_path",
    type=click.Path(path_type=Path, dir_okay=False),
    help="Also write the certificate as JSON (replaces only a report of this command).",
)
@converter_option("tolerances")
@click.option(
    "--name-map",
    type=click.Path(path_type=Path, dir_okay=False),
    help="YAML file mapping link names to body names and joint names to MJCF joint names.",
)
@click.option(
    "--samples",
    type=BoundedInt(0, 10_000),
    default=SAMPLES,
    show_default=True,
    help="Random configurations within the limits, besides home.",
)
@converter_options(("package_paths", "packages", "use_environment", "trust_xacro"))
@click.option(
    "--against",
    "against_logs",
    multiple=True,
    type=click.Path(path_type=Path),
    help="Sim against real: replay this log's commands (CSV, as calibrate reads) in the "
    "model given alone ('verify --against LOG MODEL.xml') and judge its tracking (repeatable).",
)
@click.option(
    "--q-rms",
    type=FiniteFloat(0.0, 1e6),
    default=AgainstTolerances.q_rms,
    show_default=True,
    help="--against: largest RMS position error of a joint (rad or m).",
)
@click.option(
    "--v-rms",
    type=FiniteFloat(0.0, 1e6),
    default=AgainstTolerances.v_rms,
    show_default=True,
    help="--against: largest RMS velocity error of a joint (rad/s or m/s).",
)
@click.option("-v", "--verbose", count=True, help="The certificate's table on stderr.")
@quiet_option()
def verify_command(
    source: Path,
    model: Path,
    xacro_args: tuple[str, ...],
    report_path: Path | None,
    tolerances: tuple[tuple[str, float], ...],
    name_map: Path | None,
    samples: int,
    package_paths: tuple[Path, ...],
    packages: tuple[tuple[str, str], ...],
    use_environment: bool,
    trust_xacro: bool | None,
    against_logs: tuple[Path, ...],
    q_rms: float,
    v_rms: float,
    verbose: int,
    quiet: bool,
) -> None:
    """Certify the MuJoCo MODEL against the URDF or xacro description SOURCE.

    Compares link frames (home and random configurations), joints, masses and,
    with pinocchio installed, the mass matrix and gravity torques, collision
    geometry and lint checks. Exit 0: every figure within its tolerance; 1: one
    is not (each on stderr); 2: bad input. Bodies are matched by link name.
    """
    from .. import api
    from .. import output as out
    from ..passes import xacro
    from . import certify
    from .reference import load
    from .tolerances import Tolerances

    configure_logging(verbose, quiet)
    if against_logs:
        if model is not None or xacro_args:
            raise click.UsageError(
                "with --against, give the model alone: verify --against LOG MODEL.xml"
            )
        _against(source, against_logs, AgainstTolerances(q_rms, v_rms), report_path, verbose, quiet)
        return
    if model is None:
        raise click.UsageError("Missing argument 'MODEL'.")
    tol = Tolerances().with_values(tolerances)
    names = load_name_map(name_map) if name_map else NameMap()
    if report_path:
        if report_path.resolve() in (source.resolve(), model.resolve()):
            raise click.BadParameter("is an input file", param_hint="--report")
        out.check_file(report_path, False, GENERATOR)
    options = api.make_options(
        args=pairs(xacro_args, ":=", "a xacro argument NAME:=VALUE"),
        **converter_keywords(
            {
                "package_paths": package_paths,
                "packages": packages,
                "use_environment": use_environment,
                "trust_xacro": trust_xacro,
            }
        ),
    )
    doc = xacro.run(source, options.xacro)
    ref = load(doc)
    m = load_model(model)
    try:
        certificate = certify(ref, m, tolerances=tol, names=names, samples=samples)
    except InputError as exc:  # the model is not one of this description
        raise InputError(exc.detail, file=model) from None
    if report_path:
        data = {"source": str(source), "model": str(model), "certificate": certificate.to_dict()}
        out.write_json(report_path, data, GENERATOR)
    if verbose:
        click.echo(printable(certificate.table()), err=True)
    if certificate.passed:
        if not quiet:
            click.echo(printable(certificate.summary()))
        return
    for failure in certificate.failures:
        click.echo(printable(f"failed: {failure}"), err=True)
    click.echo(printable(certificate.summary()), err=True)
    sys.exit(1)  # a figure out of tolerance (run_command passes SystemExit through)


def _against(
    model: Path,
    logs: tuple[Path, ...],
    tol: AgainstTolerances,
    report_path: Path | None,
    verbose: int,
    quiet: bool,
) -> None:
    """``verify --against LOG MODEL.xml``: exit 0 when every joint tracks the logs within
    the tolerances, 1 when one does not (each on stderr)."""
    from .. import output as out
    from ..calibrate.against import against
    from ..calibrate.fit import FitConfig
    from ..extras import require

    require("calibrate", "verify --against")
    if report_path:
        if report_path.resolve() in (model.resolve(), *(p.resolve() for p in logs)):
            raise click.BadParameter("is an input file", param_hint="--report")
        out.check_file(report_path, False, GENERATOR)
    found = against(model, logs, tol, FitConfig.window)
    if report_path:
        data = {"model": str(model), "logs": [str(p) for p in logs], "against": found.to_dict()}
        out.write_json(report_path, data, GENERATOR)
    if verbose:
        click.echo(printable(found.table()), err=True)
    failures = found.failures()
    worst = max(found.tracking.q_rms)
    summary = f"sim against real: {len(found.joints)} joints, worst RMS position error {worst:.3g}"
    if not failures:
        if not quiet:
            click.echo(printable(f"{summary}: passed"))
        return
    for failure in failures:
        click.echo(printable(f"failed: {failure}"), err=True)
    click.echo(printable(f"{summary}: failed"), err=True)
    sys.exit(1)
