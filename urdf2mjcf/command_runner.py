"""One error path for every command: each failure one ``error:`` line with its exit
code (2 for bad input or usage, 1 for a bug, 128+N for a signal), and SIGTERM turned
into an exception so staged output unwinds as on Ctrl-C.

Below the commands (``cli.py``, and the runtime's commands through it): nothing here
knows what a command does.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import signal
import sys
import threading
import time
import traceback
from typing import Any

import click

from . import headless
from .errors import ForgeError
from .untrusted import printable

ERROR_LINE_MAX = 2000
"""Characters of an error message printed (a message quoting a file is cut there)."""


def _one_line(text: str) -> str:
    """``text`` on one line, control characters escaped, at most ERROR_LINE_MAX long."""
    line = "; ".join(part.strip() for part in str(text).splitlines() if part.strip())
    line = printable(line)
    return line if len(line) <= ERROR_LINE_MAX else line[: ERROR_LINE_MAX - 3] + "..."


def with_debug_option(command: click.Command) -> click.Command:
    """``command`` (and a group's sub-commands) taking ``--debug``, which run_command reads."""
    _add_debug_option(command)
    if isinstance(command, click.Group):  # `urdf2mjcf cache info --debug`
        for sub in command.commands.values():
            _add_debug_option(sub)
    return command


def _add_debug_option(command: click.Command) -> None:
    if not any(p.name == "debug" for p in command.params):
        command.params.append(
            click.Option(
                ["--debug"],
                is_flag=True,
                expose_value=False,  # run_command reads it from the arguments
                help="Print the traceback of an error too.",
            )
        )


def command_path(ctx: click.Context) -> str:
    """The command as typed, its root by its own name: ``urdf2mjcf batch`` (a
    sub-command's help is where its options are), whatever ``argv[0]`` was."""
    names = []
    while ctx.parent is not None:
        if ctx.info_name:  # a hidden default sub-command has none
            names.append(ctx.info_name)
        ctx = ctx.parent
    return " ".join([ctx.command.name or "", *reversed(names)]).strip()


class DefaultGroup(click.Group):
    """A group whose first argument, when it names none of its sub-commands (nor asks
    for help), goes to the sub-command ``default``: a command's spelling from before it
    had sub-commands keeps working. A ``hidden_default`` is left out of the command's
    path in messages (it stands for the group itself)."""

    def __init__(self, *args: Any, default: str, hidden_default: bool = False, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.default = default
        self.hidden_default = hidden_default

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if not args or (
            args[0] not in self.list_commands(ctx) and args[0] not in ctx.help_option_names
        ):
            args = [self.default, *args]
        return super().parse_args(ctx, args)

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        name, command, rest = super().resolve_command(ctx, args)
        if self.hidden_default and name == self.default:
            name = ""  # its errors say `rover-drive`, not `rover-drive legacy`
        return name, command, rest


def run_command(
    command: click.Command, args: list[str] | None = None, prog_name: str | None = None
) -> None:
    """Run ``command`` so that every failure is one ``error:`` line on stderr.

    Bad input or usage: exit code 2. A ``ForgeError`` (any product's) is the usual path for
    bad input; the ``Exception`` guard at the end is the last resort for a bug
    (exit code 1). ``--debug`` prints the traceback as well.
    """
    headless.configure()  # before anything imports mujoco: cameras render without a display
    with_debug_option(command)
    debug = "--debug" in (sys.argv[1:] if args is None else args)
    sigterm = _terminate_cleanly()
    try:
        try:
            command.main(args=args, prog_name=prog_name, standalone_mode=False)
        except Exception as exc:
            # A native module that is being imported when SIGTERM lands wraps our
            # Terminated in its own error (pybind11: "ImportError: initialization failed")
            if sigterm.received:
                raise Terminated() from exc
            raise
    except Terminated:  # SIGTERM: the staged output was removed on the way out
        click.echo(
            f"error: {command.name} terminated (SIGTERM); its unfinished output removed", err=True
        )
        sys.exit(128 + signal.SIGTERM)
    except ForgeError as exc:  # bad input: one line, never a traceback (-vv logs it)
        logging.getLogger(__name__).debug("%s failed", command.name, exc_info=True)
        if debug:
            traceback.print_exc()
        click.echo(f"error: {_one_line(str(exc))}", err=True)
        sys.exit(2)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except KeyboardInterrupt:  # Ctrl-C: like SIGTERM, the staged output was removed
        _interrupted(command.name)
    except click.Abort as exc:
        if isinstance(exc.__context__, KeyboardInterrupt):  # click's own Ctrl-C
            _interrupted(command.name)
        click.echo("error: aborted", err=True)
        sys.exit(2)
    except click.UsageError as exc:
        path = command_path(exc.ctx) if exc.ctx is not None else command.name
        hint = f" (see '{path} --help')"
        click.echo(f"error: {_one_line(exc.format_message())}{hint}", err=True)
        sys.exit(2)
    except click.ClickException as exc:
        click.echo(f"error: {_one_line(exc.format_message())}", err=True)
        sys.exit(2)
    except OSError as exc:  # a file or folder the user named cannot be read or written
        if debug:
            traceback.print_exc()
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"error: {where}{_one_line(exc.strerror or str(exc))}", err=True)
        sys.exit(2)
    except Exception as exc:  # last resort: a bug, never the path for bad input
        if debug:
            traceback.print_exc()
        hint = "" if debug else "; run with --debug for the traceback"
        click.echo(
            f"error: internal error in {command.name}: {type(exc).__name__}: "
            f"{_one_line(str(exc))}{hint}",
            err=True,
        )
        sys.exit(1)
    finally:
        sigterm.restore()
    if sigterm.received:  # its Terminated was swallowed where Python cannot raise (a __del__)
        click.echo(
            f"error: {command.name} terminated (SIGTERM) as it finished; its output is complete",
            err=True,
        )
        sys.exit(128 + signal.SIGTERM)
    sys.exit(0)


def _interrupted(name: str | None) -> None:
    click.echo(f"error: {name} interrupted (Ctrl-C); its unfinished output removed", err=True)
    sys.exit(128 + signal.SIGINT)


class Terminated(BaseException):
    """SIGTERM, raised in the main thread: like Ctrl-C, it unwinds every staged
    output folder and file (their cleanup runs on any exception), which the default
    action (the process killed where it stands) would leave behind."""


@dataclasses.dataclass
class _SigtermHandler:
    """Whether SIGTERM arrived (the Terminated it raised may reach us wrapped), and
    how to put the previous handler back."""

    received: bool = False
    at: float = 0.0
    previous: Any = None
    installed: bool = False

    def restore(self) -> None:
        if self.installed:
            # Terminated: exiting now; another SIGTERM must not kill us mid-way (atexit
            # cleanup skipped: semaphores leaked, a message on stderr)
            signal.signal(signal.SIGTERM, signal.SIG_IGN if self.received else self.previous)


SIGTERM_GRACE = 10.0
"""Seconds after a SIGTERM in which another is ignored: the first one's unwinding (workers
stopped, staged output removed) runs to its end, never cut short into orphans."""


def _terminate_cleanly() -> _SigtermHandler:
    """Turn SIGTERM into :class:`Terminated` in this process. Child processes are
    spawned or exec'd (default handlers), and one forked after this still dies by
    SIGTERM as before."""
    state = _SigtermHandler()
    if threading.current_thread() is not threading.main_thread():
        return state
    main = os.getpid()

    def handler(signum: int, frame: Any) -> None:
        if os.getpid() != main:  # a forked child: die as SIGTERM says
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)
            return
        if state.received and time.monotonic() - state.at < SIGTERM_GRACE:
            return  # already unwinding: a second SIGTERM must not cut its cleanup short
        state.received, state.at = True, time.monotonic()
        raise Terminated()

    state.previous = signal.signal(signal.SIGTERM, handler)
    state.installed = True
    return state
