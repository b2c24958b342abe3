"""The options that watch a run live, declared once for ``facility-demo`` and
``rover-drive``: the same flag means the same thing in both."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..cli_types import BoundedInt, FiniteFloat
from ..view.live import PACE_MAX
from .foxglove_live import DEFAULT_PORT, PORT_MAX


def live_options(
    run: str, pace_with: str = "--view or --foxglove", note: str = ""
) -> Callable[[Any], Any]:
    """``--view``, ``--pace``, ``--foxglove [PORT]`` and ``--foxglove-wait``; ``run``
    names what is watched (``run``, ``drive``) in the help, ``note`` is added to the
    help of ``--view`` and ``--foxglove``."""
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
    ]

    def decorate(f: Any) -> Any:
        for option in reversed(options):
            f = option(f)
        return f

    return decorate
