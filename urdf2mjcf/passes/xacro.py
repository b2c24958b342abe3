"""The xacro pass, the first: expand xacro (with ``NAME:=VALUE`` arguments) into plain URDF.

Uses the ``xacro`` package itself, with ``$(find pkg)`` answered by our
:class:`~urdf2mjcf.packages.PackageResolver` instead of ament/rospack, so no
ROS installation is needed. Plain URDF files are read as they are, with two
liberties (each a warning, an error with ``strict``): XML that urdfdom reads
but libxml2 rejects is repaired (:mod:`urdf2mjcf.xml_repair`), and
``$(env)``, ``$(optenv)`` and ``$(find)`` left in attributes are substituted
as xacro would.
"""

from __future__ import annotations

import io
import logging
import re
import threading
import xml.parsers.expat
from collections.abc import Iterator, Mapping
from contextlib import contextmanager, redirect_stderr
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lxml import etree

from .. import untrusted, xml_repair
from ..errors import ConversionError, InputError, URDFError, XacroError
from ..ir import Note, UrdfDocument
from ..packages import PackageResolver
from . import xacro_install

log = logging.getLogger(__name__)

XACRO_NAMESPACES = ("http://www.ros.org/wiki/xacro", "http://ros.org/wiki/xacro")

# Extension elements whose attributes name things only ROS tools open (plugins,
# controller files): a $(find) there must not fail a conversion that never reads them.
_ROS_ONLY = ("gazebo", "ros2_control", "transmission")
# The substitutions a plain URDF gets; $(arg) and $(eval) need a xacro run and stay text.
_SUBSTITUTION = re.compile(r"\$\((?:env|optenv|find)\s[^()$]*\)")

# xacro keeps its state in module globals: one expansion at a time.
_LOCK = threading.Lock()


@dataclass(frozen=True)
class XacroConfig:
    args: Mapping[str, str] = field(default_factory=dict)
    """xacro arguments, as ``NAME:=VALUE`` on the command line."""
    packages: Mapping[str, Path] = field(default_factory=dict)
    """Explicit package locations (``--package NAME=DIR``)."""
    package_paths: tuple[Path, ...] = ()
    """Folders whose sub-folders are packages (``--package-path``)."""
    use_environment: bool = True
    """Also search ROS_PACKAGE_PATH and AMENT_PREFIX_PATH."""
    strict: bool = False
    """Repaired XML and substitution args in a plain URDF are errors, not warnings."""
    trust: bool = False
    """Run the description's code as stock xacro does (``--trust-xacro``); otherwise every
    expression is checked (:mod:`urdf2mjcf.passes.xacro_guard`)."""


def _needs_xacro(source: Path, data: bytes, args: Mapping[str, str]) -> bool:
    if source.suffix == ".xacro" or args:
        return True
    try:
        root = etree.fromstring(data)
    except etree.XMLSyntaxError as exc:
        line = exc.position[0] if exc.position else "?"
        raise InputError(f"malformed XML at line {line}: {exc.msg}", file=source) from None
    # A .urdf that uses xacro elements is still xacro (people do name them so).
    return any(
        isinstance(el.tag, str) and etree.QName(el).namespace in XACRO_NAMESPACES
        for el in root.iter()
    )


@contextmanager
def _patched_find(resolver: PackageResolver, found: list[Path] | None = None) -> Iterator[None]:
    """Route xacro's ``$(find pkg)`` and ``${find('pkg')}`` to our resolver (each
    folder found is appended to ``found``)."""
    from xacro import substitution_args as sa

    def find(pkg: str) -> str:
        folder = resolver.find(pkg, element=f"$(find {pkg})")
        if found is not None:
            found.append(folder)
        return str(folder)

    saved = sa._eval_find, sa._eval_dict.get("find")
    sa._eval_find = find
    sa._eval_dict["find"] = find
    try:
        yield
    finally:
        sa._eval_find = saved[0]
        sa._eval_dict["find"] = saved[1]


def _expand(
    source: Path, cfg: XacroConfig, resolver: PackageResolver, repaired: bytes | None = None
) -> tuple[bytes, list[str]]:
    import xacro

    chatter = io.StringIO()  # xacro prints its warnings; they belong in the report
    found: list[Path] = []
    with _LOCK, _patched_find(resolver, found), redirect_stderr(chatter), _yaml_state():
        try:
            with _guarded(source, cfg, found):
                doc = _process(xacro, source, cfg, repaired)
        except ConversionError:
            raise
        except Exception as exc:  # xacro raises many types; all are bad input here
            where = xacro.filestack[-1] if getattr(xacro, "filestack", None) else source
            where = where or source
            cause = exc
            while isinstance(cause, xacro.XacroException) and cause.exc:
                cause = cause.exc  # xacro wraps each level it passes through
            if isinstance(cause, ConversionError):
                raise cause from None
            if isinstance(exc, xml.parsers.expat.ExpatError):
                raise InputError(f"malformed XML: {exc}", file=where) from None
            msg = " ".join(str(exc).split()) or type(exc).__name__
            macros = [m.body.getAttribute("name") for m in (xacro.macrostack or [])]
            element = f"xacro macro '{macros[-1]}'" if macros else "xacro"
            raise XacroError(msg, file=where, element=element) from None
        finally:
            xacro.init_stacks(None)
    warnings = [
        line.strip()
        for line in chatter.getvalue().splitlines()
        if line.strip().lower().startswith("warning")
    ]
    return doc.toxml(encoding="utf-8"), warnings


def _process(xacro: Any, source: Path, cfg: XacroConfig, repaired: bytes | None) -> Any:
    if repaired is None:
        return xacro.process_file(str(source), mappings=dict(cfg.args))
    # xacro's own steps, fed the repaired bytes instead of the file
    xacro.init_stacks(str(source))
    doc = xacro.parse(io.BytesIO(repaired))
    xacro.process_doc(doc, mappings=dict(cfg.args))
    return doc


@contextmanager
def _guarded(source: Path, cfg: XacroConfig, found: list[Path]) -> Iterator[None]:
    """The expression checks, unless the user trusts the description."""
    if cfg.trust:
        yield
        return

    def roots() -> list[Path]:
        return _yaml_roots(source, cfg, found)

    with xacro_install.installed(roots, source):
        yield


def _yaml_roots(source: Path, cfg: XacroConfig, found: list[Path]) -> list[Path]:
    """Where ``xacro.load_yaml`` may read: the source's own package (nearest ancestor
    with a package.xml, else the source's folder), the packages given on the command
    line and every package ``$(find)`` resolved."""
    here = source.resolve().parent
    own = next((a for a in (here, *here.parents) if (a / "package.xml").is_file()), here)
    return [own, *map(Path, cfg.packages.values()), *cfg.package_paths, *found]


@contextmanager
def _yaml_state() -> Iterator[None]:
    """Stock xacro's load_yaml adds its unit tags (``!degrees``, whose constructor
    evaluates the scalar as an expression) to yaml.SafeLoader for the whole process:
    every later safe_load of a recipe would evaluate them. Undo that after each run."""
    import yaml

    own = yaml.SafeLoader.__dict__.get("yaml_constructors")
    saved = dict(own) if own is not None else None
    try:
        yield
    finally:
        current = yaml.SafeLoader.__dict__.get("yaml_constructors")
        if saved is None:
            if current is not None:
                del yaml.SafeLoader.yaml_constructors
        elif current is not None:
            current.clear()
            current.update(saved)


def run(source: Path, cfg: XacroConfig) -> UrdfDocument:
    source = Path(source)
    if not source.exists():
        raise InputError("no such file", file=source)
    resolver = PackageResolver(
        source=source,
        packages=dict(cfg.packages),
        package_paths=tuple(cfg.package_paths),
        use_environment=cfg.use_environment,
        strict=cfg.strict,
    )
    original = untrusted.read_file(source, "description", error=InputError)
    data, fixes = xml_repair.repair(original)
    notes = [_liberty(cfg, source, element, message, InputError) for element, message in fixes]
    if _needs_xacro(source, data, cfg.args):
        log.debug("expanding %s with xacro (args %s)", source, dict(cfg.args))
        repaired = data if fixes else None
        for _ in range(MAX_IGNORED_MACROS + 1):
            try:
                xml, warnings = _expand(source, cfg, resolver, repaired)
                break
            except XacroError as exc:
                stripped = _without_unknown_macro(exc, source, cfg, data, notes)
                if stripped is None:
                    raise
                data = repaired = stripped
        else:  # pragma: no cover - a file with more leftover macros than that
            raise XacroError(f"more than {MAX_IGNORED_MACROS} undefined macros", file=source)
        return UrdfDocument(
            source=source,
            xml=xml,
            resolver=resolver,
            expanded=True,
            warnings=tuple(warnings),
            notes=tuple(notes),
        )
    data, substituted = _substitute_plain(data, source, cfg, resolver)
    notes += substituted
    return UrdfDocument(source=source, xml=data, resolver=resolver, notes=tuple(notes))


MAX_IGNORED_MACROS = 100
"""Distinct undefined macros ignored in one plain ``.urdf`` before giving up."""
_UNKNOWN_MACRO = re.compile(r"unknown macro name: xacro:([\w.-]+)$")


def _without_unknown_macro(
    exc: XacroError, source: Path, cfg: XacroConfig, data: bytes, notes: list[Note]
) -> bytes | None:
    """``data`` without the calls of the macro ``exc`` says is unknown, where the source
    is a plain ``.urdf`` (leftover ``<xacro:grey/>`` calls of an export whose macro
    definitions are not shipped: urdfdom ignores unknown elements, and so do we, each
    macro one warning). None where that does not apply (a ``.xacro`` file, a call
    inside an included file)."""
    match = _UNKNOWN_MACRO.search(exc.detail)
    if match is None or source.suffix.lower() != ".urdf":
        return None
    if Path(str(exc.file)).resolve() != source.resolve():
        return None
    name = match.group(1)
    root = etree.fromstring(data)
    calls = [
        el
        for el in root.iter()
        if isinstance(el.tag, str)
        and etree.QName(el).namespace in XACRO_NAMESPACES
        and etree.QName(el).localname == name
    ]
    if not calls:
        return None
    for el in calls:
        parent = el.getparent()
        if parent is not None:
            parent.remove(el)
    message = (
        f"macro 'xacro:{name}' is defined nowhere (its definitions are not shipped); "
        f"{len(calls)} call(s) ignored, as urdfdom ignores unknown elements"
    )
    notes.append(_liberty(cfg, source, f"<xacro:{name}>", message, XacroError))
    return etree.tostring(root.getroottree(), encoding="utf-8", xml_declaration=True)


def _liberty(
    cfg: XacroConfig, source: Path, element: str, message: str, error: type[ConversionError]
) -> Note:
    """A warning naming file and element, or (``strict``) the error it stands for."""
    if cfg.strict:
        raise error(f"{message} (not accepted with --strict)", file=source, element=element)
    return Note("warning", f"{source}: {element}", message)


def _named_context(el: etree._Element) -> str:
    """``link 'base' <mesh>``: the nearest named ancestor, then the element."""
    for anc in el.iterancestors():
        if anc.get("name") and anc.getparent() is not None:
            return f"{anc.tag} '{anc.get('name')}' <{el.tag}>"
    return f"<{el.tag}>"


def _substitute_plain(
    data: bytes, source: Path, cfg: XacroConfig, resolver: PackageResolver
) -> tuple[bytes, list[Note]]:
    """``$(env)``, ``$(optenv)``, ``$(find)`` left in a plain URDF, resolved as xacro would.

    Tools that run every description through xacro (launch files) make these
    work; urdfdom would leave them and fail to find the file.
    """
    if b"$(" not in data:
        return data, []
    from xacro import substitution_args as sa

    tree = etree.fromstring(data).getroottree()
    notes = []
    for el in tree.getroot().iter():
        if not isinstance(el.tag, str) or any(
            a.tag in _ROS_ONLY for a in (el, *el.iterancestors())
        ):
            continue
        for attr, text in el.attrib.items():
            if not _SUBSTITUTION.search(text):
                continue
            where = f"{_named_context(el)} {attr}"
            try:
                with _LOCK, _patched_find(resolver):
                    value = _SUBSTITUTION.sub(lambda m: sa.resolve_args(m.group(0)), text)
            except ConversionError:
                raise
            except Exception as exc:  # xacro's substitution errors are bad input here
                msg = " ".join(str(exc).split()) or type(exc).__name__
                raise XacroError(f"'{text}': {msg}", file=source, element=where) from None
            if value == text:
                continue
            message = f"'{text}' in a plain URDF substituted as xacro would: '{value}'"
            notes.append(_liberty(cfg, source, where, message, URDFError))
            el.set(attr, value)
    if not notes:
        return data, []
    return etree.tostring(tree, encoding="utf-8", xml_declaration=True), notes
