"""The calibration chained: model and logs read, parameters fitted, files made."""

from __future__ import annotations

import copy
import logging
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from lxml import etree

from .. import mjcf_files
from ..errors import InputError
from ..mjcf.document import mjcf_bytes
from . import apply as calib_apply
from . import fit as fitting
from . import logs, params, report

log = logging.getLogger(__name__)

OUTPUT_FILES = ("robot.xml", "calibration.yaml", "report.html", "report.json")
"""What a calibration writes into its folder (``report.json``, the manifest, last)."""

GENERATOR = "urdf2mjcf calibrate"
"""``"generator"`` of ``report.json`` (an earlier run's files are replaced by a new one)."""


@dataclass(frozen=True)
class CalibrateConfig:
    free: tuple[str, ...] = params.DEFAULT_FREE
    """Kinds freed for every joint, actuator or body (:data:`params.KINDS`)."""
    params_file: Path | None = None
    holdout: tuple[Path, ...] = ()
    """Whole logs kept out of the fit; none: the last :attr:`holdout_fraction` of each."""
    holdout_fraction: float = 0.2
    fit: fitting.FitConfig = field(default_factory=fitting.FitConfig)


@dataclass(frozen=True)
class Outcome:
    summary: report.Summary
    calibration: calib_apply.Calibration
    files: dict[str, bytes]
    """``robot.xml``, ``calibration.yaml``, ``report.html`` and ``report.json`` (last)."""


def calibrate(
    model_path: Path, log_paths: Sequence[Path], out: Path, cfg: CalibrateConfig
) -> Outcome:
    """Fit the model at ``model_path`` to the logs; the files to write into ``out``."""
    from ..mjcf_input import load_model

    m = load_model(model_path)
    joints = params.joint_names(m)
    floating = params.floating_base(m)
    actuators = params.actuator_names(m)
    servos = params.position_servos(m)
    if not m.nu:
        raise InputError(
            "the model has no actuators: a log's commands would drive nothing", file=model_path
        )
    free = params.select(m, cfg.free, cfg.params_file)
    dt = float(m.opt.timestep)
    fitted: list[logs.Trajectory] = []
    held: list[logs.Trajectory] = []

    def trajectory(p: Path) -> logs.Trajectory:
        found = logs.read(p, actuators, servos, floating)
        return logs.resample(found, joints, actuators, dt, floating)

    for p in log_paths:
        tr = trajectory(p)
        if cfg.holdout:
            fitted.append(tr)
        else:
            head, tail = tr.split(cfg.holdout_fraction)
            fitted.append(head)
            held.append(tail)
    for p in cfg.holdout:
        held.append(trajectory(p))
    applier = params.Applier(m, free)
    history = fitting.history(applier)  # rows a replay with the longest delay reads first
    short = [t.name for t in fitted + held if len(t.q) < 4 + history]
    if short:
        raise InputError(
            f"too little data in {short[0]}: a log must span several model timesteps"
            + (f" after the delay's upper bound ({history} of them)" if history else "")
        )
    start = time.perf_counter()
    replay = fitting.Replay(applier, fitted, cfg.fit)
    nominal = np.array([p.nominal for p in free])
    before_fitted = replay.tracking(nominal)
    result = fitting.fit(replay, free, cfg.fit)
    seconds = time.perf_counter() - start
    after_fitted = replay.tracking(result.x)
    held_replay = fitting.Replay(applier, held, cfg.fit) if held else None
    summary = report.Summary(
        result,
        joints,
        before_fitted,
        after_fitted,
        held_replay.tracking(nominal) if held_replay else None,
        held_replay.tracking(result.x) if held_replay else None,
        seconds,
        replay.samples,
        ", ".join(str(p) for p in cfg.holdout)
        or f"the last {cfg.holdout_fraction:.0%} of each log",
        fitting.force_limited(applier.model(result.x), fitted, applier.delay(result.x)),
    )
    for w in report.warnings(result, summary.force_limited):
        log.warning("%s", w)
    calibration = _calibration(result)
    robot = _robot_xml(model_path, out, calibration)
    data = report.as_json(summary)
    text = yaml.safe_dump(calibration.as_data(), sort_keys=True, default_flow_style=False)
    files = {
        "robot.xml": robot,
        "calibration.yaml": text.encode(),
        "report.html": report.as_html(summary, data).encode(),
    }
    return Outcome(
        summary, calibration, {**files, "report.json": _json(data, sorted([*files, "report.json"]))}
    )


def _json(data: dict[str, Any], files: list[str]) -> bytes:
    from ..output import json_bytes

    return json_bytes({**data, "files": files}, GENERATOR)


def _calibration(result: fitting.FitResult) -> calib_apply.Calibration:
    joints: dict[str, dict[str, float]] = {}
    acts: dict[str, dict[str, float]] = {}
    bodies: dict[str, dict[str, float]] = {}
    payload = None
    delay = 0.0
    for p, x in zip(result.params, result.x, strict=True):
        value = report.rounded(float(x))
        if p.field in params.JOINT_FIELDS:
            joints.setdefault(p.target, {})[p.field] = value
        elif p.field in params.GAIN_FIELDS:
            acts.setdefault(p.target, {})[p.field] = value
        elif p.field == "mass":
            bodies.setdefault(p.target, {})["mass"] = value
        elif p.field == "payload":
            payload = (p.target, value)
        else:
            delay = value
    return calib_apply.Calibration(joints, acts, bodies, payload, delay)


def _robot_xml(model_path: Path, out: Path, calibration: calib_apply.Calibration) -> bytes:
    """The model's document with the calibration written in, its file references made
    relative to ``out`` (so that ``OUT/robot.xml`` finds the model's meshes where they are)."""
    # the document as MuJoCo reads it: every include expanded in place
    root = copy.deepcopy(mjcf_files.read_model(model_path, error=InputError).root)
    for w in calib_apply.apply(root, calibration):
        log.warning("%s", w)
    here = model_path.resolve().parent
    there = out.resolve()

    def moved(rel: str) -> str:
        return os.path.relpath(here / rel, there) if not os.path.isabs(rel) else rel

    compiler = root.find("compiler")
    if compiler is None:
        compiler = etree.Element("compiler")
        root.insert(0, compiler)
    dirs = [a for a in ("meshdir", "texturedir", "assetdir") if compiler.get(a) is not None]
    for attr in dirs:
        compiler.set(attr, moved(compiler.get(attr, "")))
    if not dirs:
        compiler.set("assetdir", moved("."))
    return mjcf_bytes(root)
