"""A calibration (``calibration.yaml``) read, and written into an MJCF document.

The file, as ``urdf2mjcf calibrate`` writes it and ``urdf2mjcf SOURCE --calibration FILE``
applies it on every later conversion::

    joints:
      elbow: {damping: 0.9, frictionloss: 0.4, armature: 0.02}
    actuators:
      elbow: {kp: 412.3}            # kp (position), kv (velocity) or gain (general)
    bodies:
      fore: {mass: 1.1}             # kg; the inertia scaled with it
    payload: {body: fore, mass: 1.5}  # kg at the body's origin
    delay: 0.005                    # s, the sensors' delay (reported; MJCF has no place)

A name the document lacks (a joint renamed or removed since) is a warning, not an error:
the rest still applies.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from lxml import etree

from .. import schema
from ..errors import InputError
from ..fmt import fmt_float, fmt_vec
from ..ir import Note
from ..mjcf.document import Document

log = logging.getLogger(__name__)

JOINT_KEYS = ("damping", "frictionloss", "armature")
ACTUATOR_KEYS = ("kp", "kv", "gain")
SECTIONS = ("joints", "actuators", "bodies", "payload", "delay")


@dataclass(frozen=True)
class Calibration:
    """Identified values by name."""

    joints: Mapping[str, Mapping[str, float]]
    actuators: Mapping[str, Mapping[str, float]]
    bodies: Mapping[str, Mapping[str, float]]
    payload: tuple[str, float] | None = None
    """(body, kg) at the body's origin."""
    delay: float = 0.0
    """Seconds."""

    def as_data(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "joints": {k: dict(v) for k, v in self.joints.items()},
            "actuators": {k: dict(v) for k, v in self.actuators.items()},
            "bodies": {k: dict(v) for k, v in self.bodies.items()},
        }
        if self.payload is not None:
            data["payload"] = {"body": self.payload[0], "mass": self.payload[1]}
        if self.delay:
            data["delay"] = self.delay
        return {k: v for k, v in data.items() if v}


def load(path: Path) -> Calibration:
    """The calibration file at ``path``; :class:`InputError` naming the key when it is
    not one."""
    data, _ = schema.load(path, "calibration file")
    data = {} if data is None else data
    if not isinstance(data, dict) or set(data) - set(SECTIONS):
        raise InputError(f"a calibration file is a mapping of {', '.join(SECTIONS)}", file=path)

    def numbers(section: str, keys: tuple[str, ...]) -> dict[str, dict[str, float]]:
        entries = data.get(section) or {}
        if not isinstance(entries, dict):
            raise InputError("expected a mapping NAME: {KEY: VALUE}", file=path, element=section)
        out: dict[str, dict[str, float]] = {}
        for name, values in entries.items():
            if not isinstance(values, dict):
                raise InputError(
                    f"expected a mapping of {', '.join(keys)}",
                    file=path,
                    element=f"{section}.{name}",
                )
            out[str(name)] = {}
            for key, value in values.items():
                out[str(name)][key] = _number(value, keys, key, path, f"{section}.{name}.{key}")
        return out

    payload = data.get("payload")
    body_mass: tuple[str, float] | None = None
    if payload is not None:
        if not isinstance(payload, dict) or set(payload) != {"body", "mass"}:
            raise InputError("expected {body: BODY, mass: KG}", file=path, element="payload")
        body_mass = (
            str(payload["body"]),
            _number(payload["mass"], ("mass",), "mass", path, "payload.mass"),
        )
    delay = data.get("delay", 0.0)
    return Calibration(
        numbers("joints", JOINT_KEYS),
        numbers("actuators", ACTUATOR_KEYS),
        numbers("bodies", ("mass",)),
        body_mass,
        _number(delay, ("delay",), "delay", path, "delay"),
    )


def _number(value: Any, keys: tuple[str, ...], key: Any, path: Path, where: str) -> float:
    if key not in keys:
        raise InputError(
            f"unknown key {key!r}; expected {', '.join(keys)}", file=path, element=where
        )
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value < 0
    ):
        raise InputError("expected a finite number >= 0", file=path, element=where)
    return float(value)


def calibrated(result: Document, path: Path) -> Document:
    """The converter's step (``--calibration FILE``): ``result`` with the file's values
    written into a copy of its document, a warning note for each name it lacks."""
    calib = load(path)
    root = result.edit()
    notes = tuple(Note("warning", f"calibration '{path}'", w) for w in apply(root, calib))
    return replace(result, root=root, notes=result.notes + notes)


def apply(root: etree._Element, calib: Calibration) -> list[str]:
    """Write ``calib`` into the MJCF document ``root`` (changed in place); the warnings,
    one sentence each, for names the document lacks."""
    warnings = []
    joints = {el.get("name"): el for el in root.iter("joint")}
    for name, values in sorted(calib.joints.items()):
        el = joints.get(name)
        if el is None:
            warnings.append(
                f"calibration: the model has no joint '{name}'; its values are not applied"
            )
            continue
        for key, value in values.items():
            el.set(key, fmt_float(value))
    acts = {el.get("name"): el for el in root.iter("position", "velocity", "motor", "general")}
    for name, values in sorted(calib.actuators.items()):
        el = acts.get(name)
        if el is None:
            warnings.append(
                f"calibration: the model has no actuator '{name}'; its gain is not applied"
            )
            continue
        for key, value in values.items():
            if el.tag == "position" and key == "kp" or el.tag == "velocity" and key == "kv":
                el.set(key, fmt_float(value))
            elif el.tag == "general" and key == "gain":
                gains = (el.get("gainprm") or "1").split()
                el.set("gainprm", " ".join([fmt_float(value)] + gains[1:]))
            else:
                warnings.append(
                    f"calibration: actuator '{name}' is a <{el.tag}>, which has no {key}; "
                    "not applied"
                )
    bodies = {el.get("name"): el for el in root.iter("body")}
    for name, values in sorted(calib.bodies.items()):
        body = bodies.get(name)
        inertial = body.find("inertial") if body is not None else None
        if inertial is None:
            warnings.append(
                f"calibration: the model has no body '{name}' with an inertial; its mass "
                "is not applied"
            )
            continue
        old = float(inertial.get("mass", "0") or 0)
        new = values["mass"]
        inertial.set("mass", fmt_float(new))
        for attr in ("diaginertia", "fullinertia"):
            if inertial.get(attr) and old > 0:
                inertial.set(
                    attr, fmt_vec(float(x) * new / old for x in inertial.get(attr, "").split())
                )
    if calib.payload is not None and calib.payload[1] > 0:
        body_name, mass = calib.payload
        body = bodies.get(body_name)
        if body is None:
            warnings.append(
                f"calibration: the model has no body '{body_name}'; the payload is not applied"
            )
        else:
            payload = etree.SubElement(body, "body", name=f"{body_name}_payload")
            etree.SubElement(
                payload,
                "inertial",
                pos="0 0 0",
                mass=fmt_float(mass),
                diaginertia="1e-09 1e-09 1e-09",
            )
    return warnings
