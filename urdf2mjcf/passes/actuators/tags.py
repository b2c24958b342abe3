"""What a URDF's ``<ros2_control>`` and ``<transmission>`` blocks say about actuators.

Only the joint-level meaning is read: which command interface a joint has and
the parameters of its servo. Hardware blocks (``gazebo_ros2_control``,
``gz_ros2_control``, ``mujoco_ros2_control``, ``mock_components``) and
``<sensor>``/``<gpio>`` elements are left alone: the command interface means
the same whatever simulates it.

``<ros2_control>``: each ``<joint name>`` with a ``<command_interface name>``
of ``position``, ``velocity`` or ``effort``. A joint with several takes the
first of position, velocity, effort: ros2_control switches interfaces at run
time as controllers claim them, a MuJoCo actuator is fixed when the model is
compiled, and a position servo is the one that holds the robot by itself.
Parameters (``<param name="...">``, on the ``<joint>`` or inside the chosen
command interface, the latter winning): ``kp`` (alias ``p``), ``kv`` (aliases ``kd``,
``d``), ``armature``, ``damping``, ``friction`` (alias ``frictionloss``),
``force_limit`` (aliases ``max_effort``, ``effort_limit``); ``min`` and ``max``
inside the command interface give the command range. Other parameters are
ignored.

``<transmission>`` (ROS 1): ``hardwareInterface`` under ``<joint>`` (or, when
the joint has none, under ``<actuator>``): ``PositionJointInterface`` (and
``PosVel``, ``PosVelAcc``), ``VelocityJointInterface``,
``EffortJointInterface``, with or without the ``hardware_interface/`` prefix.
A PR2-style transmission without any is taken as effort (its controllers were
effort controllers). ``mechanicalReduction`` is ignored, with a note when it
is not 1: ROS controllers command the joint, not the motor, and URDF effort
limits are joint-side, so the reduction does not change the joint-space
actuator. Coupled transmissions (differential, four-bar) give each joint its
own actuator, with a warning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from lxml import etree

from ...errors import URDFError
from ...ir import Note, Robot
from .config import ActuatorSpec

_INTERFACE_KIND = {"position": "position", "velocity": "velocity", "effort": "motor"}
_PREFERENCE = ("position", "velocity", "motor")
_PARAM_FIELD = {
    "kp": "kp",
    "p": "kp",
    "kv": "kv",
    "kd": "kv",
    "d": "kv",
    "armature": "armature",
    "damping": "damping",
    "friction": "frictionloss",
    "frictionloss": "frictionloss",
    "force_limit": "force_limit",
    "max_effort": "force_limit",
    "effort_limit": "force_limit",
}
_HARDWARE_INTERFACE = {
    "PositionJointInterface": "position",
    "PosVelJointInterface": "position",
    "PosVelAccJointInterface": "position",
    "VelocityJointInterface": "velocity",
    "EffortJointInterface": "motor",
}
_STATE_INTERFACES = ("JointStateInterface",)


@dataclass(frozen=True)
class ControlTags:
    specs: dict[str, ActuatorSpec]
    """Joint name -> what the URDF says (ros2_control wins over transmission)."""
    sources: dict[str, str]
    """Joint name -> ``ros2_control`` or ``transmission``."""
    notes: tuple[Note, ...] = ()


def read(robot: Robot) -> ControlTags:
    """Joint actuators declared by the robot's ``<ros2_control>`` and ``<transmission>``."""
    notes: list[Note] = []
    ros2: dict[str, ActuatorSpec] = {}
    trans: dict[str, ActuatorSpec] = {}
    for ext in robot.extensions:
        if ext.tag == "ros2_control":
            _ros2_control(_element(ext.xml, robot), robot, ros2, notes)
        elif ext.tag == "transmission":
            _transmission(_element(ext.xml, robot), trans, notes)
    specs, sources = dict(ros2), dict.fromkeys(ros2, "ros2_control")
    for name, spec in trans.items():
        if name in ros2:
            notes.append(
                Note(
                    "info",
                    f"joint '{name}'",
                    "in both ros2_control and a transmission; ros2_control is used",
                )
            )
            continue
        specs[name], sources[name] = spec, "transmission"
    return ControlTags(specs, sources, tuple(notes))


def initial_positions(robot: Robot) -> dict[str, float]:
    """Joint name -> ``initial_value`` of its ros2_control position state interface.

    This is how ROS 2 descriptions give the pose a simulated robot starts in
    (mock_components, gazebo_ros2_control and mujoco_ros2_control read it);
    emit makes it the ``home`` keyframe.
    """
    out: dict[str, float] = {}
    for ext in robot.extensions:
        if ext.tag != "ros2_control":
            continue
        for jel in _children(_element(ext.xml, robot), "joint"):
            name = (jel.get("name") or "").strip()
            for si in _children(jel, "state_interface"):
                if (si.get("name") or "").strip().lower() != "position":
                    continue
                for pel in _children(si, "param"):
                    if (pel.get("name") or "").strip() == "initial_value":
                        where = f"ros2_control joint '{name}' initial_value"
                        try:
                            value = float(_text(pel))
                        except ValueError:
                            raise URDFError(
                                f"'{_text(pel)}' is not a number", file=robot.source, element=where
                            ) from None
                        if name in robot.joint_map:
                            out.setdefault(name, value)
    return out


def _element(xml: str, robot: Robot) -> etree._Element:
    try:
        return etree.fromstring(xml)
    except etree.XMLSyntaxError as exc:  # parse produced it, so this is unexpected
        raise URDFError(f"extension element is not XML: {exc}", file=robot.source) from None


def _local(el: etree._Element) -> str:
    return etree.QName(el).localname if isinstance(el.tag, str) else ""


def _children(el: etree._Element, tag: str) -> list[etree._Element]:
    return [c for c in el if _local(c) == tag]


def _text(el: etree._Element) -> str:
    return (el.text or "").strip()


# -- ros2_control ------------------------------------------------------------


def _ros2_control(
    block: etree._Element, robot: Robot, out: dict[str, ActuatorSpec], notes: list[Note]
) -> None:
    system = block.get("name", "")
    for jel in _children(block, "joint"):
        name = (jel.get("name") or "").strip()
        where = f"ros2_control '{system}' joint '{name}'"
        if not name:
            notes.append(Note("warning", f"ros2_control '{system}'", "a <joint> has no name"))
            continue
        interfaces = {
            (ci.get("name") or "").strip().lower(): ci for ci in _children(jel, "command_interface")
        }
        kinds = {_INTERFACE_KIND[n]: ci for n, ci in interfaces.items() if n in _INTERFACE_KIND}
        if not kinds:
            if interfaces:
                listed = ", ".join(sorted(interfaces))
                notes.append(
                    Note(
                        "warning",
                        f"joint '{name}'",
                        f"ros2_control command interfaces ({listed}) "
                        "are none of position, velocity, effort; no actuator",
                    )
                )
            continue  # state interfaces only: a sensed, unactuated joint
        kind = next(k for k in _PREFERENCE if k in kinds)
        params = _params(jel, where, robot)
        ci_params = _params(kinds[kind], f"{where} command_interface '{kind}'", robot)
        params.update(ci_params)
        lo, hi = ci_params.get("min"), ci_params.get("max")
        spec = _spec(kind, params)
        if lo is not None or hi is not None:
            if lo is not None and hi is not None and not lo < hi:
                raise URDFError(
                    f"command interface min {lo!r} is not below max {hi!r}",
                    file=robot.source,
                    element=where,
                )
            spec = replace(spec, ctrlrange=(lo, hi))
        if name in out:
            notes.append(
                Note(
                    "warning", f"joint '{name}'", "listed twice in ros2_control; the first is used"
                )
            )
            continue
        out[name] = spec


def _params(el: etree._Element, where: str, robot: Robot) -> dict[str, float]:
    out: dict[str, float] = {}
    for pel in _children(el, "param"):
        key = (pel.get("name") or "").strip().lower()
        field = _PARAM_FIELD.get(key, key if key in ("min", "max") else None)
        if field is None:
            continue
        text = _text(pel)
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise URDFError(
                f"param {key!r} is {text!r}, expected a finite number",
                file=robot.source,
                element=where,
            )
        if field not in ("min", "max") and value < 0:
            raise URDFError(
                f"param {key!r} is {value!r}, expected >= 0", file=robot.source, element=where
            )
        out[field] = value
    return out


def _spec(kind: str, params: dict[str, float]) -> ActuatorSpec:
    limit = params.get("force_limit")
    return ActuatorSpec(
        type=kind,
        kp=params.get("kp"),
        kv=params.get("kv"),
        forcerange=None if limit is None else ((-limit, limit) if limit > 0 else (0.0, 0.0)),
        armature=params.get("armature"),
        damping=params.get("damping"),
        frictionloss=params.get("frictionloss"),
    )


# -- transmission ------------------------------------------------------------


def _interface_kind(el: etree._Element) -> list[str | None] | None:
    """Actuator kinds of the command hardwareInterfaces of ``el`` (None for unknown
    ones); None when ``el`` names no hardwareInterface at all."""
    interfaces = [_text(hw) for hw in _children(el, "hardwareInterface")]
    if not interfaces:
        return None
    short = (name.rsplit("/", 1)[-1].rsplit("::", 1)[-1] for name in interfaces)
    return [_HARDWARE_INTERFACE.get(s) for s in short if s not in _STATE_INTERFACES]


def _transmission(block: etree._Element, out: dict[str, ActuatorSpec], notes: list[Note]) -> None:
    tname = block.get("name", "")
    types = [_text(t) for t in _children(block, "type")] + [block.get("type") or ""]
    ttype = next((t for t in types if t), "")
    actuators = _children(block, "actuator")
    listed = [_interface_kind(a) for a in actuators]
    actuator_kinds = (
        None if all(k is None for k in listed) else [x for k in listed for x in k or ()]
    )
    joints = _children(block, "joint")
    if len(joints) > 1 or any(w in ttype for w in ("Differential", "FourBar")):
        notes.append(
            Note(
                "warning",
                f"transmission '{tname}'",
                f"coupled transmission ({ttype or 'several joints'}): "
                "each joint gets its own actuator; the coupling is not modelled",
            )
        )
    reductions = [
        r for el in (block, *actuators, *joints) for r in _children(el, "mechanicalReduction")
    ]
    for r in reductions:
        try:
            value = float(_text(r))
        except ValueError:
            value = math.nan
        if value != 1.0:
            notes.append(
                Note(
                    "info",
                    f"transmission '{tname}'",
                    f"mechanicalReduction {_text(r)} ignored: "
                    "the actuator commands the joint, as ROS controllers do",
                )
            )
    for jel in joints:
        name = (jel.get("name") or "").strip()
        if not name:
            continue
        kinds = _interface_kind(jel)
        if kinds is None:
            kinds = actuator_kinds
        known = [k for k in kinds or () if k is not None]
        if kinds is not None and not known:
            notes.append(
                Note(
                    "warning",
                    f"joint '{name}'",
                    f"transmission '{tname}' has no position, "
                    "velocity or effort hardwareInterface; no actuator",
                )
            )
            continue
        if kinds is None:
            notes.append(
                Note(
                    "info",
                    f"joint '{name}'",
                    f"transmission '{tname}' names no "
                    "hardwareInterface; taken as effort (PR2 style)",
                )
            )
            known = ["motor"]
        kind = next(k for k in _PREFERENCE if k in known)
        if name in out:
            notes.append(
                Note("warning", f"joint '{name}'", "in two transmissions; the first is used")
            )
            continue
        out[name] = ActuatorSpec(type=kind)
