"""What the commands share: logging, ``NAME=VALUE`` pairs, and the converter's options
that ``urdf2mjcf batch`` applies to every robot (declared once, so both commands show
the same help and defaults).

Below ``cli.py``, ``batch.py`` and ``certify/command.py``: ``cli.py`` dispatches to the
other two, so none of them imports it.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from .cli_types import BoundedInt, FiniteFloat
from .ir import COLLISION_SHAPES
from .passes.collision import CollisionConfig
from .passes.inertia import InertiaConfig
from .passes.meshes import MeshConfig
from .untrusted import excerpt

F = TypeVar("F", bound=Callable[..., Any])

DENSITY = FiniteFloat(0.0, 1e6, low_open=True)
"""kg/m^3: above 0 (nothing is massless by density), at most 1e6 (osmium is 2.3e4)."""


def configure_logging(verbose: int, quiet: bool) -> None:
    level = (
        logging.ERROR if quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)]
    )
    logging.basicConfig(
        level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr
    )


class KeyedChoice(click.ParamType):
    """``KEY=CHOICE``, the choice one of ``choices``; converts to ``(key, choice)``."""

    name = "key=choice"

    def __init__(self, choices: tuple[str, ...], key_name: str = "KEY") -> None:
        self.choices = choices
        self.key_name = key_name

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        key, found, choice = str(value).partition("=")
        if not found or not key:
            self.fail(f"'{excerpt(str(value), 40)}' is not {self.key_name}=VALUE", param, ctx)
        if choice not in self.choices:
            self.fail(
                f"{excerpt(key, 40)}: '{excerpt(choice, 20)}' is not one of "
                f"{', '.join(self.choices)}",
                param,
                ctx,
            )
        return (key, choice)


def pairs(values: tuple[str, ...], sep: str, what: str) -> dict[str, str]:
    """``NAME<sep>VALUE`` items -> {NAME: VALUE}; an item without ``sep`` or a name is a
    bad parameter (``what`` says what it should be)."""
    out = {}
    for item in values:
        name, found, value = item.partition(sep)
        if not found or not name:
            raise click.BadParameter(f"'{item}' is not {what}")
        out[name] = value
    return out


_SHARED: dict[str, tuple[tuple[str, ...], dict[str, Any]]] = {
    # parameter name: (declarations, attributes) of its click.Option
    "package_path": (
        ("--package-path",),
        {
            "multiple": True,
            "type": click.Path(path_type=Path, file_okay=False),
            "help": "Folder whose sub-folders are ROS packages (repeatable).",
        },
    ),
    "packages": (
        ("--package", "packages"),
        {"multiple": True, "metavar": "NAME=DIR", "help": "Location of one package (repeatable)."},
    ),
    "no_ros_env": (
        ("--no-ros-env",),
        {"is_flag": True, "help": "Ignore ROS_PACKAGE_PATH and AMENT_PREFIX_PATH."},
    ),
    "density": (
        ("--density",),
        {
            "type": DENSITY,
            "default": InertiaConfig.density,
            "show_default": True,
            "help": "kg/m^3 for links with geometry but no inertial.",
        },
    ),
    "collision_source": (
        ("--collision", "collision_source"),
        {
            "type": click.Choice(["collision", "visual", "none"]),
            "default": "collision",
            "show_default": True,
            "help": "Where collision geometry comes from.",
        },
    ),
    "collision_shape": (
        ("--collision-shape",),
        {
            "type": click.Choice(COLLISION_SHAPES),
            "default": CollisionConfig.shape,
            "show_default": True,
            "help": "What collision meshes become: decompose (the hull, or convex parts when "
            "the hull is far from the mesh), hull, primitive (fitted spheres, capsules, "
            "cylinders, boxes) or auto (a primitive within --primitive-tolerance, else as "
            "decompose).",
        },
    ),
    "primitive_tolerance": (
        ("--primitive-tolerance",),
        {
            "type": FiniteFloat(0.0, 1e6, low_open=True),
            "default": CollisionConfig.primitive_tolerance_mm,
            "show_default": True,
            "metavar": "MM",
            "help": "auto: largest distance (mm) from a primitive's surface to the mesh.",
        },
    ),
    "primitive_volume_ratio": (
        ("--primitive-volume-ratio",),
        {
            "type": FiniteFloat(1.0, 1e6),
            "default": CollisionConfig.primitive_volume_ratio,
            "show_default": True,
            "help": "auto: largest primitive volume / mesh volume.",
        },
    ),
    "keep_contacts": (
        ("--keep-contacts",),
        {
            "is_flag": True,
            "help": "Exclude no contact pair: by default a fixed base does not collide with "
            "its children, nor two bodies whose collision geoms the conversion made overlap "
            "at home (each exclusion listed in the certificate's changes).",
        },
    ),
    "actuator_config": (
        ("--actuator-config",),
        {
            "type": click.Path(path_type=Path, dir_okay=False),
            "help": "YAML file mapping joint-name patterns to actuators, gains and classes.",
        },
    ),
    "gravcomp": (
        ("--gravcomp",),
        {"is_flag": True, "help": "Gravity compensation on every link a joint moves."},
    ),
    "no_joint_sensors": (
        ("--no-joint-sensors",),
        {"is_flag": True, "help": "No joint sensors for actuated joints."},
    ),
    "no_mujoco_extension": (
        ("--no-mujoco-extension",),
        {"is_flag": True, "help": "Ignore <mujoco> elements in the URDF."},
    ),
    "fuse_fixed": (
        ("--fuse-fixed",),
        {
            "is_flag": True,
            "help": "Merge links on fixed joints into their parent (each leaves a site).",
        },
    ),
    "floating_base": (
        ("--floating-base",),
        {"is_flag": True, "help": "Give the root link a free joint."},
    ),
    "no_scene": (("--no-scene",), {"is_flag": True, "help": "Do not write scene.xml."}),
    "strict": (
        ("--strict",),
        {
            "is_flag": True,
            "help": "A missing or unreadable mesh (visual or collision) is an error, not a "
            "warning that drops it.",
        },
    ),
    "trust_xacro": (
        ("--trust-xacro",),
        {
            "is_flag": True,
            "help": "Run the description's code, as ROS's xacro does (expressions are "
            "otherwise checked: see docs/security.md)",
        },
    ),
    "no_validate": (
        ("--no-validate",),
        {"is_flag": True, "help": "Skip compiling and stepping the result in MuJoCo."},
    ),
    "cache_dir": (
        ("--cache-dir",),
        {
            "type": click.Path(path_type=Path, file_okay=False),
            "help": "Cache folder: loaded meshes and convex decompositions "
            "(see 'urdf2mjcf cache info').",
        },
    ),
    "no_cache": (("--no-cache",), {"is_flag": True, "help": "Neither read nor write the cache."}),
    "decompose_timeout": (
        ("--decompose-timeout",),
        {
            "type": FiniteFloat(0, 1e6),
            "default": CollisionConfig.timeout,
            "show_default": True,
            "help": "Seconds one mesh's convex decomposition may take (0 = no limit); "
            "past it the mesh gets its convex hull, with a warning.",
        },
    ),
    "max_faces": (
        ("--max-faces",),
        {
            "type": BoundedInt(4, 10_000_000),
            "default": MeshConfig.max_faces,
            "show_default": True,
            "help": "Decimate meshes above this face count (4 to 10,000,000).",
        },
    ),
}

QUIET: tuple[tuple[str, ...], dict[str, Any]] = (
    ("-q", "--quiet"),
    {
        "is_flag": True,
        "help": "Only errors and failures (a failed robot, a failing figure): no progress, "
        "notes or summary.",
    },
)
"""``-q`` of every command that has it: one meaning everywhere."""


def quiet_option() -> Callable[[F], F]:
    return click.option(*QUIET[0], **QUIET[1])


SHARED_OPTIONS = tuple(_SHARED)
"""The converter's options that apply to every robot of a batch, in the order of its help."""


def shared_option(name: str) -> Callable[[F], F]:
    """The converter's option ``name`` as a decorator of its command."""
    decls, attrs = _SHARED[name]
    return click.option(*decls, **attrs)


def shared_params() -> list[click.Parameter]:
    """A fresh :class:`click.Option` for each of :data:`SHARED_OPTIONS`."""
    return [click.Option(list(_SHARED[n][0]), **_SHARED[n][1]) for n in SHARED_OPTIONS]
