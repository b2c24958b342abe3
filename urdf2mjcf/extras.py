"""The optional extras a command needs, checked before it reads or writes anything.

``pip install mjcf-forge`` installs what converting a robot needs (``urdf2mjcf``,
``urdf2mjcf batch``, ``urdf2mjcf verify``). The facility demo's stack is the ``sim``
extra: without it, a command that needs it fails with one ``error:`` line naming
what is missing and how to install it (exit 2), not with a traceback half-way.
"""

from __future__ import annotations

import copy
import functools
import importlib.util
from collections.abc import Sequence
from typing import Any

import click

from .command_runner import command_path
from .errors import MissingExtraError

EXTRAS: dict[str, tuple[str, ...]] = {
    # IK (mink), collision-free planning (ompl) and its time parameterisation (toppra),
    # AprilTags (cv2: drawn into a facility, detected by the demo), the trials' plot
    "sim": ("mink", "ompl", "toppra", "cv2", "matplotlib"),
    # the live Foxglove stream (facility-demo --foxglove, rover-drive --foxglove): our own
    # server of Foxglove's protocol over websockets (MuJoCo's viewer brings it too)
    "live": ("websockets",),
    # urdf2mjcf serve --ros2: a Zenoh session speaking rmw_zenoh's conventions
    "ros2": ("zenoh",),
    # urdf2mjcf calibrate: the bounded least-squares solver, the ROS 2 bag reader
    "calibrate": ("scipy", "rosbags"),
}
"""Extra name -> the modules it provides (import names, as pyproject.toml's extra installs
them: cv2 is opencv-python-headless)."""


def missing(modules: Sequence[str]) -> list[str]:
    """Those of ``modules`` that cannot be imported (not installed, or refused)."""
    gone = []
    for name in modules:
        try:
            # find_spec, not import: cheap (toppra and matplotlib take seconds to import)
            found = importlib.util.find_spec(name) is not None
        except (ImportError, ValueError):  # an import hook refusing it, a broken package
            found = False
        if not found:
            gone.append(name)
    return gone


def require(extra: str, needed_by: str, modules: Sequence[str] | None = None) -> None:
    """Raise :class:`MissingExtraError` unless ``extra``'s modules (or just ``modules``
    of them, where that is all ``needed_by`` uses) are installed."""
    wanted = EXTRAS[extra] if modules is None else modules
    gone = missing(wanted)
    if gone:
        raise MissingExtraError(
            f"{needed_by} needs the {extra} extra: pip install 'mjcf-forge[{extra}]' "
            f"(missing: {', '.join(gone)})"
        )


def requiring(extra: str, command: click.Command) -> click.Command:
    """``command``, checking ``extra`` once its arguments are parsed (``--help`` and
    usage errors need nothing) and before its body runs (nothing is read or written)."""
    body = command.callback
    assert body is not None

    @functools.wraps(body)
    def checked(*args: Any, **kwargs: Any) -> Any:
        ctx = click.get_current_context(silent=True)
        require(extra, command_path(ctx) if ctx is not None else command.name or "this command")
        return body(*args, **kwargs)

    wrapped = copy.copy(command)
    wrapped.callback = checked
    return wrapped
