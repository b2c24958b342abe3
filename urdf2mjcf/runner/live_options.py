"""The options that watch a run live, declared once for ``facility-demo`` and
``rover-drive``: the same flag means the same thing in both. ``--allow-origin`` is
declared here once for every command that serves a browser (``urdf2mjcf view`` and
``make-facility --view`` too)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..cli_types import BoundedInt, FiniteFloat
from ..loopback_guard import FOXGLOVE_APP, OriginParam
from ..view.live import PACE_MAX
from .foxglove_live import DEFAULT_PORT, PORT_MAX

ALLOW_ORIGIN = ("--allow-origin", "allow_origins")
"""The option's flag and parameter name."""


def _allow_origin_attrs(serves: str) -> dict[str, Any]:
    return {
        "multiple": True,
        "type": OriginParam(),
        "metavar": "ORIGIN",
        "help": f"with {serves}: also answer pages of ORIGIN (scheme://host[:port], "
        f"repeatable; Foxglove's web app is {FOXGLOVE_APP}); by default only the page we "
        "serve, at the address printed",
    }


def allow_origin_param(serves: str) -> click.Option:
    """``--allow-origin ORIGIN`` (repeatable) as a parameter of a ``click.Command``."""
    return click.Option(list(ALLOW_ORIGIN), **_allow_origin_attrs(serves))


def allow_origin_option(serves: str) -> Callable[[Any], Any]:
    """``--allow-origin ORIGIN`` (repeatable) as a decorator; ``serves``: the options
    whose servers it opens to another origin (in the help)."""
    return click.option(*ALLOW_ORIGIN, **_allow_origin_attrs(serves))


def check_allow_origin(origins: tuple[str, ...], serving: bool, serves: str) -> None:
    """``--allow-origin`` where nothing is served: a usage error."""
    if origins and not serving:
        raise click.UsageError(f"--allow-origin is for {serves}")


def live_options(
    run: str, pace_with: str = "--view or --foxglove", note: str = ""
) -> Callable[[Any], Any]:
    """``--view``, ``--pace``, ``--foxglove [PORT]``, ``--foxglove-wait`` and
    ``--allow-origin``; ``run`` names what is watched (``run``, ``drive``) in the help,
    ``note`` is added to the help of ``--view`` and ``--foxglove``."""
    options = [
        click.option(
            "--view",
            is_flag=True,
            help=f"show the {run} live in MuJoCo's browser viewer (its address goes to "
            f"stderr){note}",
        ),
        click.option(
            "--pace",
            type=FiniteFloat(0.0, PACE_MAX, low_open=True),
            default=1.0,
            show_default=True,
            help=f"with {pace_with}: simulated seconds per wall-clock second",
        ),
        click.option(
            "--foxglove",
            type=BoundedInt(0, PORT_MAX),
            is_flag=False,
            flag_value=DEFAULT_PORT,
            default=None,
            metavar="[PORT]",
            help=f"stream the {run} live to Foxglove at ws://127.0.0.1:PORT (default "
            f"{DEFAULT_PORT}; 0: a free port; its address goes to stderr): the --record "
            f"topics, paced by --pace{note} (pip install 'mjcf-forge[live]')",
        ),
        click.option(
            "--foxglove-wait",
            is_flag=True,
            help=f"with --foxglove: start the {run} once a client subscribes to a topic",
        ),
        allow_origin_option(pace_with),
    ]

    def decorate(f: Any) -> Any:
        for option in reversed(options):
            f = option(f)
        return f

    return decorate
