"""``make-facility``: recipe -> xacro arguments -> one compiled facility.

Each component with ``attach`` in the recipe's table is compiled once on its own
into ``components/`` and that document is attached into the world (the recipe's
top-level xacro, with its flags and poses as xacro arguments) at its placement
(:mod:`urdf2mjcf.facility.attach`), all converted by :func:`urdf2mjcf.convert`
into ``scene.xml``. A component without ``attach`` is part of the top-level xacro,
and is also compiled on its own into ``components/<asset>/``. The output
folder is staged beside the target and moved in only when the build succeeded,
so a failed build leaves the previous one intact. ``facility.json`` lists every
file we wrote: a rebuild replaces those and keeps anything else in the folder
(see ``urdf2mjcf.output``).

The folder is a self-contained bundle (``urdf2mjcf.bundle``): it also holds the recipe
as built (``recipe.yaml``) and the demo it was built for (``demo.yaml``), so the
runtime replays and rebuilds it without the facility root's recipes.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Callable, Collection, Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import yaml

from .. import api, bundle, untrusted
from .. import output as out
from .. import report as conversion_report
from ..bundle_manifest import Manifest, Rocks
from ..calibrate import apply as calib_apply
from ..demos import DEMO_ROBOT, demo_source
from ..errors import ForgeError, InputError
from ..mjcf.document import Document
from . import attach, fiducials, fold
from .jitter import jittered
from .manifest import GENERATOR, MANIFEST, manifest, write_manifest
from .recipe import Component, Pose2D, Recipe, read_yaml
from .root import data_path, find_root  # noqa: F401  (find_root: callers import it here)
from .scatter import rocks_arg, scatter

log = logging.getLogger(__name__)

PACKAGE_DIRS = ("facility/robots", "facility/mockups", "facility/worlds")
"""Folders whose sub-folders are packages (relative to the facility root)."""
NAMED_PACKAGES = {"facility_common": "facility/common", "facility_meshes": "meshes"}


@dataclass(frozen=True)
class FacilityReport:
    output: Path
    scene: Path
    manifest: dict
    conversion: api.Report
    components: dict[str, Path] = field(default_factory=dict)
    compiled: Any = field(default=None, repr=False, compare=False)
    written: Manifest | None = field(default=None, repr=False, compare=False)
    """facility.json as written, typed (``manifest`` is its JSON)."""
    """The ``mujoco.MjModel`` of ``scene.xml`` as written, the one validation stepped
    (folding and tags are passes on the scene in memory, before it is validated)."""


def _flag_text(value: object) -> str:
    return ("true" if value else "false") if isinstance(value, bool) else str(value)


def xacro_args(recipe: Recipe, placements: dict[str, Pose2D]) -> dict[str, str]:
    """The top-level xacro's arguments: flags, every pose (``<component>_x``, ``_y``,
    ``_z``, ``_yaw``), simulation options."""
    args = {k: _flag_text(v) for k, v in recipe.flags.items()}
    for name, pose in placements.items():
        for axis, value in zip("xyz", pose.xyz, strict=True):
            args[f"{name}_{axis}"] = repr(float(value))
        args[f"{name}_yaw"] = repr(float(pose.yaw))
    for key, value in recipe.simulation.items():
        args[key] = _flag_text(value)
    return args


def _convert_options(
    root: Path,
    recipe: Recipe,
    *,
    workers: int,
    cache_dir: Path | None,
    progress: Callable[[int, int, str], None] | None,
    source: Path | None = None,
    args: Mapping[str, str] | None = None,
    prefix: str | None = None,
    elsewhere: Collection[str] = (),
) -> dict:
    """:func:`api.convert`'s options for ``source``: the facility (``prefix`` None, with
    its xacro ``args``; ``elsewhere``: the links of the components attached to it) or a
    component compiled on its own (with its ``prefix``). The recipe's
    ``collision.links`` are the facility's link names: the facility must have each
    (else an error naming the recipe and the key); a component takes those it has
    (:meth:`Recipe.link_collision`)."""
    options: dict[str, Any] = {
        "package_paths": [root / d for d in PACKAGE_DIRS],
        "packages": {name: root / d for name, d in NAMED_PACKAGES.items()},
        "use_environment": False,
        "actuator_config": data_path(root, recipe.path, recipe.actuator_config)
        if recipe.actuator_config
        else None,
        "gravcomp": recipe.gravcomp,
        "workers": workers,
        "cache_dir": cache_dir,
        "progress": progress,
        "overwrite": True,
        # Our facility descriptions are written for MuJoCo: a door closes on its frame,
        # a carriage rides its rail. Their contacts stay as described (no exclusion).
        "keep_contacts": True,
    }
    if recipe.collision.get("default") is not None:
        options["collision_shape"] = recipe.collision["default"]
    if recipe.collision.get("links") and source is not None:
        from ..passes import parse, xacro  # the link names only: no mesh is read

        config = api.make_options(args=args, **options)
        robot = parse.run(xacro.run(source, config.xacro), config.parse).robot
        links = {link.name for link in robot.links}
        if prefix is None:
            for name in recipe.collision["links"]:
                if name not in links and name not in elsewhere:
                    raise InputError(
                        "no such link in the facility",
                        file=recipe.path or source,
                        element=f"collision.links.{untrusted.excerpt(name, 60)}",
                    )
        options["link_collision"] = recipe.link_collision(links, prefix or "")
    return options


def _component_options(
    root: Path,
    recipe: Recipe,
    comp: Component,
    src: Path,
    args: Mapping[str, str] | None = None,
    *,
    workers: int,
    cache_dir: Path | None,
    progress: Callable[[int, int, str], None] | None,
) -> dict:
    """:func:`_convert_options` for component ``comp`` compiled on its own from ``src``
    (with its xacro ``args``): the recipe's actuator file only for a robot."""
    options = _convert_options(
        root,
        recipe,
        workers=workers,
        cache_dir=cache_dir,
        progress=progress,
        source=src,
        args=args,
        prefix=comp.prefix,
    )
    if comp.roles is None:  # the actuator file belongs to the robot
        options["actuator_config"] = None
    return options


class Parts:
    """Attached components built in memory (``components=False``), kept for the next
    build of the same recipe from the same files: a seed moves a part, never changes it,
    so seeded trials build each part once (``urdf2mjcf.runner.trials``). Only for builds
    whose files do not change between them: nothing here looks at the files again."""

    def __init__(self) -> None:
        self._built: dict[tuple, tuple[Document, list, set[str], dict]] = {}

    def __len__(self) -> int:
        return len(self._built)


def build_facility(
    recipe: Recipe,
    output: Path,
    *,
    root: Path,
    seed: int | None = None,
    components: bool = True,
    workers: int = 0,
    cache_dir: Path | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    overwrite: bool = False,
    fold_fixtures: bool = True,
    parts: Parts | None = None,
) -> FacilityReport:
    """Compile ``recipe`` into the folder ``output``: on success, the files of an earlier
    build there are replaced and nothing else is touched. A non-empty ``output`` without
    our ``facility.json`` is refused unless ``overwrite``. ``fold_fixtures``: move static
    fixture geoms into their weld bodies (``urdf2mjcf.facility.fold``; the same
    contacts, a cheaper broad phase). ``parts``: attached components built by an earlier
    build of this recipe (:class:`Parts`), with ``components=False``."""
    output = Path(output)
    previous = out.check_folder(output, overwrite, MANIFEST, GENERATOR)
    root = root.resolve()
    top = data_path(root, recipe.path, recipe.xacro)
    if not top.is_file():
        raise InputError(
            f"top-level xacro '{recipe.xacro}' does not exist",
            file=recipe.path or top,
            element="xacro",
        )
    table = recipe.components
    placements = {n: p for n, p in recipe.placed().items() if recipe.enabled(n)}
    ranges = {n: recipe.jitter_ranges(n) for n in placements}
    free = {n for n in placements if table[n].free}
    moved, offsets = jittered(placements, ranges, free, seed)
    args = xacro_args(recipe, moved)
    # Rocks: the recipe's seeded scatter (--seed replaces its seed), clear of every placement.
    rocks, rock_seed = [], None
    if recipe.rocks.get("count"):
        rock_seed = seed if seed is not None else recipe.rocks["seed"]
        clear_of = [p.xyz[:2] for p in moved.values()]
        rocks = scatter(recipe.rocks, rock_seed, clear_of, recipe.path)
        args["rocks"] = rocks_arg(rocks)

    present = [n for n in table if n in moved]
    attached = [n for n in present if table[n].attach is not None]
    # every calibration file read before the first conversion: a bad one costs nothing
    calibrations = {n: _calibration_file(root, recipe, n, table[n]) for n in attached}
    # Passes on the scene in memory: what is written is what validation stepped.
    folding = fold.Fold(recipe.path) if fold_fixtures else None
    tagging = fiducials.Tags(
        [
            (n, table[n].prefix, tag)
            for n in present
            if n not in attached
            for tag in table[n].fiducials
        ],
        recipe=recipe.path,
    )

    with out.staged_folder(output) as stage:
        built: dict[str, Path] = {}
        attached_parts: list[attach.Part] = []
        placed: list = []
        links: set[str] = set()
        limits: dict[str, dict[str, dict[str, float]]] = {}
        for name in attached:  # each compiled once: the file in components/ is what is attached
            file = _component_file(table, present, name)
            part, tags, names, limits[name] = _attached_component(
                root,
                recipe,
                name,
                moved[name],
                stage / file if components else None,
                calibration=calibrations[name],
                workers=workers,
                cache_dir=cache_dir,
                progress=progress,
                kept=parts,
            )
            attached_parts.append(part)
            placed += tags
            links |= names
            if components:
                built[file.parts[1]] = file
        options = _convert_options(
            root,
            recipe,
            workers=workers,
            cache_dir=cache_dir,
            progress=progress,
            source=top,
            args=args,
            elsewhere=links,
        )
        if all(c.attach is not None for c in table.values() if c.roles is not None):
            options["actuator_config"] = None  # every robot brings its own actuators
        joined = attach.Attach(attached_parts, recipe=recipe.path)
        passes = [step for step in (joined, folding, tagging) if step is not None]
        config = api.make_options(args=args, scene=False, **options)
        if attached_parts:  # the world's <mujoco> may name the parts' bodies (a rover's weld)
            config = replace(config, extension=replace(config.extension, assembly=True))
        report = api.convert(top, stage / "scene.xml", config, model_passes=passes)
        placed += tagging.placed
        if components:
            assets = sorted(
                {table[n].asset: table[n] for n in present if n not in attached}.items()
            )
            for asset, comp in assets:
                src = data_path(root, recipe.path, comp.standalone)
                if not src.is_file():
                    log.info("no standalone description for %s (%s)", asset, comp.standalone)
                    continue
                target = stage / "components" / asset / f"{asset}.xml"
                comp_options = _component_options(
                    root, recipe, comp, src, workers=workers, cache_dir=cache_dir, progress=progress
                )
                api.convert(src, target, **comp_options)
                built[asset] = Path("components") / asset / f"{asset}.xml"
        roles = _roles(root, recipe.path, table, present)
        owned = component_motion_limits(table, present, report.motion_limits(), limits)
        for name, joints in owned.items():
            roles[name]["motion_limits"] = joints
        compiled = report.compiled  # validation's model of scene.xml as written
        assert compiled is not None  # the facility is always validated
        folded = folding.folded if folding is not None else None
        demo = _write_copies(stage, recipe, root)
        data = manifest(
            stage / "scene.xml",
            recipe,
            root,
            seed,
            moved,
            offsets,
            built,
            roles,
            compiled=compiled,
            fiducials=fiducials.manifest_entries(compiled, placed, moved) if placed else [],
            bundled={"recipe": bundle.RECIPE, "demo": demo},
        )
        if folded is not None and folded.moved:  # facility.json's fold.MANIFEST_KEY
            data = replace(data, folded_geoms=MappingProxyType(dict(folded.moved)))
        if rocks:
            entries = [asdict(r) for r in rocks]
            data = replace(data, rocks=Rocks.parse({"seed": rock_seed, "rocks": entries}))
        data = write_manifest(stage, data)
        out.install_folder(stage, output, previous, overwrite=overwrite, last=MANIFEST)
    return FacilityReport(
        output=output,
        scene=output / "scene.xml",
        manifest=data.to_json(),
        conversion=report,
        written=data,
        components={k: output / v for k, v in built.items()},
        compiled=compiled,
    )


def _component_file(table: Mapping[str, Component], present: list[str], name: str) -> Path:
    """``components/<asset>/<asset>.xml``, or ``components/<name>/<asset>.xml`` where
    the facility holds the asset more than once: each file is the model attached."""
    asset = table[name].asset
    shared = sum(table[n].asset == asset for n in present) > 1
    return Path("components") / (name if shared else asset) / f"{asset}.xml"


class _Keep:
    """The last pass of a component's conversion: keeps the document it writes."""

    result: Document | None = None

    def __call__(self, result: Document) -> Document:
        self.result = result
        return result


def _attached_component(
    root: Path,
    recipe: Recipe,
    name: str,
    pose: Pose2D,
    target: Path | None,
    *,
    calibration: Path | None = None,
    workers: int,
    cache_dir: Path | None,
    progress: Callable[[int, int, str], None] | None,
    kept: Parts | None = None,
) -> tuple[attach.Part, list, set[str], dict[str, dict[str, float]]]:
    """Compile component ``name`` on its own with its ``attach`` arguments and its tags,
    into ``target`` (validated, as every conversion) or, None, in memory only, with its
    ``calibration`` file applied (:func:`_calibration_file`); the
    part to attach at ``pose``, the tags placed, its link names and its joints' URDF 1.2
    motion limits (:func:`urdf2mjcf.report.motion_limits`)."""
    comp = recipe.components[name]
    src = data_path(root, recipe.path, comp.standalone)
    if not src.is_file():
        raise InputError(
            f"standalone description '{comp.standalone}' does not exist",
            file=recipe.path or src,
            element=f"components.{name}.standalone",
        )
    args = comp.attach_args(recipe.flags)
    key = (name, str(src), tuple(sorted(args.items())), str(calibration))
    if target is None and kept is not None and key in kept._built:
        result, placed, links, limits = kept._built[key]
        part = attach.Part(name, result, pose.xyz, attach.yaw_quat(pose.yaw))
        return part, list(placed), set(links), copy.deepcopy(limits)
    options = _component_options(
        root, recipe, comp, src, args, workers=workers, cache_dir=cache_dir, progress=progress
    )
    options["calibration"] = calibration
    tags = fiducials.Tags([(name, comp.prefix, tag) for tag in comp.fiducials], recipe=recipe.path)
    keep = _Keep()
    if target is not None:
        model = api.convert(src, target, args=args, model_passes=[tags, keep], **options).model
    else:
        model, result = api.build(src, api.make_options(args=args, **options))
        keep(tags(result))
    assert keep.result is not None and model is not None
    part = attach.Part(name, keep.result, pose.xyz, attach.yaw_quat(pose.yaw))
    links = {link.name for link in model.robot.links}
    limits = conversion_report.motion_limits(model)
    if target is None and kept is not None:
        kept._built[key] = (keep.result, list(tags.placed), set(links), copy.deepcopy(limits))
    return part, tags.placed, links, limits


def _calibration_file(root: Path, recipe: Recipe, name: str, comp: Component) -> Path | None:
    """The component's calibration file (key ``calibration``), read once here so that a
    missing or bad one is an error naming the recipe and the key before any conversion."""
    if comp.calibration is None:
        return None
    where = f"components.{name}.calibration"
    file = data_path(root, recipe.path, comp.calibration)
    shown = untrusted.excerpt(comp.calibration, 80)
    if not file.is_file():
        raise InputError(
            f"calibration file '{shown}' does not exist", file=recipe.path or file, element=where
        )
    try:
        calib_apply.load(file)
    except ForgeError as exc:
        at = f" {exc.element}" if exc.element else ""
        raise InputError(
            f"calibration file '{shown}'{at}: {exc.detail}", file=recipe.path or file, element=where
        ) from None
    return file


def component_motion_limits(
    table: Mapping[str, Component],
    present: Collection[str],
    world: Mapping[str, dict[str, float]],
    attached: Mapping[str, Mapping[str, dict[str, float]]],
) -> dict[str, dict[str, dict[str, float]]]:
    """Component name -> joint -> its URDF 1.2 motion limits, for the components whose
    descriptions state any (what facility.json lists under the component, for the
    runtime's planners: MuJoCo does not enforce them). An attached component's come from
    its own conversion (``attached``: its joints are named as in the facility); one of the
    top-level xacro's from the world's conversion (``world``): the joints under its prefix,
    the longest prefix where prefixes nest (a component without a prefix gets none: its
    joints cannot be told from the world's)."""
    out = {n: dict(attached[n]) for n in present if attached.get(n)}
    inline = sorted(
        (n for n in present if n not in attached and table[n].prefix),
        key=lambda n: -len(table[n].prefix),
    )
    for joint, limits in world.items():
        owner = next((n for n in inline if joint.startswith(table[n].prefix)), None)
        if owner is not None:
            out.setdefault(owner, {})[joint] = dict(limits)
    return out


RECIPE_HEADER = (
    "# The recipe this facility was built from, as built: --set edits applied, the\n"
    "# component table inline. Paths resolve beside this file, else under the facility\n"
    "# root. Written by make-facility (facility-demo --trials rebuilds from it).\n"
)


def _plain(value: Any) -> Any:
    """Recipe values as YAML's plain types: mappings as dicts, tuples as lists."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _component_data(comp: Component) -> dict:
    """A component table entry: the fields that differ from their defaults."""
    data: dict[str, Any] = {"asset": comp.asset, "standalone": comp.standalone}
    defaults = (("flag", None), ("prefix", ""), ("roles", None), ("free", False))
    for key, default in (*defaults, ("calibration", None)):
        if getattr(comp, key) != default:
            data[key] = getattr(comp, key)
    if comp.mechanisms is not None:
        data["mechanisms"] = comp.mechanisms
    if comp.attach is not None:
        data["attach"] = dict(comp.attach)
    if comp.pose is not None:
        data["pose"] = {"xyz": list(comp.pose.xyz), "yaw": comp.pose.yaw}
    if comp.fiducials:
        data["fiducials"] = [
            {"id": f.id, "link": f.link, "xyz": list(f.xyz), "rpy": list(f.rpy), "size": f.size}
            for f in comp.fiducials
        ]
    return data


def recipe_data(recipe: Recipe) -> dict:
    """``recipe`` as the data of a recipe file that reads back to it (``parse_recipe``):
    every section as parsed (defaults filled in), the component table inline."""
    data: dict[str, Any] = {"name": recipe.name}
    if recipe.description:
        data["description"] = recipe.description
    data["xacro"] = recipe.xacro
    data["components"] = {n: _component_data(c) for n, c in recipe.components.items()}
    data["flags"] = _plain(recipe.flags)
    data["placements"] = {
        n: {"xyz": list(p.xyz), "yaw": p.yaw} for n, p in recipe.placements.items()
    }
    data["jitter"] = {n: False if r is None else _plain(r) for n, r in recipe.jitter.items()}
    data["simulation"] = _plain(recipe.simulation)
    if recipe.actuator_config is not None:
        data["actuator_config"] = recipe.actuator_config
    data["gravcomp"] = recipe.gravcomp
    if recipe.rocks:
        data["rocks"] = _plain(recipe.rocks)
    data["noise"] = _plain(recipe.noise)
    if recipe.collision:
        data["collision"] = _plain(recipe.collision)
    return data


def recipe_text(recipe: Recipe) -> str:
    """The bundle's ``recipe.yaml``: :func:`recipe_data` as YAML (the same recipe, the
    same bytes)."""
    # leaf lists and mappings in flow style, as the recipes write them ([x, y, z])
    body = yaml.safe_dump(
        recipe_data(recipe),
        sort_keys=False,
        allow_unicode=True,
        width=100,
        default_flow_style=None,
    )
    return RECIPE_HEADER + body


def _write_copies(stage: Path, recipe: Recipe, root: Path) -> str | None:
    """The bundle's copies: ``recipe.yaml`` always, ``demo.yaml`` (the demo file for
    the recipe's name, else the published one: ``urdf2mjcf.demos.demo_source``) when the recipe
    places the robot the demo drives. The demo's name in the bundle, or None."""
    (stage / bundle.RECIPE).write_text(recipe_text(recipe), encoding="utf-8")
    if not recipe.places(DEMO_ROBOT):
        return None
    source = demo_source(root, recipe.name)
    if source is None:
        log.info("no demo under %s for %s: the bundle holds none", root, recipe.name)
        return None
    # regular files only, within the YAML limit: a root given by --root is the user's
    (stage / bundle.DEMO).write_bytes(untrusted.read_file(source, "yaml", what="demo file"))
    return bundle.DEMO


def _roles(
    root: Path, recipe_path: Path | None, table: Mapping[str, Component], present: list[str]
) -> dict[str, dict]:
    """Component name -> {prefix, roles, free}: what the manifest lists for each component."""
    out: dict[str, dict] = {}
    for name in present:
        comp = table[name]
        roles = None
        file = data_path(root, recipe_path, comp.roles) if comp.roles else None
        if file is not None and file.is_file():
            roles = read_yaml(file, "roles file")  # a bad one is an error naming it
        out[name] = {"prefix": comp.prefix, "roles": roles, "free": comp.free}
    return out
