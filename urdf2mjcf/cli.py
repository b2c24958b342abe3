"""Command line: builds options, calls the library, reports. Nothing else."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from . import extras, headless
from .cli_common import (
    configure_logging,
    converter_keywords,
    converter_option,
    converter_options,
    converter_params,
    pairs,
    quiet_option,
)
from .cli_types import BoundedInt
from .command_runner import DefaultGroup, run_command
from .errors import ConversionError
from .ir import Note
from .runner.live_options import allow_origin_option, allow_origin_param, check_allow_origin
from .untrusted import printable

if TYPE_CHECKING:
    from .certify import Certificate


class _Progress:
    """A click progress bar that appears only when there is long work."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.bar: Any = None

    def __call__(self, done: int, total: int, label: str) -> None:
        if not self.enabled:
            return
        if self.bar is None:
            self.bar = click.progressbar(
                length=total, label="decomposing collision meshes", file=sys.stderr
            )
            self.bar.__enter__()
        self.bar.update(done - self.bar.pos)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None

    def __enter__(self) -> _Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _echo_notes(notes: Iterable[Note], verbose: int) -> None:
    """Warnings, repairs and decimations always; everything else with -v."""
    for note in notes:
        if note.kind in ("warning", "repaired", "decimated") or verbose:
            # a note may quote a file or a cache entry: no escape codes reach the terminal
            line = printable(f"{note.kind}: {note.element}: {note.message}")
            click.echo(line, err=True)


@click.command("convert", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("source", type=click.Path(path_type=Path, dir_okay=False))
@click.argument("xacro_args", nargs=-1, metavar="[NAME:=VALUE]...")
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path, dir_okay=False),
    help="MJCF file to write; meshes go to assets/ beside it.",
)
@converter_options()  # every option of the converter that has a flag, in order
@click.option(
    "--report",
    "report_path",
    type=click.Path(path_type=Path, dir_okay=False),
    help="Also write the conversion report as JSON.",
)
@click.option("-v", "--verbose", count=True, help="More detail (-vv for debug).")
@quiet_option()
def urdf2mjcf_command(
    source: Path,
    xacro_args: tuple[str, ...],
    output: Path,
    report_path: Path | None,
    verbose: int,
    quiet: bool,
    **converter: Any,
) -> None:
    """Convert a URDF or xacro robot description SOURCE into MuJoCo MJCF.

    xacro arguments are given as NAME:=VALUE, exactly as with ROS.

    'urdf2mjcf SOURCE ...' (without 'convert') does the same. The other sub-commands
    ('urdf2mjcf --help' lists them): batch, verify, view, cache, serve, excite,
    calibrate.
    """
    from . import api  # keep `--help` fast
    from . import output as out
    from .certify import CertificateFailed

    overwrite = converter["overwrite"]
    configure_logging(verbose, quiet)
    if report_path:
        if report_path.resolve() == Path(output).resolve():
            raise click.BadParameter("is the MJCF output file", param_hint="--report")
        out.check_file(report_path, overwrite, "urdf2mjcf")  # before the work, not after
    # All or nothing: the report's file is made before the work (a folder we cannot write
    # in fails here), the MJCF files are installed only once the report is written, and
    # undone if its rename fails.
    slot = out.reserved_file(report_path) if report_path else contextlib.nullcontext(None)
    with (
        _Progress(enabled=not quiet and sys.stderr.isatty()) as progress,
        slot as reserved,
        out.together() as batch,
    ):
        options = api.make_options(
            args=pairs(xacro_args, ":=", "a xacro argument NAME:=VALUE"),
            progress=progress,
            **converter_keywords(converter),
        )
        try:
            report = api.convert(source, output, options)
        except CertificateFailed as exc:  # --verify: the input was fine, the result is not
            _echo_certificate_failures(exc.certificate, verbose)
            sys.exit(1)  # as batch does: run_command passes SystemExit through
        if reserved is not None:
            reserved.write(out.json_bytes(report.to_dict(), "urdf2mjcf"))
            batch.last(reserved.commit)
    if not quiet:
        _echo_notes(report.notes, verbose)
        click.echo(f"wrote {output}")
        click.echo(report.summary())
        if report.certificate is not None:
            if verbose:
                click.echo(printable(report.certificate.table()), err=True)
            click.echo(printable(report.certificate.summary()))


def _echo_certificate_failures(certificate: Certificate, verbose: int) -> None:
    """Each failing figure on its own stderr line, then the one-line summary."""
    if verbose:
        click.echo(printable(certificate.table()), err=True)
    for failure in certificate.failures:
        click.echo(printable(f"failed: {failure}"), err=True)
    click.echo(printable(f"{certificate.summary()}; nothing written"), err=True)


def _view(
    source: Path,
    xacro_args: tuple[str, ...],
    port: int,
    no_browser: bool,
    desktop: bool,
    allow_origins: tuple[str, ...] = (),
    **kw: Any,
) -> None:
    """Convert SOURCE and show it in MuJoCo's browser viewer; convert again, and show the
    new model, whenever the description or a file it pulled in changes.

    xacro arguments are given as NAME:=VALUE. Runs until Ctrl-C or SIGTERM (exit 0); a
    conversion that fails on the way prints its error: line and the viewer keeps the
    last good model. See docs/viewing.md."""
    from . import api
    from .cache import default_cache_dir
    from .view.watch import serve

    if allow_origins and desktop:
        raise click.UsageError("--allow-origin is for the browser viewer, not --desktop")
    configure_logging(0, False)
    options = api.make_options(
        args=pairs(xacro_args, ":=", "a xacro argument NAME:=VALUE"), **converter_keywords(kw)
    )

    def describe(report: Any) -> list[str]:
        _echo_notes(report.notes, 0)
        lines = [f"converted {report.summary()}"]
        if report.certificate is not None:
            lines.append(report.certificate.summary())
        return lines

    try:
        cache = kw["cache_dir"] or default_cache_dir()
    except RuntimeError:  # no home folder: nothing cached to leave out of the watch
        cache = None
    serve(
        source,
        lambda out: api.convert(source, out, options),
        describe,
        scene=kw["scene"],
        port=port,
        browser=not no_browser,
        desktop=desktop,
        cache=cache,
        origins=allow_origins,
    )


view_command = click.Command(
    "view",
    callback=_view,
    params=[
        click.Argument(["source"], type=click.Path(path_type=Path, dir_okay=False)),
        click.Argument(["xacro_args"], nargs=-1, metavar="[NAME:=VALUE]..."),
        click.Option(
            ["--port"],
            type=BoundedInt(0, 65535),
            default=0,
            help="Port of the browser viewer (0: the first free one from 8080 up).",
        ),
        click.Option(
            ["--no-browser"], is_flag=True, help="Do not open a browser (the address is printed)."
        ),
        click.Option(
            ["--desktop"],
            is_flag=True,
            help="MuJoCo's desktop viewer instead of the browser one (needs a display).",
        ),
        allow_origin_param("the browser viewer"),
        *converter_params(),  # the converter's options, as 'urdf2mjcf' and 'batch' take them
    ],
    help=_view.__doc__,
    context_settings={"help_option_names": ["-h", "--help"]},
)


COMMANDS: dict[str, tuple[str, str, str | None]] = {
    "convert": ("urdf2mjcf.cli", "urdf2mjcf_command", None),
    "batch": ("urdf2mjcf.batch", "batch_command", None),
    "verify": ("urdf2mjcf.certify.command", "verify_command", None),
    "view": ("urdf2mjcf.cli", "view_command", None),
    "cache": ("urdf2mjcf.cli", "cache_group", None),
    "serve": ("urdf2mjcf.ros2.command", "serve_command", None),
    "excite": ("urdf2mjcf.calibrate.command", "excite_command", None),
    "calibrate": ("urdf2mjcf.calibrate.command", "calibrate_command", "calibrate"),
}
"""``urdf2mjcf``'s sub-commands: name -> (module, command, the extra it needs). Each is
imported when it runs, so that ``--help`` and a conversion import none of the others."""


class _Commands(DefaultGroup):
    """The sub-commands of :data:`COMMANDS`. A first argument that names none is a
    conversion's: ``urdf2mjcf SOURCE ...`` is ``urdf2mjcf convert SOURCE ...``, the
    spelling from before sub-commands, which keeps working (a SOURCE file named like a
    sub-command is given as ``./NAME``)."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        import importlib

        from .command_runner import with_debug_option

        module, name, extra = COMMANDS[cmd_name]
        command = getattr(importlib.import_module(module), name)
        if extra is not None:
            command = extras.requiring(extra, command)
        return with_debug_option(command)


urdf2mjcf_group = _Commands(
    "urdf2mjcf",
    default="convert",
    help="""Convert robot descriptions into MuJoCo MJCF, check, show, serve and calibrate
    the result.

    'urdf2mjcf SOURCE [NAME:=VALUE]... -o OUT.xml' is short for 'urdf2mjcf convert ...'
    (the spelling from before sub-commands; it keeps working). Each sub-command's --help
    says what it takes.""",
    context_settings={"help_option_names": ["-h", "--help"]},
)


def urdf2mjcf_main() -> None:
    run_command(urdf2mjcf_group)


_CACHE_DIR_OPTION = converter_option("cache_dir")


def _cache_root(cache_dir: Path | None) -> Path:
    from .cache import default_cache_dir

    if cache_dir is not None:
        return cache_dir
    try:
        return default_cache_dir()
    except RuntimeError as exc:  # no home directory
        raise click.UsageError(
            f"no default cache folder ({exc}); name one with --cache-dir"
        ) from None


def _mb(n: int) -> str:
    return f"{n / 2**20:.1f} MB"


@click.group("cache", context_settings={"help_option_names": ["-h", "--help"]})
def cache_group() -> None:
    """Show or empty the cache of loaded meshes and convex decompositions.

    Conversions share one cache folder; entries are named by the content they
    depend on, so they never go stale. It is held to $URDF2MJCF_CACHE_MAX_MB
    (default 2048; 0 for no bound), least recently used entries going first.
    """


@cache_group.command("info")
@_CACHE_DIR_OPTION
def cache_info_command(cache_dir: Path | None) -> None:
    """Where the cache is, its entries and their size by kind."""
    from . import cache

    info = cache.info(_cache_root(cache_dir))
    where = printable(str(info.root))
    click.echo(f"cache: {where}" + ("" if info.root.is_dir() else " (not created yet)"))
    if info.root.is_dir() and not info.ours:
        click.echo(
            f"  not a cache of ours: no {cache.TAG_NAME} of urdf2mjcf "
            "('cache clear' refuses it; conversions never evict from it)"
        )
    for k in info.kinds:
        click.echo(f"  {k.description} ({k.kind}/): {k.entries} entries, {_mb(k.bytes)}")
    limit = "none" if info.limit is None else _mb(info.limit)
    click.echo(f"total: {info.entries} entries, {_mb(info.bytes)} (limit {limit})")


@cache_group.command("clear")
@_CACHE_DIR_OPTION
def cache_clear_command(cache_dir: Path | None) -> None:
    """Delete every cache entry (files in the folder that are not entries stay).

    Only a folder marked with our CACHEDIR.TAG is cleared, and only files named as
    we name entries; symlinks are never followed."""
    from . import cache

    root = _cache_root(cache_dir)
    count, size = cache.clear(root)
    click.echo(f"removed {count} entries, {_mb(size)}, from {printable(str(root))}")


DEFAULT_RECIPE = "recipes/imetro.yaml"
"""The recipe make-facility builds when none is named (relative to the facility root)."""


@click.command("make-facility", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("recipe", required=False, type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path, file_okay=False),
    help="Output folder (default: build/<recipe name> in the checkout, else here).",
)
@click.option(
    "--set",
    "sets",
    multiple=True,
    metavar="KEY=VALUE",
    help="Change the recipe: a flag (hatch_4040=true) or a dotted field (jitter.ctb.yaw=0.2).",
)
@click.option(
    "--seed",
    type=BoundedInt(0, 2**32 - 1),
    help="Seed for the recipe's pose uncertainty and its rocks, 0 .. 2**32-1 "
    "(none: nominal poses).",
)
@click.option(
    "--root",
    type=click.Path(path_type=Path, file_okay=False),
    help="Facility root (holds facility/ and recipes/); default: a checkout at or above the "
    "current folder, else the data installed with the package.",
)
@click.option("--no-components", is_flag=True, help="Do not also compile each asset on its own.")
@click.option(
    "--overwrite",
    is_flag=True,
    help="Build into a non-empty folder that is not an earlier build (its other files are kept).",
)
@converter_options(("workers", "cache_dir"))
@click.option(
    "--demo", is_flag=True, help="Then replay the logistics demo in it (see facility-demo)."
)
@click.option(
    "--view",
    is_flag=True,
    help="Then show it in MuJoCo's browser viewer until Ctrl-C (with --demo: the demo's "
    "run, live).",
)
@allow_origin_option("--view")
@click.option("-v", "--verbose", count=True, help="More detail (-vv for debug).")
@quiet_option()
@click.pass_context
def make_facility_command(
    ctx: click.Context,
    recipe: Path | None,
    output: Path | None,
    sets: tuple[str, ...],
    seed: int | None,
    root: Path | None,
    no_components: bool,
    overwrite: bool,
    workers: int,
    cache_dir: Path | None,
    demo: bool,
    view: bool,
    allow_origins: tuple[str, ...],
    verbose: int,
    quiet: bool,
) -> None:
    """Build a simulated facility from a RECIPE (default: recipes/imetro.yaml).

    Writes scene.xml (the whole facility), components/, assets/ and facility.json.
    """
    from .facility import build as facility_build
    from .facility import root as facility_root
    from .facility.recipe import load_recipe

    check_allow_origin(allow_origins, view, "--view")
    configure_logging(verbose, quiet)
    with _Progress(enabled=not quiet and sys.stderr.isatty()) as progress:
        root = facility_root.find_root(root)
        recipe_path = facility_root.recipe_file(root, recipe, DEFAULT_RECIPE)
        parsed = load_recipe(recipe_path, pairs(sets, "=", "KEY=VALUE"), root)
        # The demo drives the component named robot (its roles): say so before building.
        if demo and not parsed.places("robot"):
            raise ConversionError(
                "the recipe places no robot (see its flags and placements); --demo needs one",
                file=recipe_path,
                element="--demo",
            )
        # Before building: the demo needs the whole sim extra, a recipe's AprilTags its cv2.
        if demo:
            extras.require("sim", "make-facility --demo")
        elif any(c.fiducials for n, c in parsed.components.items() if parsed.places(n)):
            extras.require("sim", "drawing the recipe's AprilTags (fiducials)", ("cv2",))
        out = Path(output) if output else facility_root.default_output(root, parsed.name)
        report = facility_build.build_facility(
            parsed,
            out,
            root=root,
            seed=seed,
            components=not no_components,
            workers=workers,
            cache_dir=cache_dir,
            progress=progress,
            overwrite=overwrite,
        )
    if not quiet:
        _echo_notes(report.conversion.notes, verbose)
        counts = report.written.counts.to_json() if report.written and report.written.counts else {}
        click.echo(f"wrote {report.scene}")
        click.echo(
            f"{parsed.name}: {counts['bodies'] - 1} bodies, {counts['joints']} joints, "
            f"{counts['actuators']} actuators, {counts['sensors']} sensors, "
            f"{counts['cameras']} cameras" + (f", seed {seed}" if seed is not None else "")
        )
    if demo:
        from .runner.cli import facility_demo_command

        ctx.invoke(
            facility_demo_command, scene=report.output, view=view, allow_origins=allow_origins
        )
    if view:
        from .view.watch import show

        show(report.scene, what=f"{parsed.name} ({report.scene})", origins=allow_origins)


def make_facility_main() -> None:
    run_command(make_facility_command)


def facility_demo_main() -> None:
    headless.configure()
    from .runner.cli import facility_demo_command

    run_command(extras.requiring("sim", facility_demo_command))


def rover_drive_main() -> None:
    headless.configure()
    from .runner.rover.cli import rover_drive_group

    run_command(rover_drive_group)
