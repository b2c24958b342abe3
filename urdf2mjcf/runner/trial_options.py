"""``--workers`` and ``--executor``, declared once for ``facility-demo`` and
``rover-drive --task``: where seeded trials run, meaning the same in both."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from ..cli_types import BoundedInt
from .executors import EXECUTORS

WORKERS_MAX = 1024
"""Processes of a local pool, or CPUs of a Ray instance started here."""


def trial_options() -> Callable[[Any], Any]:
    """The two options, in this order, on a click command."""
    options = [
        click.option(
            "--workers",
            type=BoundedInt(1, WORKERS_MAX),
            default=None,
            help="with --trials: processes of the local pool, or CPUs of a Ray instance "
            "started here",
        ),
        click.option(
            "--executor",
            type=click.Choice(EXECUTORS),
            default="local",
            show_default=True,
            help="where --trials run: the local process pool, or Ray "
            "(pip install 'mjcf-forge[ray]')",
        ),
    ]

    def apply(f: Any) -> Any:
        for option in reversed(options):
            f = option(f)
        return f

    return apply
