"""The Python API: chain the passes. The command line is a thin layer on this."""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from . import output as out
from .certify import Certificate, CertificateFailed, CertifyConfig
from .errors import ConversionError, OutputError
from .ir import Model, UrdfDocument
from .mjcf import compile as mjcf_compile
from .mjcf.document import Document, mjcf_bytes
from .options import ConvertOptions, make_options
from .passes import (
    actuators,
    collision,
    contacts,
    emit,
    extension,
    inertia,
    meshes,
    parse,
    scene,
    sensors,
    validate,
    xacro,
)
from .report import Report

log = logging.getLogger(__name__)


ModelPass = Callable[[Document], Document]
"""A pass on the MJCF document in memory, after ``extension`` and before it is written
and validated (the facility's fold and tags): it returns a new result, changing a copy
(:meth:`~urdf2mjcf.mjcf.document.Document.edit`) where it changes anything."""


def build(source: str | Path, options: ConvertOptions) -> tuple[Model, Document]:
    """Run the passes up to ``extension`` in memory: no file is written. The result holds
    the MJCF document as an element tree (``result.root``; ``result.xml``: as written)."""
    _doc, model, result = _build(source, options, mjcf_compile.HomeCompiles())
    return model, result


def _build(
    source: str | Path, options: ConvertOptions, compiles: mjcf_compile.HomeCompiles
) -> tuple[UrdfDocument, Model, Document]:
    """:func:`build`, and the xacro pass's document (the certificate's reference reads it).
    ``compiles``: the conversion's compile that the scene pass may reuse."""
    mjcf_compile.make_room()  # before the first compile of this conversion
    doc = xacro.run(Path(source), options.xacro)
    model = parse.run(doc, options.parse)
    model = meshes.run(model, options.meshes)
    model = collision.run(model, options.collision)
    model = inertia.run(model, options.inertia)
    model = actuators.run(model, options.actuators, robot_tree, compiles)
    model = sensors.run(model, options.sensors)
    result = emit.run(model, options.emit)
    result = extension.run(result, model, replace(options.extension, resolver=doc.resolver))
    result = contacts.run(result, model, options.contacts, compiles)
    if options.calibration is not None:
        from .calibrate.apply import calibrated

        result = calibrated(result, options.calibration)
    return doc, replace(model, notes=model.notes + result.notes), result


def robot_tree(model: Model, floating_base: bool) -> Document:
    """The robot as emit writes it, which the actuators pass compiles to size gains."""
    return emit.run(model, emit.EmitConfig(floating_base=floating_base))


def convert(
    source: str | Path,
    output: str | Path,
    options: ConvertOptions | None = None,
    *,
    model_passes: Sequence[ModelPass] = (),
    **kwargs: Any,
) -> Report:
    """Convert a URDF or xacro file into ``output`` (an ``.xml`` path).

    Writes ``output``, its meshes and textures under ``assets/`` beside it and,
    unless ``scene=False``, a ``scene.xml`` that includes it. Either pass a
    :class:`ConvertOptions` or keyword options (see :func:`make_options`).
    ``model_passes`` run, in order, on the document in memory before it is written
    and validated (:data:`ModelPass`). Raises a
    :class:`~urdf2mjcf.errors.ConversionError` on bad input; then nothing has been
    written.
    """
    if options is None:
        options = make_options(**kwargs)
    elif kwargs:
        raise TypeError("pass either options or keyword options, not both")
    source, output = Path(source), Path(output)
    scene_name = "scene.xml"
    if options.scene and output.name == scene_name:
        raise OutputError(
            "output would be overwritten by scene.xml; choose another name or --no-scene",
            file=output,
        )
    out.check_target(output, options.overwrite, (scene_name,) if options.scene else ())

    compiles = mjcf_compile.HomeCompiles()
    doc, model, result = _build(source, options, compiles)
    for step in model_passes:
        result = step(result)
    # Each document becomes text once, here, by our one writer; validation compiles
    # these bytes, and they are what is installed.
    files = dict(result.files)
    files[output.name] = result.xml
    documents = {output.name: result.root}  # the trees the twin is made from
    check = output
    if options.scene:
        around = scene.run(
            result, output.name, options.emit.model_name or model.robot.name, compiles
        )
        files[scene_name] = mjcf_bytes(around)
        documents[scene_name] = around
        check = output.with_name(scene_name)
    validated: list = []
    certificates: list[Certificate] = []

    def run_validation(staged: Path) -> None:
        staged_target = staged.with_name(check.name)
        cfg = options.certify
        wanted = cfg.enforce or (cfg.enabled and options.validate.enabled)
        # the certificate's passive second is stepped by validation, beside its own
        checks = replace(options.validate, passive_second=wanted)
        validated.append(
            validate.run(
                staged_target, checks, report_as=check, files=list(files), documents=documents
            )
        )
        if wanted:
            # the staged files, before they are installed: --verify can still refuse them
            v = validated[0]
            compiled, passive = (v.model, v.passive) if v is not None else (None, None)
            certificates.append(
                _certificate(doc, model, staged, list(files), cfg, compiled, passive)
            )
            if cfg.enforce and not certificates[0].passed:
                raise CertificateFailed(certificates[0], file=output)

    written = out.write_atomic(output, files, run_validation)
    robot = model.robot
    return Report(
        source=source,
        output=output,
        robot=robot.name,
        links=len(robot.links),
        joints=len(robot.joints),
        bodies=validated[0].nbody - 1 if validated and validated[0] else len(robot.links),
        geoms=sum(len(v) for v in model.visual_geoms.values())
        + sum(len(v) for v in model.collision_geoms.values()),
        meshes=len(model.mesh_assets),
        files=tuple(written),
        notes=model.notes,
        model=model,
        compiled=validated[0].model if validated and validated[0] else None,
        certificate=certificates[0] if certificates else None,
    )


def _certificate(
    doc: UrdfDocument,
    model: Model,
    staged: Path,
    files: list[str],
    cfg: CertifyConfig,
    compiled: Any = None,
    passive: mjcf_compile.PassiveRun | None = None,
) -> Certificate:
    """The certificate of the staged robot file against the description ``doc``.

    ``compiled``: what validation compiled from the staged files (``scene.xml``, which
    includes the robot file, or the robot file itself), reused: a second compile of
    the robot costs a third of a warm conversion. None: the robot file is compiled.
    ``passive``: the passive second validation stepped beside its own (None: the
    certificate steps it).

    A description the reference cannot read, or a model it cannot match, gives a
    certificate that is not computed (and so not passed) rather than a failed
    conversion; ``--verify`` then refuses it."""
    from .certify import certify, compile_written
    from .certify.reference import load

    if not model.robot.links:
        return Certificate.not_computed("the description has no links", cfg.tolerances)
    try:
        m = compiled if compiled is not None else compile_written(staged, files)
        ref = load(doc)
        return certify(
            ref,
            m,
            tolerances=cfg.tolerances,
            model=model,
            notes=model.notes,
            samples=cfg.samples,
            seed=cfg.seed,
            cache_root=cfg.cache_root,
            model_path=staged,
            passive=passive,
        )
    except ConversionError as exc:
        log.info("certificate not computed: %s", exc)
        return Certificate.not_computed(exc.detail, cfg.tolerances)
    except Exception as exc:  # a bug in the certificate must not lose a good conversion
        log.warning("certificate not computed: internal error: %r", exc, exc_info=True)
        return Certificate.not_computed(f"internal error: {type(exc).__name__}: {exc}")
