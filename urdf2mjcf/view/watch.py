"""``urdf2mjcf view``'s loop: convert, show, watch every file the conversion read,
convert again when one changes.

What a conversion read is what this process opened while it ran (Python's ``open``
audit event): the description, its xacro includes and YAML files, the meshes and
textures, the ``--actuator-config`` file, the ``<mujoco>`` extension's files, the
``package.xml`` files that located packages. Python's own files, the cache and the
working folder are left out. Changes are seen by polling each file's modification
time and size (no file-system notification dependency).
"""

from __future__ import annotations

import os
import shutil
import signal
import site
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import click

from ..errors import ConversionError, ForgeError
from ..untrusted import printable
from .studio import Studio, check_desktop, check_studio, open_browser

POLL_S = 0.5
"""Seconds between two looks at the watched files."""

_recording: list[set[str]] = []
_hooked = threading.Lock()
_installed: list[bool] = []


def _audit(event: str, args: tuple) -> None:
    if event == "open" and _recording and args and isinstance(args[0], (str, bytes, os.PathLike)):
        mode = args[1] if len(args) > 1 else None
        flags = args[2] if len(args) > 2 else 0
        writing = (isinstance(mode, str) and any(c in mode for c in "wax+")) or (
            isinstance(flags, int) and flags & (os.O_WRONLY | os.O_RDWR)
        )
        if not writing:
            _recording[-1].add(os.fsdecode(args[0]))


@contextmanager
def recording_reads() -> Iterator[set[str]]:
    """The paths this process opens for reading inside the block (every thread)."""
    with _hooked:
        if not _installed:  # an audit hook cannot be removed: one for the process
            sys.addaudithook(_audit)
            _installed.append(True)
    found: set[str] = set()
    _recording.append(found)
    try:
        yield found
    finally:
        _recording.remove(found)


def _ignored_roots(extra: Iterable[Path]) -> list[Path]:
    roots = {Path(p) for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}
    roots.update(Path(p) for p in site.getsitepackages())
    roots.update(Path(p) for p in extra)
    return [r.resolve() for r in roots] + [Path("/proc"), Path("/dev"), Path("/sys")]


def inputs(opened: Iterable[str], ignore: Iterable[Path]) -> set[Path]:
    """Of the paths opened, the user's input files: regular files outside Python's own
    folders and ``ignore`` (the cache, the working folder)."""
    roots = _ignored_roots(ignore)
    out = set()
    for name in opened:
        path = Path(name).resolve()
        if path.suffix in (".py", ".pyc", ".so") or not path.is_file():
            continue
        if any(path.is_relative_to(r) for r in roots):
            continue
        out.add(path)
    return out


Stamp = tuple[int, int] | None


def stamps(paths: Iterable[Path]) -> dict[Path, Stamp]:
    """Each file's (modification time in ns, size); None where it is missing."""
    out: dict[Path, Stamp] = {}
    for p in paths:
        try:
            st = p.stat()
            out[p] = (st.st_mtime_ns, st.st_size)
        except OSError:
            out[p] = None
    return out


def wait_for_change(seen: dict[Path, Stamp], stop: threading.Event) -> bool:
    """Polls until a watched file changes and then stays put for one poll (an editor's
    save written in pieces is converted once); False when ``stop`` is set first."""
    while not stop.wait(POLL_S):
        now = stamps(seen)
        if now != seen:
            while not stop.wait(POLL_S):
                later = stamps(seen)
                if later == now:
                    return True
                now = later
            return False
    return False


@contextmanager
def _stopped_by_signals() -> Iterator[threading.Event]:
    """An event set by SIGTERM (and Ctrl-C): the loop ends between two polls."""
    stop = threading.Event()
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, lambda *_: stop.set())
    try:
        yield stop
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


Convert = Callable[[Path], Any]
"""Converts the description into the given robot file; returns the report."""
Describe = Callable[[Any], Sequence[str]]
"""The lines printed after a conversion, from its report."""


def serve(
    source: Path,
    convert: Convert,
    describe: Describe,
    *,
    scene: bool,
    port: int = 0,
    browser: bool = True,
    desktop: bool = False,
    cache: Path | None = None,
    watch: Iterable[Path] = (),
    origins: Iterable[str] = (),
) -> None:
    """Convert ``source`` into a working folder, show it, and convert again on every
    change of a file the conversion read (``watch``: files to watch besides those),
    until SIGTERM or Ctrl-C. A first conversion that fails is the command's error; a
    later one prints its ``error:`` line and the viewer keeps the last good model.
    ``origins``: those the browser viewer answers besides its own page."""
    check_studio()  # said before converting
    if desktop:
        check_desktop()
    work = Path(tempfile.mkdtemp(prefix="urdf2mjcf-view-"))
    ignore = [work] + ([cache] if cache is not None else [])
    generation = 0

    said: list[tuple[str, str]] = []  # for the page's console, once it is up

    def attempt() -> tuple[Path | None, set[Path]]:
        nonlocal generation
        generation += 1
        folder = work / str(generation)
        with recording_reads() as opened:
            try:
                report = convert(folder / "robot.xml")
            except ForgeError as exc:
                read = inputs(opened, ignore) | {source.resolve()}
                if generation == 1:
                    raise
                click.echo(f"error: {printable(str(exc))}", err=True)
                said.append(("error", f"{printable(str(exc))} (the last good model stays)"))
                return None, read
        for line in describe(report):
            click.echo(printable(line))
            said.append(("info", printable(line)))
        return folder / ("scene.xml" if scene else "robot.xml"), inputs(opened, ignore)

    def tell(studio: Studio) -> None:
        while said:
            studio.log(*said.pop(0))

    try:
        shown, read = attempt()
        assert shown is not None
        viewer = Studio(port=port, desktop=desktop, origins=origins)
        with _stopped_by_signals() as stop, viewer as studio:
            if not studio.load(shown):
                raise ConversionError("the viewer could not load the model", file=shown)
            tell(studio)
            if studio.url:
                click.echo(f"viewing {source} at {studio.url} (Ctrl-C to stop)")
                if browser:
                    open_browser(studio.url)
            else:
                click.echo(f"viewing {source} in MuJoCo's desktop viewer (Ctrl-C to stop)")
            extra = {Path(p).resolve() for p in watch}
            seen = stamps(read | extra)
            while wait_for_change(seen, stop):
                newer, now_read = attempt()
                tell(studio)
                # on an error, the files of both tries: fixing either converts again
                seen = stamps(now_read | extra | (set(seen) if newer is None else set()))
                if newer is not None:
                    if studio.load(newer):
                        shutil.rmtree(shown.parent, ignore_errors=True)
                        shown = newer
                    else:
                        click.echo(f"error: the viewer could not load {newer}", err=True)
                if not studio.alive():
                    raise ConversionError("the viewer stopped", element="viewer")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def show(
    path: Path,
    *,
    port: int = 0,
    browser: bool = True,
    what: str | None = None,
    origins: Iterable[str] = (),
) -> None:
    """Show the model file ``path`` in the browser viewer until SIGTERM or Ctrl-C
    (``origins``: those it answers besides its own page)."""
    with _stopped_by_signals() as stop, Studio(port=port, origins=origins) as studio:
        if not studio.load(path):
            raise ConversionError("the viewer could not load the model", file=path)
        click.echo(f"viewing {what or path} at {studio.url} (Ctrl-C to stop)")
        if browser and studio.url:
            open_browser(studio.url)
        while not stop.wait(POLL_S):
            if not studio.alive():
                raise ConversionError("the viewer stopped", element="viewer")
