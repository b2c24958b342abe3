"""The converter's options, each declared once.

:data:`OPTIONS` is the one declaration of every option a conversion takes: its keyword
(of :func:`make_options` and :func:`urdf2mjcf.convert`), its default (read from the
pass config it sets), its values (a number's range, a choice), its help, and the
command-line flag that gives it. Everything else is derived from it: the click options
of ``urdf2mjcf convert``, ``batch``, ``view`` and ``verify`` (``cli_common``), the
keywords those commands hand on, the facility's options (checked as keywords here) and
the docs' list (tested). :func:`make_options` turns the keywords into
:class:`ConvertOptions`, one frozen config per pass.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from .certify import CertifyConfig
from .certify.tolerances import Tolerances
from .ir import COLLISION_SHAPES
from .passes import (
    actuators,
    collision,
    contacts,
    emit,
    extension,
    inertia,
    meshes,
    parse,
    sensors,
    validate,
    xacro,
)


@dataclass(frozen=True)
class ConvertOptions:
    """Every option of a conversion, one config per pass, defaults in one place."""

    xacro: xacro.XacroConfig = field(default_factory=xacro.XacroConfig)
    parse: parse.ParseConfig = field(default_factory=parse.ParseConfig)
    meshes: meshes.MeshConfig = field(default_factory=meshes.MeshConfig)
    collision: collision.CollisionConfig = field(default_factory=collision.CollisionConfig)
    inertia: inertia.InertiaConfig = field(default_factory=inertia.InertiaConfig)
    actuators: actuators.ActuatorConfig = field(default_factory=actuators.ActuatorConfig)
    sensors: sensors.SensorConfig = field(default_factory=sensors.SensorConfig)
    emit: emit.EmitConfig = field(default_factory=emit.EmitConfig)
    extension: extension.ExtensionConfig = field(default_factory=extension.ExtensionConfig)
    contacts: contacts.ContactsConfig = field(default_factory=contacts.ContactsConfig)
    validate: validate.ValidateConfig = field(default_factory=validate.ValidateConfig)
    certify: CertifyConfig = field(default_factory=CertifyConfig)
    """The fidelity certificate of the written model (see :mod:`urdf2mjcf.certify`)."""
    calibration: Path | None = None
    """A calibration file (:mod:`urdf2mjcf.calibrate.apply`) written into the document
    after the actuators and contacts."""
    scene: bool = True
    """Also write ``scene.xml`` (floor, light, sky) beside the robot."""
    overwrite: bool = False


@dataclass(frozen=True)
class Number:
    """A finite number in ``[low, high]`` (``(low, high]`` with ``low_open``)."""

    low: float
    high: float
    low_open: bool = False
    integer: bool = False


@dataclass(frozen=True)
class Choice:
    choices: tuple[str, ...]


Kind = Literal["switch", "text", "file", "folder", "object"]
"""What an option's value is when it is not a :class:`Number` or a :class:`Choice`: an
on/off ``switch`` (a flag; one whose default is on is the flag that turns it off), a
``text``, a ``file`` or ``folder`` path, or an ``object`` only the API passes."""


@dataclass(frozen=True)
class Option:
    """One option of a conversion."""

    keyword: str
    """Its keyword of :func:`make_options`; the click parameter's name too."""
    default: Any
    help: str
    flags: tuple[str, ...] = ()
    """Its command-line spellings (``("-j", "--jobs")``); none: the API's only."""
    value: Number | Choice | Kind = "switch"
    key: str | None = None
    """Repeatable ``KEY=VALUE`` pairs, the key named so (``LINK``), the value ``value``."""
    repeatable: bool = False
    metavar: str | None = None
    every_robot: bool = False
    """It applies to every robot of a batch: ``batch`` and ``view`` take it too."""
    show_default: bool = True


DENSITY = Number(0.0, 1e6, low_open=True)
"""kg/m^3: above 0 (nothing is massless by density), at most 1e6 (osmium is 2.3e4)."""

OPTIONS: tuple[Option, ...] = (
    Option("args", None, "xacro arguments NAME -> VALUE (on the command line: NAME:=VALUE).",
           value="object"),
    Option("package_paths", (), "Folder whose sub-folders are ROS packages (repeatable).",
           ("--package-path",), "folder", repeatable=True, every_robot=True),
    Option("packages", None, "Location of one package (repeatable).", ("--package",),
           "text", key="NAME", metavar="NAME=DIR", every_robot=True),
    Option("use_environment", xacro.XacroConfig.use_environment,
           "Ignore ROS_PACKAGE_PATH and AMENT_PREFIX_PATH.", ("--no-ros-env",),
           every_robot=True),
    Option("density", inertia.InertiaConfig.density,
           "kg/m^3 for links with geometry but no inertial.", ("--density",), DENSITY,
           every_robot=True),
    Option("link_density", None, "Per-link density override (repeatable).",
           ("--link-density",), DENSITY, key="LINK", metavar="LINK=KG_PER_M3"),
    Option("collision_source", collision.CollisionConfig.source,
           "Where collision geometry comes from.", ("--collision",),
           Choice(("collision", "visual", "none")), every_robot=True),
    Option("collision_shape", collision.CollisionConfig.shape,
           "What collision meshes become: decompose (the hull, or convex parts when the "
           "hull is far from the mesh), hull, primitive (fitted spheres, capsules, "
           "cylinders, boxes) or auto (a primitive within --primitive-tolerance, else as "
           "decompose).", ("--collision-shape",), Choice(COLLISION_SHAPES),
           every_robot=True),
    Option("link_collision", None, "One link's collision shape (repeatable); above the "
           "URDF's <mujoco> and the --actuator-config file's collision section.",
           ("--link-collision",), Choice(COLLISION_SHAPES), key="LINK",
           metavar="LINK=SHAPE"),
    Option("primitive_tolerance", collision.CollisionConfig.primitive_tolerance_mm,
           "auto: largest distance (mm) from a primitive's surface to the mesh.",
           ("--primitive-tolerance",), Number(0.0, 1e6, low_open=True), metavar="MM",
           every_robot=True),
    Option("primitive_volume_ratio", collision.CollisionConfig.primitive_volume_ratio,
           "auto: largest primitive volume / mesh volume.", ("--primitive-volume-ratio",),
           Number(1.0, 1e6), every_robot=True),
    Option("keep_contacts", contacts.ContactsConfig.keep,
           "Exclude no contact pair: by default a fixed base does not collide with its "
           "children, nor two bodies whose collision geoms the conversion made overlap at "
           "home (each exclusion listed in the certificate's changes).",
           ("--keep-contacts",), every_robot=True),
    Option("actuator_config", None,
           "YAML file mapping joint-name patterns to actuators, gains and classes.",
           ("--actuator-config",), "file", every_robot=True),
    Option("gravcomp", actuators.ActuatorConfig.gravcomp,
           "Gravity compensation on every link a joint moves.", ("--gravcomp",),
           every_robot=True),
    Option("joint_sensors", sensors.SensorConfig.joint_sensors,
           "No joint sensors for actuated joints.", ("--no-joint-sensors",),
           every_robot=True),
    Option("mujoco_extension", extension.ExtensionConfig.enabled,
           "Ignore <mujoco> elements in the URDF.", ("--no-mujoco-extension",),
           every_robot=True),
    Option("fuse_fixed", emit.EmitConfig.fuse_fixed,
           "Merge links on fixed joints into their parent (each leaves a site).",
           ("--fuse-fixed",), every_robot=True),
    Option("floating_base", emit.EmitConfig.floating_base,
           "Give the root link a free joint.", ("--floating-base",), every_robot=True),
    Option("model_name", emit.EmitConfig.model_name,
           "Name of the MuJoCo model (default: the URDF robot name).", ("--model-name",),
           "text"),
    Option("calibration", ConvertOptions.calibration,
           "calibration.yaml from 'urdf2mjcf calibrate': its identified joint damping, "
           "friction, armature, gains and masses written into the model.",
           ("--calibration",), "file"),
    Option("scene", ConvertOptions.scene, "Do not write scene.xml.", ("--no-scene",),
           every_robot=True),
    Option("overwrite", ConvertOptions.overwrite, "Replace existing output files.",
           ("--overwrite",)),
    Option("strict", parse.ParseConfig.strict,
           "A missing or unreadable mesh (visual or collision) is an error, not a warning "
           "that drops it.", ("--strict",), every_robot=True),
    Option("trust_xacro", None,
           "Run the description's code, as ROS's xacro does (expressions are otherwise "
           "checked: see docs/security.md); not given: $URDF2MJCF_TRUST_XACRO decides.",
           ("--trust-xacro",), every_robot=True),
    Option("validate_model", validate.ValidateConfig.enabled,
           "Skip compiling and stepping the result in MuJoCo.", ("--no-validate",),
           every_robot=True),
    Option("certify", CertifyConfig.enabled,
           "Compute the certificate of the written model (with validation).",
           value="object"),
    Option("verify", CertifyConfig.enforce,
           "Fail (exit 1, nothing written) when the certificate of the written model "
           "against the description fails (see 'urdf2mjcf verify --help').", ("--verify",)),
    Option("tolerances", None,
           "Change one of the certificate's tolerances (repeatable; the names: "
           "docs/cli.md).", ("--tolerance",), Number(0.0, 1e6), key="NAME",
           metavar="NAME=VALUE"),
    Option("cache_dir", collision.CollisionConfig.cache_dir,
           "Cache folder: loaded meshes and convex decompositions (default: "
           "$URDF2MJCF_CACHE, else $XDG_CACHE_HOME/urdf2mjcf, else ~/.cache/urdf2mjcf; see "
           "'urdf2mjcf cache info').", ("--cache-dir",), "folder", every_robot=True),
    Option("use_cache", collision.CollisionConfig.use_cache,
           "Neither read nor write the cache.", ("--no-cache",), every_robot=True),
    Option("workers", collision.CollisionConfig.workers,
           "Parallel decompositions (0 = one per CPU; at most 1024).", ("-j", "--jobs"),
           Number(0, 1024, integer=True), show_default=False),
    Option("decompose_timeout", collision.CollisionConfig.timeout,
           "Seconds one mesh's convex decomposition may take (0 = no limit); past it the "
           "mesh gets its convex hull, with a warning.", ("--decompose-timeout",),
           Number(0, 1e6), every_robot=True),
    Option("max_faces", meshes.MeshConfig.max_faces,
           "Decimate meshes above this face count (4 to 10,000,000).", ("--max-faces",),
           Number(4, 10_000_000, integer=True), every_robot=True),
    Option("progress", collision.CollisionConfig.progress,
           "A callable (done, total, label) told of the decompositions' progress.",
           value="object"),
)  # fmt: skip
"""Every option of a conversion, in the order of ``urdf2mjcf convert --help``."""

BY_KEYWORD: dict[str, Option] = {o.keyword: o for o in OPTIONS}


def resolve(keywords: Mapping[str, Any]) -> dict[str, Any]:
    """Every option's value: the one given in ``keywords``, else its default. A keyword
    that is no option is a TypeError, as for any function."""
    unknown = sorted(set(keywords) - set(BY_KEYWORD))
    if unknown:
        raise TypeError(f"make_options() got an unexpected keyword argument '{unknown[0]}'")
    return {o.keyword: keywords.get(o.keyword, o.default) for o in OPTIONS}


def _pairs(value: Mapping[str, Any] | Iterable[tuple[str, Any]] | None) -> dict[str, Any]:
    """A mapping, or ``(key, value)`` pairs as the command line gives them, as a dict."""
    return dict(value or {})


def make_options(**keywords: Any) -> ConvertOptions:
    """Keyword options (as :func:`urdf2mjcf.convert` takes them, one per entry of
    :data:`OPTIONS`) -> :class:`ConvertOptions`.

    ``trust_xacro`` runs a description's code as ROS's xacro does; ``None`` takes it
    from ``$URDF2MJCF_TRUST_XACRO`` (default: expressions are checked). ``certify``:
    compute the certificate (with validation); ``verify``: compute it even without
    validation and fail the conversion (:class:`~urdf2mjcf.certify.CertificateFailed`,
    nothing written) when it fails, against ``tolerances`` (a
    :class:`~urdf2mjcf.certify.tolerances.Tolerances`, or name -> value changes).
    ``collision_shape``: what collision meshes become (``decompose``, ``hull``,
    ``primitive`` or ``auto``), for every link; ``link_collision``: link name -> shape,
    above every other route; ``primitive_tolerance`` (mm) and ``primitive_volume_ratio``:
    what ``auto`` accepts of a primitive fit (see :mod:`urdf2mjcf.passes.collision`).
    ``keep_contacts``: write no contact exclusion (see :mod:`urdf2mjcf.passes.contacts`).
    Mappings (``args``, ``packages``, ``link_density``, ``link_collision``) may be given
    as ``(key, value)`` pairs too."""
    from .cache import default_cache_dir
    from .passes.xacro_guard import trust_from_env

    v = resolve(keywords)
    cache_dir = Path(v["cache_dir"]) if v["cache_dir"] else None
    use_cache = v["use_cache"]
    config_file = Path(v["actuator_config"]) if v["actuator_config"] else None
    strict, floating_base, extended = v["strict"], v["floating_base"], v["mujoco_extension"]
    tolerances = v["tolerances"]
    if not isinstance(tolerances, Tolerances):
        tolerances = Tolerances().with_values(_pairs(tolerances).items())
    return ConvertOptions(
        xacro=xacro.XacroConfig(
            args=_pairs(v["args"]),
            packages={k: Path(p) for k, p in _pairs(v["packages"]).items()},
            package_paths=tuple(Path(p) for p in v["package_paths"]),
            use_environment=v["use_environment"],
            strict=strict,
            trust=trust_from_env() if v["trust_xacro"] is None else v["trust_xacro"],
        ),
        parse=parse.ParseConfig(strict=strict, free_root=floating_base),
        meshes=meshes.MeshConfig(
            max_faces=v["max_faces"],
            strict_visual=strict,
            cache_dir=cache_dir,
            use_cache=use_cache,
        ),
        collision=collision.CollisionConfig(
            source=v["collision_source"],
            cache_dir=cache_dir,
            use_cache=use_cache,
            workers=v["workers"],
            timeout=v["decompose_timeout"],
            progress=v["progress"],
            shape=v["collision_shape"],  # checked by the pass
            link_shapes=_pairs(v["link_collision"]),
            primitive_tolerance_mm=v["primitive_tolerance"],
            primitive_volume_ratio=v["primitive_volume_ratio"],
            config_file=config_file,
            mujoco_extension=extended,
        ),
        inertia=inertia.InertiaConfig(
            density=v["density"], link_density=_pairs(v["link_density"]), free_root=floating_base
        ),
        actuators=actuators.ActuatorConfig(
            config_file=config_file, gravcomp=v["gravcomp"], floating_base=floating_base
        ),
        sensors=sensors.SensorConfig(joint_sensors=v["joint_sensors"]),
        emit=emit.EmitConfig(
            fuse_fixed=v["fuse_fixed"], floating_base=floating_base, model_name=v["model_name"]
        ),
        extension=extension.ExtensionConfig(enabled=extended, check=v["validate_model"]),
        contacts=contacts.ContactsConfig(
            keep=v["keep_contacts"], config_file=config_file, mujoco_extension=extended
        ),
        validate=validate.ValidateConfig(enabled=v["validate_model"]),
        certify=CertifyConfig(
            enabled=v["certify"],
            enforce=v["verify"],
            tolerances=tolerances,
            cache_root=(cache_dir or default_cache_dir()) if use_cache else None,
        ),
        calibration=Path(v["calibration"]) if v["calibration"] else None,
        scene=v["scene"],
        overwrite=v["overwrite"],
    )
