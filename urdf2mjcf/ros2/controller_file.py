"""The controllers a user gives (``--controllers FILE``): ros2_control's own
controller_manager YAML, the file a robot's bringup already has.

Read from it: ``controller_manager: ros__parameters: <name>: {type: ...}`` and each
controller's ``<name>: ros__parameters: {joints, interface_name | command_interfaces}``.
Served: ``joint_trajectory_controller/JointTrajectoryController`` (position command
interface) on ``/<name>/joint_trajectory``; ``forward_command_controller/
ForwardCommandController`` and ``{position,velocity,effort}_controllers/
JointGroup{Position,Velocity,Effort}Controller`` on ``/<name>/commands``.
``joint_state_broadcaster/JointStateBroadcaster`` is what the server publishes
anyway; any other type is left out with a warning. Every joint must have an
actuator of the controller's interface (the conversion made them from the same
description's ``ros2_control`` tags), else one error naming the file and the key.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ControllerFileError
from ..schema import load
from .controllers import KINDS, Group

log = logging.getLogger(__name__)

TRAJECTORY = "joint_trajectory_controller/JointTrajectoryController"
FORWARD = {
    "position_controllers/JointGroupPositionController": "position",
    "velocity_controllers/JointGroupVelocityController": "velocity",
    "effort_controllers/JointGroupEffortController": "effort",
    "forward_command_controller/ForwardCommandController": None,  # interface_name says
    "forward_command_controller/MultiInterfaceForwardCommandController": None,
}
SILENT = {"joint_state_broadcaster/JointStateBroadcaster"}


@dataclass(frozen=True)
class Controllers:
    forward: tuple[Group, ...]
    """``/<name>/commands``"""
    trajectory: tuple[Group, ...]
    """``/<name>/joint_trajectory`` (position groups)"""


def _params(data: dict, name: str, path: Path) -> dict:
    block = data.get(name, {})
    params = block.get("ros__parameters", {}) if isinstance(block, dict) else None
    if not isinstance(params, dict):
        raise ControllerFileError("is not a mapping", file=path, element=f"{name}.ros__parameters")
    return params


def read(path: Path, m: mujoco.MjModel, kinds: dict[int, str]) -> Controllers:
    """The controllers of ``path`` over ``m``'s actuators (``kinds``: actuator id ->
    its interface, as :func:`.controllers.actuator_kind` says)."""
    data, _ = load(path, "controllers file", ControllerFileError)
    if not isinstance(data, dict):
        raise ControllerFileError("is not a mapping of controllers", file=path)
    manager = _params(data, "controller_manager", path)
    by_joint: dict[str, tuple[int, str]] = {}
    for a, kind in kinds.items():
        j = int(m.actuator_trnid[a, 0])
        by_joint[mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or ""] = (a, kind)
    forward: list[Group] = []
    trajectory: list[Group] = []
    for name, spec in manager.items():
        if not isinstance(spec, dict) or "type" not in spec:
            continue  # update_rate and the manager's other parameters
        kind_of = str(spec["type"])
        where = f"controller_manager.ros__parameters.{name}.type"
        if kind_of in SILENT:
            continue
        if kind_of != TRAJECTORY and kind_of not in FORWARD:
            log.warning("%s: %s: %s is not served (left out)", path, where, kind_of)
            continue
        params = _params(data, str(name), path)
        joints = params.get("joints")
        if (
            not isinstance(joints, list)
            or not joints
            or not all(isinstance(j, str) for j in joints)
        ):
            raise ControllerFileError(
                "needs a list of joint names", file=path, element=f"{name}.ros__parameters.joints"
            )
        if kind_of == TRAJECTORY:
            interfaces = params.get("command_interfaces", ["position"])
            if interfaces != ["position"]:
                raise ControllerFileError(
                    f"{interfaces} served: only [position]",
                    file=path,
                    element=f"{name}.ros__parameters.command_interfaces",
                )
            kind = "position"
        else:
            kind = FORWARD[kind_of] or str(params.get("interface_name", ""))
            if kind not in KINDS:
                raise ControllerFileError(
                    f"interface '{kind}'; served: {', '.join(KINDS)}",
                    file=path,
                    element=f"{name}.ros__parameters.interface_name",
                )
        acts = []
        for j in joints:
            found = by_joint.get(j)
            if found is None or found[1] != kind:
                what = "no actuator" if found is None else f"a {found[1]} actuator"
                raise ControllerFileError(
                    f"joint '{j}' has {what} in the model, not a {kind} one",
                    file=path,
                    element=f"{name}.ros__parameters.joints",
                )
            acts.append(found[0])
        low = np.array(
            [m.actuator_ctrlrange[a, 0] if m.actuator_ctrllimited[a] else -np.inf for a in acts]
        )
        high = np.array(
            [m.actuator_ctrlrange[a, 1] if m.actuator_ctrllimited[a] else np.inf for a in acts]
        )
        group = Group(str(name), kind, tuple(joints), tuple(acts), low, high)
        (trajectory if kind_of == TRAJECTORY else forward).append(group)
    return Controllers(tuple(forward), tuple(trajectory))
