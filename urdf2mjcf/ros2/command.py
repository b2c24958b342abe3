"""``urdf2mjcf serve MODEL --ros2``: options -> :class:`.server.ServeConfig` -> serve."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import click

from ..cli_common import configure_logging
from ..cli_types import FiniteFloat
from ..errors import ServeError
from ..untrusted import printable
from ..view.live import PACE_MAX
from .options import ros2_options, transport


@click.command("serve", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("model", type=click.Path(path_type=Path, exists=True))
@ros2_options("Serve to ROS 2 over rmw_zenoh (the transport served).")
@click.option(
    "--pace",
    type=FiniteFloat(0.0, PACE_MAX, low_open=True),
    default=1.0,
    show_default=True,
    help="Simulated seconds per wall-clock second.",
)
@click.option(
    "--rate",
    type=FiniteFloat(0.0, 2000.0, low_open=True),
    default=100.0,
    show_default=True,
    help="Hz of /clock, /joint_states and /tf (simulated time).",
)
@click.option(
    "--node-name",
    default="ros2_control_node",
    show_default=True,
    help="The node's name; its services are /NAME/reset_world, set_pause, step_simulation.",
)
@click.option(
    "--camera-rate",
    type=FiniteFloat(0.0, 100.0),
    default=0.0,
    show_default=True,
    help="Hz (simulated time) each camera of the model is rendered at, to "
    "/<camera>/image_raw and /<camera>/camera_info; 0: none.",
)
@click.option(
    "--controllers",
    type=click.Path(path_type=Path, exists=True, dir_okay=False),
    help="ros2_control's controller_manager YAML (the bringup's controllers.yaml): its "
    "trajectory and forward controllers, by name, over the model's actuators (default: "
    "one forward controller per actuator kind, joint_trajectory_controller over the "
    "position servos).",
)
@click.option("-v", "--verbose", count=True, help="More log lines (-vv: debug).")
def serve_command(
    model: Path,
    ros2: bool,
    zenoh_connect: tuple[str, ...],
    zenoh_listen: tuple[str, ...],
    ros_domain: int | None,
    pace: float,
    rate: float,
    node_name: str,
    camera_rate: float,
    controllers: Path | None,
    verbose: int,
) -> None:
    """Serve MODEL (a converted robot's robot.xml or scene.xml, or a facility bundle:
    its folder or scene.xml) live to ROS 2.

    Its node publishes /clock, /joint_states, /tf and /tf_static, takes the forward
    controllers' /<group>/commands and /joint_trajectory_controller/joint_trajectory,
    and answers mujoco_ros2_control's services, until Ctrl-C (docs/ros2.md).
    """
    if not ros2:
        raise click.UsageError("name the transport: --ros2")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", node_name):
        raise click.UsageError(f"--node-name '{printable(node_name)[:40]}' is not a ROS node name")
    chosen = transport(ros2, zenoh_connect, zenoh_listen, ros_domain, "urdf2mjcf serve --ros2")
    assert chosen is not None  # --ros2 is given
    domain = chosen.domain
    configure_logging(verbose, False)

    from .server import ServeConfig, serve
    from .session import Endpoints
    from .world import build

    endpoints = Endpoints(listen=chosen.listen, connect=chosen.connect)
    config = ServeConfig(
        endpoints=endpoints,
        domain=domain,
        node_name=node_name,
        pace=pace,
        rate=rate,
        controllers=controllers,
        camera_rate=camera_rate,
    )
    served = build(model, config, ServeError)

    def ready(server: Any) -> None:
        where = ", ".join(
            [
                *(f"listening on {e}" for e in zenoh_listen),
                *(f"connecting to {e}" for e in endpoints.connect),
            ]
        )
        groups = (
            ", ".join(
                [
                    *(f"/{g}/commands" for g in server.groups),
                    *(f"/{g}/joint_trajectory" for g in server.trajectory_groups),
                ]
            )
            or "no controllers"
        )
        rovers: dict = next((e.driven for e in server.extensions if hasattr(e, "driven")), {})
        if rovers:
            groups += "; rovers " + ", ".join(f"/{r}/cmd_vel" for r in rovers)
        click.echo(
            f"serving {printable(str(model))} to ROS 2 as node /{node_name} (domain {domain}, "
            f"rmw_zenoh; {where}): {len(server.joint_names)} joints, {groups}; Ctrl-C to stop",
            err=True,
        )

    # Ctrl-C and SIGTERM unwind through here (the session closed on the way out): the
    # command's one line and exit code are every command's (command_runner)
    serve(served, ready)
