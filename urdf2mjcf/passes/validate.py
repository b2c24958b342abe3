"""Pass 7: compile the written MJCF with MuJoCo and step it; any warning fails.

MuJoCo's compiler is the best validator of MJCF there is. Stepping for a
second with zero controls catches what compiles but cannot simulate
(unstable inertias, bad constraints); MuJoCo reports those as warnings,
which we treat as failures of the conversion.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from pathlib import Path

from ..errors import ValidationError

log = logging.getLogger(__name__)
_LOCK = threading.Lock()  # the user warning callback is process-global


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


def run(
    xml_path: Path, cfg: ValidateConfig, *, report_as: Path | None = None
) -> ValidationResult | None:
    """Compile ``xml_path`` (all includes and assets beside it) and simulate it.

    ``report_as`` is the file name used in error messages (the final output
    path rather than the temporary one we validate in).
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
                m = mujoco.MjModel.from_xml_path(str(xml_path))
            except ValueError as exc:
                message = " ".join(str(exc).split())
                raise ValidationError(f"MuJoCo rejected the model: {message}", file=shown) from None
            d = mujoco.MjData(m)
            if m.nkey:
                mujoco.mj_resetDataKeyframe(m, d, 0)
            steps = int(round(cfg.duration / m.opt.timestep))
            try:
                for _ in range(steps):
                    mujoco.mj_step(m, d)
                    if warnings:
                        break
            except mujoco.FatalError as exc:
                raise _fatal(exc, m, cfg, shown) from None
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
    return ValidationResult(m.nbody, m.njnt, m.ngeom, m.nmesh, m.nq, steps)


def _fatal(exc: Exception, m, cfg: ValidateConfig, shown: Path) -> ValidationError:
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
