"""Pass 7: compile the written MJCF with MuJoCo and step it; any warning fails.

MuJoCo's compiler is the best validator of MJCF there is. Stepping for a
second from the home keyframe (its controls hold the home pose) catches what
compiles but cannot simulate (unstable inertias, bad constraints); MuJoCo
reports those as warnings,
which we treat as failures of the conversion. Sensors are evaluated in the
first and the last step only (see :func:`run`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ValidationError
from ..mjmodel import LOCK as _LOCK
from ..mjmodel import compile_xml, home_data

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ValidateConfig:
    enabled: bool = True
    duration: float = 1.0
    """Seconds of simulated time to step."""


@dataclass(frozen=True)
class ValidationResult:
    nbody: int
    njnt: int
    ngeom: int
    nmesh: int
    nq: int
    steps: int
    model: Any = field(default=None, repr=False, compare=False)
    """The ``mujoco.MjModel`` validated, for whoever reads the same document next."""


def run(
    xml_path: Path,
    cfg: ValidateConfig,
    *,
    report_as: Path | None = None,
    files: Sequence[str] | None = None,
) -> ValidationResult | None:
    """Compile ``xml_path`` (all includes and assets beside it) and simulate it.

    ``report_as`` is the file name used in error messages (the final output
    path rather than the temporary one we validate in). ``files``: the names,
    relative to its folder, of every file the model reads (``xml_path``'s
    own included); they are read from disk and compiled from memory under
    those names, as the other passes compile, so MuJoCo's mesh cache answers
    (see :mod:`urdf2mjcf.mjmodel`).
    """
    if not cfg.enabled:
        return None
    import mujoco

    shown = report_as or xml_path
    warnings: list[str] = []
    with _LOCK:
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(lambda msg: warnings.append(str(msg).strip()))
        try:
            try:
                if files is None:
                    m = mujoco.MjModel.from_xml_path(str(xml_path))
                else:
                    written = {name: (xml_path.parent / name).read_bytes() for name in files}
                    m = compile_xml(written[xml_path.name], written, warnings)
            except ValueError as exc:
                message = " ".join(str(exc).split())
                raise ValidationError(f"MuJoCo rejected the model: {message}", file=shown) from None
            d = home_data(m)
            steps = int(round(cfg.duration / m.opt.timestep))
            # Sensors read the state and never change it, so they are evaluated in the
            # first and the last step (one MuJoCo cannot evaluate still fails), not in
            # every step between: a lidar's rangefinders (1636 rays on tiago_pro) cost
            # thirty times the physics. The trajectory is the same either way.
            flags = m.opt.disableflags
            quiet = flags | int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
            try:
                for i in range(steps):
                    m.opt.disableflags = flags if i in (0, steps - 1) else quiet
                    mujoco.mj_step(m, d)
                    if warnings:
                        break
            except mujoco.FatalError as exc:
                raise _fatal(exc, m, cfg, shown) from None
            finally:
                m.opt.disableflags = flags
        finally:
            mujoco.set_mju_user_warning(previous)
    raised = [
        f"{mujoco.mjtWarning(i).name} x{d.warning[i].number}"
        for i in range(len(d.warning))
        if d.warning[i].number > 0
    ]
    if warnings or raised:
        detail = "; ".join(warnings + raised)
        raise ValidationError(
            f"MuJoCo warned while simulating {cfg.duration:g} s: {detail}", file=shown
        )
    log.debug("validated %s: nbody=%d nq=%d", shown, m.nbody, m.nq)
    return ValidationResult(m.nbody, m.njnt, m.ngeom, m.nmesh, m.nq, steps, model=m)


def _fatal(exc: Exception, m: Any, cfg: ValidateConfig, shown: Path) -> ValidationError:
    """MuJoCo's fatal error while stepping, on one line; for its arena (a long robot
    lying on the floor has thousands of contacts) the limit and how to raise it."""
    message = " ".join(str(exc).split())
    if "mj_stackAlloc" in message or "arena" in message:
        arena = int(m.narena)
        message = (
            f"MuJoCo ran out of its {arena / 2**20:.0f} MiB arena "
            f"(contacts and constraints) while simulating {cfg.duration:g} s: {message}; "
            f'give it more with <mujoco><size memory="{4 * arena // 2**20}M"/></mujoco> '
            "in the URDF"
        )
    else:
        message = f"MuJoCo stopped while simulating {cfg.duration:g} s: {message}"
    return ValidationError(message, file=shown)

