"""Pass 1: expand xacro (with ``NAME:=VALUE`` arguments) into plain URDF.

Uses the ``xacro`` package itself, with ``$(find pkg)`` answered by our
:class:`~urdf2mjcf.packages.PackageResolver` instead of ament/rospack, so no
ROS installation is needed. Plain URDF files are read as they are.
"""

from __future__ import annotations

import io
import logging
import threading
import xml.parsers.expat
from collections.abc import Mapping
from contextlib import contextmanager, redirect_stderr
from dataclasses import dataclass, field
from pathlib import Path

from lxml import etree

from ..errors import ConversionError, InputError, XacroError
from ..ir import UrdfDocument
from ..packages import PackageResolver

log = logging.getLogger(__name__)

XACRO_NAMESPACES = ("http://www.ros.org/wiki/xacro", "http://ros.org/wiki/xacro")

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
def _patched_find(resolver: PackageResolver):
    """Route xacro's ``$(find pkg)`` and ``${find('pkg')}`` to our resolver."""
    from xacro import substitution_args as sa

    def find(pkg: str) -> str:
        return str(resolver.find(pkg, element=f"$(find {pkg})"))

    saved = sa._eval_find, sa._eval_dict.get("find")
    sa._eval_find = find
    sa._eval_dict["find"] = find
    try:
        yield
    finally:
        sa._eval_find = saved[0]
        sa._eval_dict["find"] = saved[1]


def _expand(source: Path, cfg: XacroConfig, resolver: PackageResolver) -> tuple[bytes, list[str]]:
    import xacro

    chatter = io.StringIO()  # xacro prints its warnings; they belong in the report
    with _LOCK, _patched_find(resolver), redirect_stderr(chatter):
        try:
            doc = xacro.process_file(str(source), mappings=dict(cfg.args))
        except ConversionError:
            raise
        except Exception as exc:  # xacro raises many types; all are bad input here
            where = xacro.filestack[-1] if getattr(xacro, "filestack", None) else source
            where = where or source
            cause = exc.exc if isinstance(exc, xacro.XacroException) and exc.exc else exc
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


def run(source: Path, cfg: XacroConfig) -> UrdfDocument:
    source = Path(source)
    if not source.is_file():
        raise InputError("no such file", file=source)
    resolver = PackageResolver(
        source=source,
        packages=dict(cfg.packages),
        package_paths=tuple(cfg.package_paths),
        use_environment=cfg.use_environment,
    )
    data = source.read_bytes()
    if _needs_xacro(source, data, cfg.args):
        log.debug("expanding %s with xacro (args %s)", source, dict(cfg.args))
        xml, warnings = _expand(source, cfg, resolver)
        return UrdfDocument(
            source=source, xml=xml, resolver=resolver, expanded=True, warnings=tuple(warnings)
        )
    return UrdfDocument(source=source, xml=data, resolver=resolver)
