"""The fidelity certificate: a compiled MJCF model against its URDF description.

The description is read by independent implementations of URDF (urdfdom through
pinocchio for the frames where it is installed, yourdfpy for its parts and
otherwise: :mod:`.reference`), the model is compiled by MuJoCo from the files on
disk, and the two are compared figure by figure: link frames at home and at random
configurations within the limits (:mod:`.kinematics`), joint types, axes,
anchors, limits and mimic couplings, masses and the centre of mass
(:mod:`.mass`), the mass matrix and gravity torques against pinocchio where it
is installed (:mod:`.dynamics`), collision geometry per link
(:mod:`.collision`) and the single-model lint checks run against the source
(:mod:`.checks`). What the model changed on purpose is listed
(:mod:`.changes`); every figure is held to a :class:`~.tolerances.Tolerances`.

The tolerances are :mod:`.tolerances`'s, figures that depend only on content are kept
in the cache by :mod:`.stored`, and ``urdf2mjcf verify`` is :mod:`.command`.

Used after every conversion (``api.convert``, on the staged files before they
are installed; ``--verify`` makes a failing certificate fail the conversion)
and by ``urdf2mjcf verify`` for any model against any description.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import CertificateFailed, ConversionError
from ..ir import Model, Note
from ..mjcf.compile import PassiveRun
from .kinematics import NameMap
from .reference import Reference
from .tolerances import Tolerances

log = logging.getLogger(__name__)

SAMPLES = 4
"""Random configurations besides home (the certificate's cost is linear in them)."""
DYNAMICS_SAMPLES = 3
"""Random configurations (besides home) for the mass matrix and gravity torques."""

__all__ = ["SAMPLES", "Certificate", "CertificateFailed", "CertifyConfig", "NameMap", "certify"]


@dataclass(frozen=True)
class CertifyConfig:
    """How a conversion certifies itself."""

    enabled: bool = True
    """Compute the certificate (it needs the model compiled: off with ``--no-validate``
    unless ``enforce``)."""
    enforce: bool = False
    """``--verify``: a failing certificate fails the conversion (nothing is written)."""
    tolerances: Tolerances = field(default_factory=Tolerances)
    samples: int = SAMPLES
    seed: int = 0
    cache_root: Path | None = None
    """Where collision figures are kept by content (None: measured every time)."""


@dataclass
class Certificate:
    """The figures, what failed and what the model changed on purpose."""

    reference: str
    """``"urdfdom 6.0.0"`` or ``"yourdfpy 0.0.60"``: the implementation whose frames
    the model is held to (the ``references`` section says who read what)."""
    tolerances: Tolerances
    sections: dict[str, Any] = field(default_factory=dict)
    changes: list[dict[str, Any]] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    why_not: str | None = None
    """Why it was not computed (None: it was)."""

    @property
    def computed(self) -> bool:
        return self.why_not is None

    @property
    def passed(self) -> bool:
        return self.computed and not self.failures

    @classmethod
    def not_computed(cls, why: str, tolerances: Tolerances | None = None) -> Certificate:
        return cls(reference="", tolerances=tolerances or Tolerances(), why_not=why)

    def to_dict(self) -> dict[str, Any]:
        if not self.computed:
            return {"computed": False, "why": self.why_not, "passed": False, "failures": []}
        implementation, _, version = self.reference.partition(" ")
        return json_safe(
            {
                "computed": True,
                "reference": {"implementation": implementation, "version": version},
                "tolerances": self.tolerances.to_dict(),
                **self.sections,
                "changes": self.changes,
                "passed": self.passed,
                "failures": list(self.failures),
            }
        )

    def summary(self) -> str:
        """One line: passed with the headline figures, or FAILED with the first failures;
        where the two references disagree, which one the figures hold to."""
        if not self.computed:
            return (
                f"certificate: not computed: {self.why_not}; nothing checked the model "
                "against the description"
            )
        disagreement = self.disagreement()
        if self.failures:
            shown = "; ".join(self.failures[:3])
            more = f"; and {len(self.failures) - 3} more" if len(self.failures) > 3 else ""
            return f"certificate: FAILED: {shown}{more}{disagreement}{self.dropped()}"
        f = self.sections.get("frames", {})
        m = self.sections.get("mass", {})
        n = len(self.changes)
        return (
            f"certificate: passed (frames {f.get('max_position_error_m', 0):.1g} m / "
            f"{f.get('max_rotation_error_rad', 0):.1g} rad, mass {m.get('mjcf_kg', 0):.3f} kg = "
            f"{m.get('urdf_kg', 0) + m.get('added_kg', 0) - m.get('welded_kg', 0):.3f} kg, "
            f"{n} change{'' if n == 1 else 's'}){disagreement}{self.dropped()}"
        )

    def dropped(self) -> str:
        """``; the description's flaw: 3 meshes it names were not found ...``: what a
        passing certificate cannot vouch for, or "" when every mesh was found."""
        lost = [
            c
            for c in self.changes
            if c.get("kind") == "warning"
            and " mesh '" in str(c.get("element", ""))
            and str(c.get("message", "")).endswith("dropped")
        ]
        if not lost:
            return ""
        n = len(lost)
        return (
            f"; the description's flaw: {n} mesh{'' if n == 1 else 'es'} it names "
            f"{'was' if n == 1 else 'were'} not found or not readable and "
            f"{'is' if n == 1 else 'are'} missing from the model (see the warnings)"
        )

    def disagreement(self) -> str:
        """``; yourdfpy's frames differ from urdfdom's by 5.93 m (link 'x'): urdfdom
        believed``, or "" where the references agree (or only one read the file)."""
        agreement = self.sections.get("references", {}).get("agreement", {})
        if agreement.get("agree", True):
            return ""
        return (
            f"; yourdfpy's frames differ from {agreement['believed']}'s by "
            f"{agreement['max_position_difference_m']:.3g} m (link '{agreement['link']}'): "
            f"{agreement['believed']} believed (see the certificate's references)"
        )

    def _failed(self, section: str) -> bool:
        return any(f.startswith(section) for f in self.failures)

    def table(self) -> str:
        """A few lines for ``-v``: each figure, its tolerance and its verdict."""
        if not self.computed:
            return self.summary()
        t = self.tolerances
        s = self.sections
        fr, jo, ma, dy = s["frames"], s["joints"], s["mass"], s["dynamics"]
        rows = [
            (
                "frames",
                f"{fr['max_position_error_m']:.2g} m, {fr['max_rotation_error_rad']:.2g} rad "
                f"({fr['links']} links x {fr['configurations']} configurations)",
                f"{t.frame_position_m:g} m, {t.frame_rotation_rad:g} rad",
                self._failed("frames"),
            ),
            (
                "joints",
                f"{jo['checked']} checked, {len(jo['mismatches'])} mismatched",
                "see docs/cli.md",
                self._failed("joints"),
            ),
            (
                "mass",
                f"{ma['mjcf_kg']:.6g} kg, description {ma['urdf_kg']:.6g} kg"
                + (f" + {ma['added_kg']:.3g} kg supplied" if ma["added_kg"] else "")
                + (f", COM off {ma['com_error_m']:.2g} m" if ma["com_error_m"] is not None else ""),
                f"{t.mass_relative:g} rel, {t.com_m:g} m",
                self._failed("mass"),
            ),
            (
                "dynamics",
                (
                    f"M {dy['mass_matrix_relative_error']:.2g}, "
                    f"g {dy['gravity_relative_error']:.2g} ({dy['dofs']} dofs, {dy['reference']})"
                )
                if dy.get("computed")
                else f"not computed ({dy.get('why')})",
                f"{t.dynamics_relative:g} rel",
                self._failed("dynamics"),
            ),
        ]
        for name in ("collision", "checks"):
            sec = s.get(name, {})
            if sec.get("computed") is False:
                text = f"not computed ({sec.get('why')})"
            else:
                items = sec.get("links" if name == "collision" else "checks", {})
                bad = sum(
                    1 for v in items.values() if isinstance(v, dict) and not v.get("ok", True)
                )
                text = f"{len(items)} {'links' if name == 'collision' else 'checks'}, {bad} out"
            rows.append((name, text, "", self._failed(name)))
        refs = s.get("references", {})
        agreement = refs.get("agreement", {})
        if agreement.get("compared"):
            text = (
                "urdfdom and yourdfpy agree"
                if agreement["agree"]
                else f"yourdfpy differs by {agreement['max_position_difference_m']:.3g} m at "
                f"link '{agreement['link']}': {agreement['believed']} believed: {agreement['why']}"
            )
            rows.append(("references", text, "", False))
        elif refs:
            text = f"frames by {refs['frames']} ({agreement.get('why')})"
            rows.append(("references", text, "", False))
        lines = [f"certificate against {self.reference}:"]
        for name, value, tol, failed in rows:
            verdict = "FAILED" if failed else "ok"
            tol_text = f"  (tolerance {tol})" if tol else ""
            lines.append(f"  {name:<10} {verdict:<6} {value}{tol_text}")
        lines.append(f"  {'changes':<10} {len(self.changes)}")
        return "\n".join(lines)


def json_safe(value: Any) -> Any:
    """``value`` with every NaN or infinite float written as None (JSON's null): a
    report is JSON, which has no NaN; such a figure is a failure too
    (:func:`not_finite`)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


def not_finite(sections: Mapping[str, Any]) -> list[str]:
    """A failure for each figure of ``sections`` that is NaN or infinite (a model whose
    numbers overflow): no comparison with a tolerance can pass it."""
    found: list[str] = []
    stack: list[tuple[str, Any]] = [(k, v) for k, v in sections.items()]
    while stack:
        where, value = stack.pop()
        if isinstance(value, float) and not math.isfinite(value):
            found.append(f"{where}: {value} is not a finite number")
        elif isinstance(value, dict):
            stack.extend((f"{where}.{k}", v) for k, v in value.items())
        elif isinstance(value, list | tuple):
            stack.extend((f"{where}[{i}]", v) for i, v in enumerate(value))
    return sorted(found)


def certify(
    ref: Reference,
    m: Any,
    *,
    tolerances: Tolerances | None = None,
    names: NameMap | None = None,
    model: Model | None = None,
    notes: Iterable[Note] = (),
    samples: int = SAMPLES,
    seed: int = 0,
    cache_root: Path | None = None,
    model_path: Path | None = None,
    passive: PassiveRun | None = None,
) -> Certificate:
    """The certificate of the compiled model ``m`` against the description ``ref``.

    ``cache_root``: where the geometric figures (collision, the geometry's inertia,
    source overlaps) are kept by content (a warm conversion measures none again);
    ``model_path``: the MJCF file ``m`` was compiled from (lets the visual geoms be
    weighed); ``passive``: the passive second of ``m``, stepped already (validation
    does, beside its own); None: it steps on a copy of ``m`` in a thread of its own
    while the other figures are computed.

    ``model`` (and its ``notes``): our conversion's intermediate representation,
    which says which inertials it supplied and why; without it (a model we did not
    write) the links whose inertial a model may supply are found by rule. Raises an
    InputError when the model has no body for the description's root link.
    """
    import copy

    from ..mjcf.compile import home_data, start_passive_second, warnings_into

    # MuJoCo's warnings are not figures: kept from its default handler (a log file)
    with warnings_into([]):
        stepping: Future[PassiveRun]
        if passive is None:
            stepping = start_passive_second(copy.copy(m), home_data(m))
        else:
            stepping = Future()
            stepping.set_result(passive)
        try:
            return _certify(
                ref,
                m,
                tolerances,
                names,
                model,
                notes,
                samples,
                seed,
                cache_root,
                model_path,
                stepping,
            )
        finally:
            stepping.exception()  # the thread is done before the handler is restored


def _certify(
    ref: Reference,
    m: Any,
    tolerances: Tolerances | None,
    names: NameMap | None,
    model: Model | None,
    notes: Iterable[Note],
    samples: int,
    seed: int,
    cache_root: Path | None,
    model_path: Path | None,
    passive: Future[PassiveRun],
) -> Certificate:
    from . import changes as changes_mod
    from . import dynamics, kinematics, mass

    tol = tolerances or Tolerances()
    mt = kinematics.match(ref, m, names)
    configs = kinematics.sample_configurations(ref, samples, seed)
    frames, failures, ref_frames = kinematics.frames_section(
        mt, configs, tol.frame_position_m, tol.frame_rotation_rad
    )
    home = ref_frames[0]
    joints, joint_failures, joint_changes = kinematics.joints_section(mt, home, tol)
    amended: Mapping[str, mass.LinkInertial | None]
    if model is not None:
        amended = changes_mod.amended_by_conversion(model)
    else:
        amended = changes_mod.amended_by_rule(ref, free_root=mt.root_free is not None)
    mass_sec, mass_failures, mass_changes = mass.mass_section(
        mt, home, amended, tol.mass_relative, tol.com_m
    )
    dyn, dyn_failures = dynamics.dynamics_section(
        mt, configs[: 1 + DYNAMICS_SAMPLES], amended, tol.dynamics_relative
    )
    collision, collision_failures = _collision(ref, m, tol, cache_root)
    checks, check_failures = _checks(ref, m, tol, model_path, cache_root, passive)
    listed = changes_mod.from_notes(notes)
    seen = {c["element"] for c in listed}
    extra = joint_changes + mass_changes + changes_mod.massless_with_inertia(ref)
    listed += [c for c in extra if c["element"] not in seen]
    vectors = [kinematics.config_vector(ref, kinematics.with_mimics(ref, c)) for c in configs]
    references = {
        **ref.readers(),
        "agreement": ref.agreement(vectors, tol.frame_position_m, tol.frame_rotation_rad),
    }
    sections = {
        "references": references,
        "frames": frames,
        "joints": joints,
        "mass": mass_sec,
        "dynamics": dyn,
        "collision": collision,
        "checks": checks,
    }
    return Certificate(
        reference=ref.implementation,
        tolerances=tol,
        sections=sections,
        changes=listed,
        failures=failures
        + joint_failures
        + mass_failures
        + dyn_failures
        + collision_failures
        + check_failures
        + not_finite(sections),
    )


def _collision(
    ref: Reference, m: Any, tol: Tolerances, cache_root: Path | None
) -> tuple[dict[str, Any], list[str]]:
    from .collision import collision_section

    return _section(
        "collision",
        lambda: collision_section(
            ref,
            m,
            hausdorff_mm=tol.collision_hausdorff_mm,
            hausdorff_rel=tol.collision_hausdorff_rel,
            volume_ratio=(tol.collision_volume_ratio_min, tol.collision_volume_ratio_max),
            cache_root=cache_root,
        ),
    )


def _checks(
    ref: Reference,
    m: Any,
    tol: Tolerances,
    model_path: Path | None,
    cache_root: Path | None,
    passive: Future[PassiveRun],
) -> tuple[dict[str, Any], list[str]]:
    from ..mjcf.compile import home_data
    from .checks import lint_section

    return _section(
        "checks",
        lambda: lint_section(
            ref,
            m,
            home_data(m),
            inertia_factor=tol.inertia_factor,
            penetration_m=tol.penetration_m,
            energy_growth=tol.energy_growth,
            model_path=model_path,
            cache_root=cache_root,
            passive=passive,
        ),
    )


def _section(name: str, compute: Callable[[], dict[str, Any]]) -> tuple[dict[str, Any], list[str]]:
    """A section's figures and its failures, each prefixed with ``name``; a bug in it
    must not hide the other figures (bad input, a ConversionError, still stops)."""
    try:
        result = compute()
    except ConversionError:
        raise
    except Exception as exc:
        log.warning("certificate: %s section failed: %s", name, exc, exc_info=True)
        return {"computed": False, "why": f"internal error: {type(exc).__name__}: {exc}"}, []
    failures = [f if f.startswith(name) else f"{name}.{f}" for f in result.get("failures", [])]
    return {k: v for k, v in result.items() if k != "failures"}, failures


def compile_written(xml_path: Path, files: Iterable[str]) -> Any:
    """``mujoco.MjModel`` of the written ``xml_path``: every file named in ``files``
    (relative to its folder) read back from disk and compiled as MuJoCo opens it."""
    from ..errors import ValidationError
    from ..mjcf.compile import compile_xml

    folder = xml_path.parent
    written = {name: (folder / name).read_bytes() for name in files}
    try:
        return compile_xml(written[xml_path.name], written)
    except ValueError as exc:
        message = " ".join(str(exc).split())
        raise ValidationError(f"MuJoCo rejected the model: {message}", file=xml_path) from None
