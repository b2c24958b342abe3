"""The ROS 2 transport options (``--ros2``, ``--zenoh-connect``, ``--zenoh-listen``,
``--ros-domain``), declared once for ``urdf2mjcf serve`` and the runs that publish
while they run (``facility-demo``, ``rover-drive``), and what they choose."""

from __future__ import annotations

import ipaddress
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import click

from ..cli_types import BoundedInt
from ..extras import require
from ..untrusted import printable

_ENDPOINT = re.compile(r"^tcp/(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.\-]+):(?P<port>\d{1,5})$")
DOMAIN_MAX = 232
"""The largest ROS_DOMAIN_ID ROS 2 documents."""


class ZenohEndpoint(click.ParamType):
    """``tcp/HOST:PORT``; with ``listen``, HOST an address of this machine: loopback
    (127.0.0.1, [::1], localhost) or an interface's own address the user names, never
    a wildcard (0.0.0.0, [::]) that would listen on every interface."""

    name = "tcp/HOST:PORT"

    def __init__(self, listen: bool) -> None:
        self.listen = listen

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        text = str(value)
        m = _ENDPOINT.match(text)
        if m is None or int(m["port"]) > 65535:
            self.fail(f"'{printable(text)[:60]}' is not tcp/HOST:PORT", param, ctx)
        host = m["host"].strip("[]")
        if self.listen and host != "localhost":
            try:
                address = ipaddress.ip_address(host)
            except ValueError:
                self.fail(
                    f"listen on an address (like 127.0.0.1), not the name '{host}'", param, ctx
                )
            if address.is_unspecified:
                self.fail(
                    f"{host} listens on every interface: name the interface's own address",
                    param,
                    ctx,
                )
        return text


def _default_domain() -> int:
    text = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit() or int(text) > DOMAIN_MAX:
        raise click.UsageError(f"ROS_DOMAIN_ID={printable(text)[:20]} is not 0..{DOMAIN_MAX}")
    return int(text)


def ros2_options(ros2_help: str) -> Callable[[Any], Any]:
    """``--ros2``, ``--zenoh-connect``, ``--zenoh-listen`` and ``--ros-domain``, declared
    once for ``serve`` and the runs that publish while they run (``facility-demo``,
    ``rover-drive``); ``ros2_help``: the help of ``--ros2``."""
    options = [
        click.option("--ros2", is_flag=True, help=ros2_help),
        click.option(
            "--zenoh-connect",
            multiple=True,
            type=ZenohEndpoint(listen=False),
            help="with --ros2: a Zenoh router (rmw_zenohd) or peer to connect to (repeatable; "
            "default tcp/localhost:7447, rmw_zenoh's router, unless --zenoh-listen is given).",
        ),
        click.option(
            "--zenoh-listen",
            multiple=True,
            type=ZenohEndpoint(listen=True),
            help="with --ros2: listen for ROS nodes at tcp/HOST:PORT (repeatable): a loopback "
            "address, or an interface's own address only when named.",
        ),
        click.option(
            "--ros-domain",
            type=BoundedInt(0, DOMAIN_MAX),
            default=None,
            help="with --ros2: the ROS domain (default: $ROS_DOMAIN_ID, else 0).",
        ),
    ]

    def decorate(f: Any) -> Any:
        for option in reversed(options):
            f = option(f)
        return f

    return decorate


@dataclass(frozen=True)
class Transport:
    """What the ROS 2 options chose: where the session listens and connects, the domain."""

    listen: tuple[str, ...]
    connect: tuple[str, ...]
    domain: int


def transport(
    ros2: bool,
    zenoh_connect: tuple[str, ...],
    zenoh_listen: tuple[str, ...],
    ros_domain: int | None,
    command: str,
) -> Transport | None:
    """The transport of the ROS 2 options (None without ``--ros2``; a transport option
    without it, or the ros2 extra missing: a usage error); ``command`` names the
    command in the extra's install line."""
    if not ros2:
        if zenoh_connect or zenoh_listen or ros_domain is not None:
            raise click.UsageError("--zenoh-connect, --zenoh-listen and --ros-domain need --ros2")
        return None
    domain = _default_domain() if ros_domain is None else ros_domain
    require("ros2", command)
    if zenoh_listen or zenoh_connect:
        return Transport(zenoh_listen, zenoh_connect, domain)
    from .session import ROUTER

    # as an rmw_zenoh node: the local router, and a loopback port for peers
    return Transport(("tcp/127.0.0.1:0",), (ROUTER,), domain)
