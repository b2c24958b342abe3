"""docs/security.md's "Servers" states what the code holds: the table of what each
server listens on, whom it answers and its bounds is made here from the code's own
constants, and the figures the section repeats are the code's; the option it names
exists on every command that serves, and refuses what it says it refuses."""

from __future__ import annotations

from pathlib import Path

import click
import pytest

from urdf2mjcf import loopback_guard
from urdf2mjcf.ros2 import server as ros2_server
from urdf2mjcf.ros2 import session as ros2_session
from urdf2mjcf.runner import foxglove_live, foxglove_server
from urdf2mjcf.runner.rover import console
from urdf2mjcf.view import studio_guard

DOC = (Path(__file__).resolve().parents[2] / "docs" / "security.md").read_text()
LOOPBACK = "`Host` a loopback name and its port"
OWN = "its own page's origin or an `--allow-origin` one; the run's token"


def _kib(n: int) -> str:
    return f"{n // 1024} KiB"


def servers_table() -> str:
    rows = [
        "| server | listens on | answers | at most |",
        "|---|---|---|---|",
        "| browser viewer | 127.0.0.1, `--port` (0: the first free port from 8080 up) | "
        f"{LOOPBACK}; {OWN} | {studio_guard.CLIENTS_MAX} connections, "
        f"{_kib(studio_guard.MESSAGE_MAX)} per message, "
        f"{studio_guard.OPEN_TIMEOUT_S:g} s to open a connection |",
        "| rover console | 127.0.0.1, `--port` (0: a free port) | "
        f"{LOOPBACK}; {OWN} | {console.CLIENTS_MAX} connections, "
        f"{_kib(console.BODY_MAX)} per body, {console.BODY_TIMEOUT_S:g} s for a body, "
        f"{console.REQUEST_TIMEOUT_S:g} s idle |",
        f"| Foxglove stream | 127.0.0.1, `--foxglove PORT` ({foxglove_live.DEFAULT_PORT}; "
        f"0: a free port) | {LOOPBACK}; no web page but an `--allow-origin` one (a program "
        f"sends no `Origin`) | {foxglove_server.CLIENTS_MAX} clients, "
        f"{foxglove_server.QUEUE_BYTES // 2**20} MiB queued per client, "
        f"{_kib(foxglove_server.MESSAGE_MAX)} per client message, "
        f"{foxglove_server.OPEN_TIMEOUT_S:g} s to open a connection |",
        "| ROS 2 node (`urdf2mjcf serve`, `--ros2`) | 127.0.0.1 (a free port), or "
        "`--zenoh-listen tcp/HOST:PORT` (a wildcard 0.0.0.0 or [::] refused); it connects "
        f"to `--zenoh-connect` (default {ros2_session.ROUTER}, rmw_zenohd's) | any Zenoh "
        "peer, over Zenoh's own TCP protocol (no web page speaks it); no multicast scouting "
        "| a bad command (length, NaN, unknown joint, times going back) dropped with one "
        f"warning per {ros2_server.WARN_EVERY:g} s; a value outside its limits clipped, "
        "said once |",
    ]
    return "\n".join(rows)


def test_the_servers_table_is_the_code_s():
    start = DOC.index("<!-- servers table")
    end = DOC.index("<!-- end servers table -->")
    table = DOC[start:end].split("-->", 1)[1].strip()
    assert table == servers_table(), "regenerate the table from the code:\n" + servers_table()


def test_the_figures_the_section_repeats_are_the_code_s():
    section = DOC[DOC.index("## Servers") : DOC.index("## What is not defended")]
    assert console.HOST == foxglove_server.FoxgloveServer.HOST == "127.0.0.1"
    for figure in (
        f"--allow-origin {loopback_guard.FOXGLOVE_APP}",
        f"{loopback_guard.TOKEN_BYTES} random bytes",
        f"longer than {console.DIGITS_MAX} characters",
        f"beyond ±{console.NUMBER_MAX:.0e}".replace("+0", ""),
        f"beyond {console.CLIENTS_MAX} connections",
        *(f"`{n}`" for n in loopback_guard.LOOPBACK_NAMES),
        *studio_guard.CLOSED_PATHS,
        *(f"`{k}: {v}`" for k, v in loopback_guard.SECURITY_HEADERS.items()),
    ):
        assert figure in section, figure


def _commands() -> dict[str, click.Command]:
    from urdf2mjcf.cli import make_facility_command, view_command
    from urdf2mjcf.runner.cli import facility_demo_command
    from urdf2mjcf.runner.rover.cli import rover_drive_command

    return {
        "urdf2mjcf view": view_command,
        "make-facility": make_facility_command,
        "facility-demo": facility_demo_command,
        "rover-drive": rover_drive_command,
    }


@pytest.mark.parametrize("name", list(_commands()))
def test_every_command_that_serves_takes_allow_origin(name):
    (option,) = [p for p in _commands()[name].params if "--allow-origin" in p.opts]
    assert option.multiple and isinstance(option.type, loopback_guard.OriginParam)


@pytest.mark.parametrize(
    "given, normal",
    [
        ("https://app.foxglove.dev", "https://app.foxglove.dev"),
        ("https://APP.Foxglove.dev:443/", "https://app.foxglove.dev"),
        ("http://localhost:8080", "http://localhost:8080"),
        ("http://[::1]:80", "http://[::1]"),
    ],
)
def test_an_origin_is_written_as_a_browser_writes_it(given, normal):
    assert loopback_guard.normalize_origin(given) == normal


@pytest.mark.parametrize(
    "bad",
    ["*", "null", "file://", "ws://x", "https://*.foxglove.dev", "https://a/b", "https://a?q",
     "https://u:p@a", "https://a:99999", "", "x" * 300, "https://a b", "https://\x1b[31m"],
)  # fmt: skip
def test_an_origin_that_is_not_one_is_refused(bad):
    with pytest.raises(ValueError):
        loopback_guard.normalize_origin(bad)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--view", "--allow-origin", "*"], "every site"),
        (["--view", "--allow-origin", "https://a.example/path"], "no path"),
        (["--allow-origin", "https://app.foxglove.dev"], "--allow-origin is for --view"),
    ],
)
def test_a_bad_allow_origin_is_one_error_line_before_any_work(tmp_path, args, needle):
    from tests.security.attack import assert_one_error, run

    res = run("make-facility", "recipes/mira3d-floor.yaml", "-o", str(tmp_path / "out"), *args,
              cwd=Path(__file__).resolve().parents[2], timeout=120)  # fmt: skip
    assert_one_error(res, needle)
    assert not (tmp_path / "out").exists()
