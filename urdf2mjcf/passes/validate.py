"""Validation, after the passes: compile the written MJCF in MuJoCo and step it; any warning fails.

MuJoCo's compiler is the best validator of MJCF there is. Stepping for a
second from the home keyframe (its controls hold the home pose) catches what
compiles but cannot simulate (unstable inertias, bad constraints); MuJoCo
reports those as warnings,
which we treat as failures of the conversion. Sensors are evaluated in the
first and the last step only (see :func:`run`).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ValidationError
from ..mjcf.compile import (
    LOCK,
    PassiveRun,
    compile_xml,
    files_named,
    home_data,
    passive_steps,
    start_passive_second,
    step_with_energy,
    warning_handler,
    without_visuals,
)
from ..untrusted import check_regular

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ValidateConfig:
    enabled: bool = True
    duration: float = 1.0
    """Seconds of simulated time to step (at most :attr:`max_steps` steps)."""
    max_steps: int = 10_000
    """Most steps validation takes, whatever the model's timestep: a timestep below
    ``duration / max_steps`` (0.1 ms) simulates less than ``duration`` (said in a
    debug log), so a tiny ``<option timestep>`` cannot make validation run forever."""
    passive_second: bool = False
    """Also step the certificate's passive second (:func:`~urdf2mjcf.mjcf.compile.passive_second`):
    for a model without actuators it is the second above, stepped once with the energy
    read; else a copy of the model steps it in a thread beside. What it finds is the
    certificate's to judge, not validation's."""


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
    passive: PassiveRun | None = field(default=None, repr=False, compare=False)
    """The passive second, when :attr:`ValidateConfig.passive_second` asked for it."""


def run(
    xml_path: Path,
    cfg: ValidateConfig,
    *,
    report_as: Path | None = None,
    files: Sequence[str] | None = None,
    documents: Mapping[str, Any] | None = None,
) -> ValidationResult | None:
    """Compile ``xml_path`` (all includes and assets beside it) and simulate it.

    ``report_as`` is the file name used in error messages (the final output
    path rather than the temporary one we validate in). ``files``: the names,
    relative to its folder, of every file the model reads (``xml_path``'s
    own included); they are read from disk and compiled from memory under
    those names, as the other passes compile, so MuJoCo's mesh cache answers
    (see :mod:`urdf2mjcf.mjcf.compile`).

    With ``files``, the second of simulation runs on the model's physics twin
    (its documents without the visual geoms, :func:`~urdf2mjcf.mjcf.compile.without_visuals`:
    the same bodies, joints, colliding geoms and actuators, so the same
    trajectory bit for bit) in a thread while the whole model compiles: MuJoCo
    releases the GIL in both, and on two cores the stepping costs no time. The
    whole model is still compiled, and its sensors evaluated at home.
    ``documents``: the MJCF files among ``files`` as the element trees they were
    written from (name -> root): the twin is made from those, not parsed again.
    """
    if not cfg.enabled:
        return None
    import mujoco

    shown = report_as or xml_path
    warnings: list[str] = []
    with LOCK:
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(warning_handler(warnings))
        twin: _Stepper | None = None
        passive: PassiveRun | None = None
        try:
            try:
                if files is None:  # MuJoCo opens it (and what it names) itself
                    check_regular(xml_path, "description", error=ValidationError, what="model")
                    m = mujoco.MjModel.from_xml_path(str(xml_path))
                else:
                    written = {name: (xml_path.parent / name).read_bytes() for name in files}
                    physics = _physics_files(written, documents or {})
                    if physics is not None:
                        twin = _Stepper(written[xml_path.name], physics, cfg, warnings)
                        twin.start()
                    m = compile_xml(written[xml_path.name], written, warnings)
            except ValueError as exc:
                message = " ".join(str(exc).split())
                raise ValidationError(f"MuJoCo rejected the model: {message}", file=shown) from None
            if twin is not None:
                twin.join()
                if twin.rejected:  # something used what the twin left out: step the whole
                    twin = None
            if twin is None:
                d, steps, passive = _simulate_both(m, cfg, warnings)
            else:
                try:  # the whole model's sensors at home (rays see visual geoms too)
                    mujoco.mj_forward(m, home_data(m))
                except mujoco.FatalError as exc:
                    raise _fatal(exc, m, cfg, shown) from None
                d, steps, passive = twin.data, twin.steps, twin.passive
            if isinstance(d, Exception):  # the model stepped says how big its arena is
                raise _fatal(d, m if twin is None else twin.model, cfg, shown) from None
        finally:
            if twin is not None:
                twin.join()  # never leave it warning into a restored (default: a log file) handler
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
    return ValidationResult(
        m.nbody, m.njnt, m.ngeom, m.nmesh, m.nq, steps, model=m, passive=passive
    )


def _simulate(m: Any, cfg: ValidateConfig, warnings: list[str]) -> tuple[Any, int]:
    """Step ``m`` for ``cfg.duration`` from home: (its data, or the FatalError that
    stopped it; the steps asked for)."""
    import mujoco

    d = home_data(m)
    steps = step_count(cfg, float(m.opt.timestep))
    # Sensors read the state and never change it, so they are evaluated in the
    # first and the last step (one MuJoCo cannot evaluate still fails), not in
    # every step between: a lidar's rangefinders (1636 rays on tiago_pro) cost
    # thirty times the physics. The trajectory is the same either way.
    flags = m.opt.disableflags
    quiet = flags | int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    # The steps between go to MuJoCo in one call: it holds no GIL meanwhile, so a
    # thread beside (the certificate's) cannot make each step wait for it.
    between = max(0, steps - 2)
    try:
        for count, sensors in ((1, True), (between, False), (steps - 1 - between, True)):
            if count and not warnings:
                m.opt.disableflags = flags if sensors else quiet
                mujoco.mj_step(m, d, nstep=count)
    except mujoco.FatalError as exc:
        return exc, steps
    finally:
        m.opt.disableflags = flags
    return d, steps


def _simulate_both(
    m: Any, cfg: ValidateConfig, warnings: list[str]
) -> tuple[Any, int, PassiveRun | None]:
    """:func:`_simulate`, and the passive second when ``cfg`` asks (None: not asked, or
    it failed: the certificate steps it then). A robot without actuators steps the
    same trajectory passively: its second is the passive one, stepped once with the
    energy read (a warning still fails validation); else the passive second steps a
    copy of ``m`` in a thread beside."""
    if not cfg.passive_second:
        return (*_simulate(m, cfg, warnings), None)
    if m.nu == 0 and step_count(cfg, float(m.opt.timestep)) == passive_steps(m):
        return _simulate_with_energy(m, cfg, warnings)
    import copy

    passive = start_passive_second(copy.copy(m), home_data(m))
    d, steps = _simulate(m, cfg, warnings)
    try:
        return d, steps, passive.result()
    except Exception:  # pragma: no cover - passive_second catches MuJoCo's errors
        log.debug("passive second not stepped", exc_info=True)
        return d, steps, None


def _simulate_with_energy(
    m: Any, cfg: ValidateConfig, warnings: list[str]
) -> tuple[Any, int, PassiveRun | None]:
    """:func:`_simulate` of a model without actuators, as the passive second steps it:
    the sensors evaluated at home and at the end."""
    import mujoco

    d = home_data(m)
    steps = step_count(cfg, float(m.opt.timestep))
    run, fatal = step_with_energy(m, d, steps)
    if fatal is not None:
        return fatal, steps, None
    if run.diverged_at is None:
        try:
            mujoco.mj_forward(m, d)  # the sensors at the end
        except mujoco.FatalError as exc:
            return exc, steps, None
    return d, steps, run


def step_count(cfg: ValidateConfig, timestep: float) -> int:
    """Steps that simulate ``cfg.duration`` at ``timestep``, at most ``cfg.max_steps``
    (and at least one)."""
    wanted = cfg.duration / timestep if timestep > 0 and math.isfinite(timestep) else math.inf
    if not wanted <= cfg.max_steps:  # NaN included
        log.debug(
            "timestep %g s: validation steps %d times (%g s), not %g s",
            timestep,
            cfg.max_steps,
            cfg.max_steps * timestep if math.isfinite(timestep) else 0.0,
            cfg.duration,
        )
        return cfg.max_steps
    return max(1, int(round(wanted)))


def _physics_files(
    written: dict[str, bytes], documents: Mapping[str, Any] | None = None
) -> dict[str, bytes] | None:
    """``written`` with each MJCF document's visual geoms left out, where
    :func:`without_visuals` finds that safe, and only the files the documents
    still name; None when no document has a visual geom to leave out. A document in
    ``documents`` (its element tree) is stripped from the tree."""
    from lxml import etree

    stripped = {}
    for name, data in written.items():
        if not name.endswith(".xml"):
            continue
        tree = (documents or {}).get(name)
        lean = without_visuals(tree if tree is not None else data)
        if lean is not None:
            stripped[name] = lean if tree is None else etree.tostring(lean)
    if not stripped:
        return None
    twin = {**written, **stripped}
    return files_named(twin, *(data for name, data in twin.items() if name.endswith(".xml")))


class _Stepper(threading.Thread):
    """Compiles the physics twin and simulates it, beside the whole model's compile.
    Warnings go to the handler the caller set (MuJoCo's is process-wide)."""

    def __init__(
        self, xml: bytes, files: dict[str, bytes], cfg: ValidateConfig, warnings: list[str]
    ):
        super().__init__(name="urdf2mjcf-validate", daemon=True)
        self.xml, self.files, self.cfg, self.warnings = xml, files, cfg, warnings
        self.rejected = False
        self.data: Any = None
        self.model: Any = None
        self.steps = 0
        self.passive: PassiveRun | None = None

    def run(self) -> None:
        import mujoco

        try:
            m = mujoco.MjModel.from_xml_string(self.xml.decode(), self.files)
        except ValueError:
            self.rejected = True
            return
        finally:
            self.files = {}  # the bytes are the caller's; keep no second reference
        self.model = m
        self.data, self.steps, self.passive = _simulate_both(m, self.cfg, self.warnings)


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
