"""The extension pass: the URDF's ``<mujoco>`` elements applied to the emitted MJCF.

A ``<robot>`` may carry top-level ``<mujoco>`` elements for what URDF cannot
say (see ``docs/extension.md``). They are applied in document order, each
child in document order, to the document emit produced:

* ``compiler``, ``option``, ``size``, ``visual``, ``statistic``: attributes
  merged into the generated element (child elements merged by tag);
* ``default``: merged as a tree into the top-level default (an existing class
  is merged into, a new one added);
* ``asset``, ``contact``, ``equality``, ``tendon``, ``actuator``, ``sensor``:
  children appended to the section; asset files are resolved like URDF meshes
  and copied into the asset folder under content-hash names;
* ``keyframe``: keys appended; a key named like an existing one replaces it;
* ``worldbody``: children added to the world body; ``body``, ``frame``,
  ``geom``, ``site``, ``camera``, ``light`` with ``parent="NAME"`` added to
  the body ``NAME`` (``world`` for the world body);
* ``override``: attributes of a generated (or earlier added) element, found
  by tag and name, set or replaced; ``attr=""`` removes one;
* ``collision``: skipped here; the collision pass read it (a link's collision shape).

Missing sections are created in Menagerie's order. The document is
re-serialised exactly as emit writes it, so a robot without ``<mujoco>``
comes out byte-identical. Generated keyframes are re-padded when added
bodies bring joints of their own. With ``check`` the merged model is compiled
once by MuJoCo, and an error in content that came from ``<mujoco>`` is
reported against that content rather than a line of the generated file.
"""

from __future__ import annotations

import copy
import logging
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

from lxml import etree

from .. import untrusted
from ..assets import content_name
from ..errors import MeshError, URDFError
from ..ir import Model, Note
from ..mjcf import joints as mjcf_joints
from ..mjcf.compile import LOCK
from ..mjcf.document import SECTIONS, Document, section
from ..packages import PackageResolver
from .meshes import LFS_MAGIC

log = logging.getLogger(__name__)

MERGED = ("compiler", "option", "size", "visual", "statistic")
"""Singleton sections: attributes merged, child elements merged by tag."""

APPENDED = ("asset", "contact", "equality", "tendon", "actuator", "sensor", "custom")
"""Sections whose children are appended in document order."""

BODY_LEVEL = ("body", "frame", "geom", "site", "camera", "light")
"""Elements that may sit directly in ``<mujoco>`` with ``parent="BODY"``."""

ELEMENTS = (*SECTIONS, *BODY_LEVEL, "collision", "override")
"""Everything a ``<mujoco>`` element may contain (``collision``: for the collision pass)."""

OVERRIDES: dict[str, tuple[str, tuple[str, ...] | None]] = {
    "body": ("worldbody", ("body",)),
    "joint": ("worldbody", ("joint", "freejoint")),
    "geom": ("worldbody", ("geom",)),
    "site": ("worldbody", ("site",)),
    "camera": ("worldbody", ("camera",)),
    "light": ("worldbody", ("light",)),
    "mesh": ("asset", ("mesh",)),
    "material": ("asset", ("material",)),
    "texture": ("asset", ("texture",)),
    "hfield": ("asset", ("hfield",)),
    "skin": ("asset", ("skin",)),
    "pair": ("contact", ("pair",)),
    "exclude": ("contact", ("exclude",)),
    "equality": ("equality", None),
    "tendon": ("tendon", None),
    "actuator": ("actuator", None),
    "sensor": ("sensor", None),
    "key": ("keyframe", ("key",)),
}
"""Override tag -> (section searched, element tags matched; None: any child).
``equality``, ``tendon``, ``actuator`` and ``sensor`` match every type."""

FILE_ATTRS = ("file", "fileright", "fileleft", "fileup", "filedown", "filefront", "fileback")
"""Asset attributes naming a file (the last six: cube textures)."""

COMPILER_PATHS = ("meshdir", "texturedir", "assetdir")
"""Ignored: asset files are copied beside the output and found there."""

COMPILER_FIXED = {
    "angle": (
        "radian",
        "every angle in the generated model is in radians (URDF's unit); "
        "write angles in <mujoco> content in radians too",
    ),
    "autolimits": ("true", 'joint and actuator ranges are written without limited="true"'),
    "inertiafromgeom": (
        "false",
        "inertials come from the URDF (repaired or estimated when missing); "
        "give bodies you add an <inertial>",
    ),
}
"""Compiler attributes the generated model depends on: (required value, why)."""

OPTION_RANGES: dict[tuple[str, str], tuple[float, float, bool]] = {
    ("option", "timestep"): (0.0, 1.0, False),
    ("option", "iterations"): (1, 10_000, True),
    ("option", "ls_iterations"): (1, 10_000, True),
    ("option", "noslip_iterations"): (0, 10_000, True),
    ("option", "ccd_iterations"): (1, 10_000, True),
    ("option", "sdf_iterations"): (1, 10_000, True),
    ("option", "sdf_initpoints"): (1, 10_000, True),
    ("global", "offwidth"): (1, 16_384, True),
    ("global", "offheight"): (1, 16_384, True),
    ("quality", "shadowsize"): (0, 16_384, True),
    ("quality", "offsamples"): (0, 64, True),
    ("quality", "numslices"): (1, 10_000, True),
    ("quality", "numstacks"): (1, 10_000, True),
    ("quality", "numquads"): (1, 10_000, True),
}
"""(element, attribute) of a merged section -> (low, high, integer). ``timestep`` is
in (0, 1] s (MuJoCo takes any positive one; validation steps at most
:attr:`~urdf2mjcf.passes.validate.ValidateConfig.max_steps` times); iteration
counts and render buffer sizes are bounded (each costs time or memory in
proportion). Every other number in ``compiler``, ``option``, ``size``, ``visual``
and ``statistic`` must be finite and at most :data:`MAX_MAGNITUDE` in size."""

MAX_MAGNITUDE = 1e12
"""Largest magnitude of a number in a merged section (gravity, tolerances, sizes)."""

MAX_MEMORY = 16 * 2**30
"""Largest ``<size memory>`` (bytes): MuJoCo allocates it for every ``MjData``."""

_PLURAL = {"body": "bodies", "equality": "equality constraints", "key": "keyframes"}


@dataclass(frozen=True)
class ExtensionConfig:
    enabled: bool = True
    """Apply ``<mujoco>`` elements; False ignores them."""
    resolver: PackageResolver | None = None
    """Resolves ``package://`` and relative asset files (pass the xacro pass's
    resolver); None: one built from the source path alone (environment
    variables and the folders above the source)."""
    check: bool = True
    """Compile the merged model once with MuJoCo and report an error in
    ``<mujoco>`` content against that content."""
    assembly: bool = False
    """The document is a world that parts are attached to afterwards (a facility's
    components, ``urdf2mjcf.facility.attach``): its ``<mujoco>`` content may name their
    bodies (a weld between the world's grains and a rover's base), so MuJoCo cannot
    compile it alone. An error is then left to the validation of the assembled scene,
    and keyframes are re-padded from the document's own poses."""


@dataclass
class _Context:
    root: etree._Element
    source: Path
    resolver: PackageResolver
    files: dict[str, bytes]
    notes: list[Note]
    origin: dict[etree._Element, str] = field(default_factory=dict)
    """Element -> the ``<mujoco>`` content it came from (for MuJoCo's errors)."""
    assembly: bool = False
    """:attr:`ExtensionConfig.assembly`: names may be of parts attached later."""

    def error(self, message: str, element: str) -> URDFError:
        return URDFError(message, file=self.source, element=element)

    def section(self, tag: str) -> etree._Element:
        return section(self.root, tag)

    @property
    def worldbody(self) -> etree._Element:
        return self.section("worldbody")


def run(result: Document, model: Model, cfg: ExtensionConfig) -> Document:
    extensions = [e for e in model.robot.extensions if e.tag == "mujoco"]
    if not cfg.enabled or not extensions:
        return result
    root = result.edit()
    source = model.robot.source
    ctx = _Context(
        root=root,
        source=source,
        resolver=cfg.resolver or PackageResolver(source=source),
        files=dict(result.files),
        notes=[],
        assembly=cfg.assembly,
    )
    layout = mjcf_joints.layout(root)
    owned = {key: key.get("qpos") for key in root.iterfind("keyframe/key")}
    for ext in extensions:
        _apply(ctx, ext.xml)

    if not ctx.assembly:  # an assembled world names the bodies of parts attached later
        _follow_merges(ctx)
    keys = [k for k, q in owned.items() if q is not None and k.get("qpos") == q and _attached(k)]
    if cfg.check or (keys and mjcf_joints.layout(root) != layout):
        _compile(ctx, keys, layout, assembly=cfg.assembly)

    return replace(
        result,
        root=root,
        files=ctx.files,
        qpos_home=_home(root, result.qpos_home),
        notes=result.notes + tuple(ctx.notes),
    )


# -- names the <mujoco> content gives that the model merged or lacks ---------

REFERENCES: dict[str, tuple[str, ...]] = {
    "body": ("body1", "body2", "body", "targetbody"),
    "site": ("site", "site1", "site2"),
    "joint": ("joint", "joint1", "joint2", "jointinparent"),
    "geom": ("geom1", "geom2"),
    "tendon": ("tendon", "tendon1", "tendon2"),
}
"""Attributes that name a model element of a kind (MJCF's; ``objname`` by ``objtype``)."""
OBJTYPES = {
    "body": "body",
    "xbody": "body",
    "site": "site",
    "joint": "joint",
    "geom": "geom",
    "tendon": "tendon",
}


def _references(el: etree._Element) -> list[tuple[str, str]]:
    """``(attribute, kind)`` of each name ``el`` gives of a model element."""
    out = [(a, kind) for kind, attrs in REFERENCES.items() for a in attrs if a in el.attrib]
    if el.tag in ("camera", "light") and "target" in el.attrib:
        out.append(("target", "body"))
    kind = OBJTYPES.get(el.get("objtype", ""))
    if kind is not None and "objname" in el.attrib:
        out.append(("objname", kind))
    return out


def _model_names(root: etree._Element) -> dict[str, set[str]]:
    """The names of the model's bodies, sites, joints and geoms (in the worldbody) and
    tendons."""
    names: dict[str, set[str]] = {kind: set() for kind in REFERENCES}
    names["body"].add("world")
    world = root.find("worldbody")
    for el in world.iter() if world is not None else ():
        tag = "joint" if el.tag == "freejoint" else el.tag
        if tag in names and el.get("name"):
            names[tag].add(el.get("name"))  # type: ignore[arg-type]
    for tendon in root.iterfind("tendon/*"):
        if tendon.get("name"):
            names["tendon"].add(tendon.get("name"))  # type: ignore[arg-type]
    return names


def _follow_merges(ctx: _Context) -> None:
    """A ``<mujoco>`` element naming a link that was fused into its parent (a fixed
    joint: the link left a site of its name in the body it joined) now names that body;
    one naming a body, site, joint, geom or tendon the model lacks (a typo, a link that
    is not there) is dropped, whole, with a warning naming it. Either way the robot
    converts, as urdfdom reads the description: its ``<mujoco>`` block is ours to
    apply, not a reason to refuse the robot."""
    names = _model_names(ctx.root)
    fused = {
        s.get("name"): s.getparent().get("name") or "world"  # type: ignore[union-attr]
        for s in ctx.worldbody.iter("site")
        if s.get("name") and s.get("name") not in names["body"]
    }
    for el, origin in list(ctx.origin.items()):
        top = el
        while top.getparent() is not None and top.getparent() is not ctx.root:
            top = top.getparent()  # type: ignore[assignment]
        if top.getparent() is None or top.tag not in (*APPENDED, "worldbody"):
            continue  # removed, or a merged section or default class: no names of elements
        for attr, kind in _references(el):
            name = el.get(attr, "")
            if name in names[kind]:
                continue
            if kind == "body" and name in fused:
                el.set(attr, fused[name])
                ctx.notes.append(
                    Note(
                        "info",
                        origin,
                        f"{attr}='{name}' names a link fused into body '{fused[name]}' "
                        "(a fixed joint): it names that body",
                    )
                )
                continue
            item = el  # in a section, its whole element goes (a tendon with a bad site)
            while top.tag != "worldbody" and item.getparent() is not top:
                item = item.getparent()  # type: ignore[assignment]
            item.getparent().remove(item)  # type: ignore[union-attr]
            known = _names(sorted(names[kind]))
            ctx.notes.append(
                Note(
                    "warning",
                    ctx.origin.get(item, origin),
                    f"{attr}='{untrusted.excerpt(name, 80)}' names no {kind} of the model; "
                    f"this element of the description's <mujoco> is dropped "
                    f"({'bodies' if kind == 'body' else kind + 's'}: {known})",
                )
            )
            break


# -- applying one <mujoco> element -------------------------------------------


def _apply(ctx: _Context, text: str) -> None:
    parser = etree.XMLParser(remove_blank_text=True, remove_comments=True, remove_pis=True)
    src = etree.fromstring(text.strip(), parser)
    etree.cleanup_namespaces(src)  # xacro's xmlns must not follow the children
    if src.attrib:
        raise ctx.error(f"takes no attributes; found {_names(src.attrib)}", "mujoco")
    _check_file_readers(ctx, src)
    applied: list[str] = []
    shapes = 0
    for child in _elements(src):
        tag = child.tag
        if tag == "collision":  # a link's collision shape: read by the collision pass
            shapes += 1
            continue
        if tag in MERGED:
            _merge_singleton(ctx, child)
        elif tag == "default":
            _merge_default(ctx, child)
        elif tag == "asset":
            _add_assets(ctx, child)
        elif tag in APPENDED:
            _append(ctx, child)
        elif tag == "keyframe":
            _merge_keys(ctx, child)
        elif tag == "worldbody":
            for el in _elements(child):
                _add_to_body(ctx, ctx.worldbody, el, f"mujoco worldbody {_label(el)}")
        elif tag in BODY_LEVEL:
            _add_body_level(ctx, child)
        elif tag == "override":
            if child.attrib:
                raise ctx.error(
                    f"takes no attributes; found {_names(child.attrib)}", "mujoco override"
                )
            for el in _elements(child):
                _override(ctx, el)
        else:
            shown = etree.QName(child).localname
            raise ctx.error(
                f"unknown element <{shown}>; valid: {', '.join(ELEMENTS)}", f"mujoco {shown}"
            )
        count = len(_elements(child))
        applied.append(
            _label(child) if tag in BODY_LEVEL or tag in MERGED or not count else f"{tag} ({count})"
        )
    if shapes and not applied:
        return  # only collision shapes, which the collision pass reported
    message = "applied " + (", ".join(applied) if applied else "nothing (empty)")
    ctx.notes.append(Note("info", "mujoco", message))
    log.debug("%s: mujoco: %s", ctx.source, message)


def _check_file_readers(ctx: _Context, src: etree._Element) -> None:
    """Refuse an element that would make MuJoCo open a file itself (``<include>``,
    ``<flexcomp file=...>``): only ``<asset>`` files are read, by us (regular files
    within the size limit, see :func:`_copy_files`), and copied beside the output."""
    for el in src.iter():
        if not isinstance(el.tag, str) or el is src:
            continue
        parent = el.getparent()
        if parent is src and el.tag not in ELEMENTS:
            continue  # an unknown top-level element: _apply lists the valid ones
        ours = parent is not None and (
            (parent.tag == "asset" and parent.getparent() is src)
            or (parent.tag == "override" and OVERRIDES.get(el.tag, ("",))[0] == "asset")
        )
        named = [k for k in FILE_ATTRS if el.get(k) is not None]
        if el.tag == "include" or (named and not ours):
            shown = etree.QName(el).localname
            raise ctx.error(
                f"<{shown}> would make MuJoCo read a file itself; only files of <asset> "
                "children are read (and copied beside the output)",
                f"mujoco {_label(el)}",
            )


def _check_numbers(ctx: _Context, src: etree._Element, origin: str) -> None:
    """Every number in a merged section (``option``, ``compiler``, ...) finite and in
    range (see :data:`OPTION_RANGES`); an error naming the element and attribute."""
    for el in src.iter():
        if not isinstance(el.tag, str):
            continue
        where = origin if el is src else f"{origin} {el.tag}"
        for key, value in el.items():
            if key == "memory" and el.tag == "size":
                _check_memory(ctx, value, where)
                continue
            words = value.split()
            try:
                numbers = [float(w) for w in words]
            except ValueError:
                continue  # a keyword ("elliptic", "enable"): MuJoCo checks it
            if not numbers:
                continue
            low, high, integer = OPTION_RANGES.get(
                (el.tag, key), (-MAX_MAGNITUDE, MAX_MAGNITUDE, False)
            )
            for x in numbers:
                bad = not math.isfinite(x) or not low <= x <= high
                if (el.tag, key) == ("option", "timestep"):
                    bad = bad or x <= 0.0
                if integer and not bad:
                    bad = x != int(x)
                if bad:
                    shown = untrusted.excerpt(value, 40)
                    kind = "an integer" if integer else "a finite number"
                    lo = "above" if (el.tag, key) == ("option", "timestep") else "from"
                    raise ctx.error(
                        f'{key}="{shown}" is out of range; expected {kind} {lo} {low:g} '
                        f"to {high:g}",
                        where,
                    )


def _check_memory(ctx: _Context, value: str, where: str) -> None:
    """``<size memory>``: ``-1`` or a byte count with an optional K, M, G suffix, at most
    :data:`MAX_MEMORY`."""
    text = value.strip()
    units = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40, "P": 2**50, "E": 2**60}
    match = re.fullmatch(r"(-?\d{1,20})\s*([KMGTPE]?)", text, flags=re.IGNORECASE)
    if text == "-1":
        return
    if match is None or int(match.group(1)) * units[match.group(2).upper()] > MAX_MEMORY:
        raise ctx.error(
            f'memory="{untrusted.excerpt(value, 40)}" is out of range; expected -1 or '
            f"at most {MAX_MEMORY // 2**30}G",
            where,
        )


def _elements(el: etree._Element) -> list[etree._Element]:
    return [c for c in el if isinstance(c.tag, str)]


def _label(el: etree._Element) -> str:
    name = el.get("name") or (el.get("class") if el.tag == "default" else None)
    return f"{el.tag} '{name}'" if name else str(el.tag)


def _names(items: Iterable[str], limit: int = 20) -> str:
    items = list(items)
    shown = ", ".join(items[:limit])
    return shown + (f", ... ({len(items) - limit} more)" if len(items) > limit else "")


def _copy(ctx: _Context, el: etree._Element, origin: str) -> etree._Element:
    new = copy.deepcopy(el)
    for part in new.iter():
        ctx.origin[part] = origin
    return new


def _merge_attrs(target: etree._Element, attrs: Iterable[tuple[str, str]]) -> None:
    """Set or replace attributes; an empty value removes the attribute."""
    for key, value in attrs:
        if value == "":
            target.attrib.pop(key, None)
        else:
            target.set(key, value)


def _merge_tree(ctx: _Context, target: etree._Element, src: etree._Element, origin: str) -> None:
    """Attributes merged, children merged into the same-tag child (created if missing)."""
    # Depth first with a stack, not recursion; the same-tag child is looked up when its
    # turn comes, so a repeated tag merges into the one its first sibling created.
    stack: list[tuple[etree._Element, etree._Element | None, etree._Element]] = [
        (target, target, src)
    ]
    while stack:
        parent, found, part = stack.pop()
        if found is None:
            found = parent.find(part.tag)
            if found is None:
                found = etree.SubElement(parent, part.tag)
        _merge_attrs(found, part.items())
        ctx.origin[found] = origin
        stack.extend((found, None, child) for child in reversed(_elements(part)))


def _merge_singleton(ctx: _Context, src: etree._Element) -> None:
    origin = f"mujoco {src.tag}"
    _check_numbers(ctx, src, origin)
    if src.tag == "compiler":
        kept = []
        for key, value in src.items():
            if key in COMPILER_PATHS:
                ctx.notes.append(
                    Note(
                        "info",
                        origin,
                        f'{key}="{value}" ignored: asset files are copied into the '
                        "output's asset folder and found there",
                    )
                )
            elif key in COMPILER_FIXED and value != COMPILER_FIXED[key][0]:
                required, why = COMPILER_FIXED[key]
                raise ctx.error(
                    f'{key}="{value}" is not supported; it stays "{required}": {why}', origin
                )
            else:
                kept.append((key, value))
        src = copy.deepcopy(src)
        src.attrib.clear()
        for key, value in kept:
            src.set(key, value)
    _merge_tree(ctx, ctx.section(src.tag), src, origin)


def _merge_default(ctx: _Context, src: etree._Element) -> None:
    cls = src.get("class")
    if cls not in (None, "main"):
        raise ctx.error(
            f"the top-level <default> is the model's own (class 'main'); put classes inside "
            f'it: <default><default class="{cls}">...</default></default>',
            f"mujoco default class '{cls}'",
        )
    top = ctx.section("default")
    _merge_attrs(top, ((k, v) for k, v in src.items() if k != "class"))
    _merge_classes(ctx, top, top, src)


def _merge_classes(
    ctx: _Context, top: etree._Element, target: etree._Element, src: etree._Element
) -> None:
    """Merge the default tree ``src`` into ``target``; classes are found anywhere under ``top``."""
    # Depth first with a stack, not recursion: each element meets the tree as it
    # stands after the elements before it in document order.
    stack = [(target, child) for child in reversed(_elements(src))]
    while stack:
        target, child = stack.pop()
        if child.tag == "default":
            cls = child.get("class")
            origin = f"mujoco default class '{cls}'"
            if not cls:
                raise ctx.error('a nested <default> needs class="NAME"', "mujoco default")
            existing = top if cls == "main" else _find_class(top, cls)
            if existing is None:
                existing = etree.SubElement(target, "default")
                existing.set("class", cls)
                ctx.origin[existing] = origin
            _merge_attrs(existing, ((k, v) for k, v in child.items() if k != "class"))
            stack.extend((existing, grandchild) for grandchild in reversed(_elements(child)))
            continue
        origin = f"mujoco default {child.tag}"
        if target is not top:
            origin = f"mujoco default class '{target.get('class')}' {child.tag}"
        existing = target.find(child.tag)
        if existing is None:
            existing = etree.Element(child.tag)
            first_class = target.find("default")
            if first_class is None:
                target.append(existing)
            else:  # element settings before nested classes, as Menagerie writes them
                first_class.addprevious(existing)
        _merge_tree(ctx, existing, child, origin)


def _find_class(top: etree._Element, cls: str) -> etree._Element | None:
    return next((d for d in top.iter("default") if d.get("class") == cls), None)


def _add_assets(ctx: _Context, src: etree._Element) -> None:
    section = ctx.section("asset")
    for child in _elements(src):
        origin = f"mujoco asset {_label(child)}"
        el = _copy(ctx, child, origin)
        if el.get("file") and el.get("name") is None:
            # MuJoCo names a file asset after its file; keep the name the user knows.
            attrs = [("name", Path(el.get("file", "")).stem), *el.items()]
            el.attrib.clear()
            for key, value in attrs:
                el.set(key, value)
            origin = f"mujoco asset {_label(el)}"
            ctx.origin[el] = origin
        _copy_files(ctx, el, origin)
        section.append(el)


def _copy_files(ctx: _Context, el: etree._Element, origin: str) -> None:
    """Resolve the file attributes of an asset element, copy the files, point at the copies."""
    compiler = ctx.root.find("compiler")
    attr = "texturedir" if el.tag == "texture" else "meshdir"
    folder = compiler.get(attr, "") if compiler is not None else ""
    for key in FILE_ATTRS:
        uri = el.get(key)
        if not uri:
            continue
        path = ctx.resolver.resolve(uri, element=origin)
        # a regular file within its size limit: a FIFO would block, /dev/zero fill memory
        kind = "texture" if el.tag in ("texture", "hfield") else "mesh"
        try:
            data = untrusted.read_file(path, kind, error=MeshError, what="file")
        except MeshError as exc:
            raise MeshError(exc.detail, file=ctx.source, element=origin) from None
        if data.startswith(LFS_MAGIC):
            raise MeshError(
                f"{path} is a Git LFS pointer, not a file; run 'git lfs pull' in its repository",
                file=ctx.source,
                element=origin,
            )
        name = content_name(path.stem, data) + path.suffix.lower()
        ctx.files[f"{folder}/{name}" if folder else name] = data
        el.set(key, name)


def _append(ctx: _Context, src: etree._Element) -> None:
    section = ctx.section(src.tag)
    for child in _elements(src):
        section.append(_copy(ctx, child, f"mujoco {src.tag} {_label(child)}"))


def _merge_keys(ctx: _Context, src: etree._Element) -> None:
    section = ctx.section("keyframe")
    for child in _elements(src):
        new = _copy(ctx, child, f"mujoco keyframe {_label(child)}")
        name = child.get("name")
        existing = next((k for k in section if name and k.get("name") == name), None)
        if existing is None:
            section.append(new)
        else:  # same place: 'home' stays key 0, the one viewers and our scene start from
            section.replace(existing, new)


def _add_body_level(ctx: _Context, src: etree._Element) -> None:
    origin = f"mujoco {_label(src)}"
    parent = src.get("parent")
    if not parent:
        raise ctx.error(
            'needs parent="BODY" naming the body to add it to (a link name, or "world"); '
            "or put it inside <worldbody>",
            origin,
        )
    el = copy.deepcopy(src)
    del el.attrib["parent"]
    body = _find_body(ctx, parent, origin)
    if body is not None:
        _add_to_body(ctx, body, el, origin)


def _find_body(ctx: _Context, name: str, origin: str) -> etree._Element | None:
    """The body called ``name``; for a link fused into its parent (a fixed joint: it left
    a site of its name), a frame at that site in the body it joined; else None, with a
    warning that the element is dropped (an error in an assembled world, whose parts
    are attached later)."""
    world = ctx.worldbody
    if name == "world":
        return world
    bodies = [b.get("name") for b in world.iter("body")]
    for body in world.iter("body"):
        if body.get("name") == name:
            return body
    site = next((s for s in world.iter("site") if s.get("name") == name), None)
    if site is not None:
        holder = site.getparent()
        assert holder is not None
        frame = etree.SubElement(holder, "frame")
        for attr in ("pos", "quat"):
            if site.get(attr) is not None:
                frame.set(attr, site.get(attr, ""))
        ctx.notes.append(
            Note(
                "info",
                origin,
                f"parent='{name}' names a link fused into body "
                f"'{holder.get('name') or 'world'}' (a fixed joint): added there, in a frame "
                "at the link's place",
            )
        )
        return frame
    known = _names(["world", *(b for b in bodies if b)])
    message = f"parent body '{untrusted.excerpt(name, 80)}' does not exist"
    if ctx.assembly:
        raise ctx.error(f"{message}; bodies: {known}", origin)
    ctx.notes.append(
        Note(
            "warning",
            origin,
            f"{message}; this element of the description's <mujoco> is dropped (bodies: {known})",
        )
    )
    return None


def _add_to_body(ctx: _Context, body: etree._Element, el: etree._Element, origin: str) -> None:
    """Append ``el`` to ``body``: bodies and frames last, other elements before them."""
    el = _copy(ctx, el, origin)
    first = next((c for c in body if c.tag in ("body", "frame")), None)
    if el.tag in ("body", "frame") or first is None:
        body.append(el)
    else:
        first.addprevious(el)


def _override(ctx: _Context, src: etree._Element) -> None:
    tag = src.tag
    if tag not in OVERRIDES:
        hint = ""
        if tag in ("position", "velocity", "motor", "general", "intvelocity", "damper"):
            hint = "; actuators of every type are overridden as <actuator name=...>"
        elif tag == "default":
            hint = "; default classes are changed by merging: <default><default class=...>"
        raise ctx.error(
            f"cannot override <{tag}>; valid: {', '.join(OVERRIDES)}{hint}",
            f"mujoco override {tag}",
        )
    name = src.get("name")
    if not name:
        raise ctx.error('needs name="..." naming the element to change', f"mujoco override {tag}")
    origin = f"mujoco override {tag} '{name}'"
    children = _elements(src)
    if children:
        raise ctx.error(
            f"an override only sets attributes; child <{children[0].tag}> is not allowed "
            "(add elements with the raw sections or parent=)",
            origin,
        )
    section_tag, tags = OVERRIDES[tag]
    section = ctx.root.find(section_tag)
    if section is None:
        candidates = []
    elif section_tag == "worldbody":
        candidates = list(section.iter(*(tags or ())))
    else:
        candidates = [c for c in _elements(section) if tags is None or c.tag in tags]
    target = next((c for c in candidates if c.get("name") == name), None)
    if target is None:
        plural = _PLURAL.get(tag, f"{tag}s")
        names = [n for n in (c.get("name") for c in candidates) if n]
        known = f"{plural}: {_names(names)}" if names else f"the model has no named {plural}"
        raise ctx.error(f"no {tag} '{name}' in the model; {known}", origin)
    attrs = copy.deepcopy(src)
    del attrs.attrib["name"]
    if section_tag == "asset":
        _copy_files(ctx, attrs, origin)
    _merge_attrs(target, attrs.items())
    ctx.origin[target] = origin


# -- keyframes and MuJoCo's verdict -------------------------------------------


def _attached(el: etree._Element) -> bool:
    return el.getparent() is not None


def _compile(
    ctx: _Context, keys: list[etree._Element], layout: list, *, assembly: bool = False
) -> None:
    """Compile the merged model without our keyframes; blame ``<mujoco>`` content for
    an error in it; re-pad our keyframes when joints were added. ``assembly``: an
    error is not blamed (parts are attached later) and keys are re-padded from the
    document's poses (:func:`~urdf2mjcf.mjcf.joints.joint_qpos0`)."""
    import mujoco

    places = [(k, k.getparent(), k.getparent().index(k)) for k in keys]  # type: ignore[union-attr]
    for key, parent, _ in places:
        parent.remove(key)
    etree.indent(ctx.root, space="  ")
    xml = etree.tostring(ctx.root, encoding="utf-8")
    error = None
    with LOCK:
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(lambda msg: None)  # validate reports warnings
        try:
            m = mujoco.MjModel.from_xml_string(xml.decode(), ctx.files)
        except ValueError as exc:
            error = str(exc)
        finally:
            mujoco.set_mju_user_warning(previous)
    for key, parent, index in reversed(places):
        parent.insert(index, key)
    if error is not None and assembly:  # where MuJoCo would start each joint, read here
        mjcf_joints.repad(
            keys,
            layout,
            [(el.get("name"), mjcf_joints.joint_qpos0(el)) for el in mjcf_joints.joints(ctx.root)],
        )
        return
    if error is not None:
        _blame(ctx, xml, error)
        log.debug("%s: merged model does not compile: %s", ctx.source, error)
        return  # not ours to report: validate will
    starts = []
    for j in range(m.njnt):
        adr = int(m.jnt_qposadr[j])
        width = {0: 7, 1: 4}.get(int(m.jnt_type[j]), 1)
        starts.append((m.joint(j).name, m.qpos0[adr : adr + width].tolist()))
    mjcf_joints.repad(keys, layout, starts)


def _blame(ctx: _Context, xml: bytes, error: str) -> None:
    """Raise against the ``<mujoco>`` content MuJoCo's ``error`` points at, if any."""
    element = None
    line = re.search(r"\bline (\d+)", error)
    if line:
        parsed = etree.fromstring(xml, etree.XMLParser(huge_tree=True))
        for mine, theirs in zip(ctx.root.iter(), parsed.iter(), strict=True):
            if theirs.sourceline == int(line.group(1)):
                element = mine
                break
    else:
        key = re.search(r"keyframe '([^']+)'", error)
        if key:
            element = next(
                (k for k in ctx.root.iterfind("keyframe/key") if k.get("name") == key.group(1)),
                None,
            )
    if element is None or element not in ctx.origin:
        return  # generated content: validate reports it
    detail = error.strip().splitlines()[0]
    detail = re.sub(r"^(XML Error: )?(Error: )?", "", detail).strip()
    name = element.get("name")
    what = f"<{element.tag} name='{name}'>" if name else f"<{element.tag}>"
    if detail.startswith("repeated name"):
        detail += " (to change an existing element, use <override>)"
    if "mass and inertia of moving bodies" in detail:
        detail += " (inertiafromgeom is false: give the body an <inertial>)"
    raise ctx.error(f"MuJoCo rejects {what}: {detail}", ctx.origin[element])


def _home(root: etree._Element, default: tuple[float, ...]) -> tuple[float, ...]:
    key = next((k for k in root.iterfind("keyframe/key") if k.get("name") == "home"), None)
    if key is None or not key.get("qpos"):
        return default
    try:
        return tuple(float(x) for x in key.get("qpos", "").split())
    except ValueError:
        return default
