"""Find ROS packages and resolve resource URIs without a ROS installation.

Lookup order for a package name (first hit wins):

1. ``--package NAME=DIR`` given explicitly;
2. ``--package-path DIR``: each sub-folder of DIR is a package, known by its
   folder name and by the ``<name>`` in its ``package.xml``; a DIR that is
   itself a package counts too;
3. ``ROS_PACKAGE_PATH`` (same rule as ``--package-path``);
4. ``AMENT_PREFIX_PATH``: ``<prefix>/share/<name>``;
5. walking up from the source file: an ancestor folder holding a
   ``package.xml`` is that package; an ancestor folder whose name is the
   package name is accepted too (descriptions vendored without package.xml).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from urllib.parse import unquote

from .errors import PackageNotFoundError

_NAME_RE = re.compile(rb"<name>\s*([^<\s]+)\s*</name>")


def _package_xml_name(folder: Path) -> str | None:
    try:
        text = (folder / "package.xml").read_bytes()
    except OSError:
        return None
    match = _NAME_RE.search(text)
    return match.group(1).decode() if match else None


def _scan(dirs: Sequence[Path]) -> dict[str, Path]:
    """Packages in each dir's immediate sub-folders (and the dir itself)."""
    found: dict[str, Path] = {}
    for base in dirs:
        if not base.is_dir():
            continue
        candidates = [base] + sorted(p for p in base.iterdir() if p.is_dir())
        for folder in candidates:
            names = [_package_xml_name(folder)]
            if folder != base:
                names.append(folder.name)
            for name in names:
                if name and name not in found:
                    found[name] = folder.resolve()
    return found


def _env_dirs(var: str) -> list[Path]:
    return [Path(p) for p in os.environ.get(var, "").split(os.pathsep) if p]


@dataclass(frozen=True)
class PackageResolver:
    """Maps package names to folders and resource URIs to files."""

    source: Path
    """The file being converted; relative paths and the upward walk start here."""
    packages: Mapping[str, Path] = field(default_factory=dict)
    package_paths: tuple[Path, ...] = ()
    use_environment: bool = True

    @cached_property
    def _indexed(self) -> dict[str, Path]:
        dirs = list(self.package_paths)
        if self.use_environment:
            dirs += _env_dirs("ROS_PACKAGE_PATH")
        found = _scan(dirs)
        if self.use_environment:
            for prefix in _env_dirs("AMENT_PREFIX_PATH"):
                share = prefix / "share"
                if share.is_dir():
                    for folder in sorted(p for p in share.iterdir() if p.is_dir()):
                        found.setdefault(folder.name, folder.resolve())
        return found

    def find(self, name: str, *, element: str | None = None) -> Path:
        """The folder of package ``name``; PackageNotFoundError if unknown."""
        if name in self.packages:
            return Path(self.packages[name]).resolve()
        if name in self._indexed:
            return self._indexed[name]
        for ancestor in self.source.resolve().parents:
            if ancestor.name == name or _package_xml_name(ancestor) == name:
                return ancestor
        raise PackageNotFoundError(
            f"package '{name}' not found; pass --package {name}=DIR or --package-path "
            "with the folder that contains it",
            file=self.source,
            element=element,
        )

    def resolve(self, uri: str, *, element: str | None = None, base: Path | None = None) -> Path:
        """Resolve ``package://``, ``file://``, absolute and relative references.

        ``package:///pkg/x`` (three slashes, seen in the wild) is read as
        ``package://pkg/x``. Relative paths are relative to ``base`` (default:
        the source file's folder). The file need not exist.
        """
        base = base or self.source.resolve().parent
        if uri.startswith("package://"):
            rest = uri[len("package://") :].lstrip("/")
            name, _, relative = rest.partition("/")
            if not name:
                raise PackageNotFoundError(
                    f"malformed package URI '{uri}'", file=self.source, element=element
                )
            return self.find(name, element=element) / unquote(relative)
        if uri.startswith("file://"):
            return Path(unquote(uri[len("file://") :]))
        if uri.startswith("model://"):
            # Gazebo model URIs name a folder on GAZEBO_MODEL_PATH; treat like a package.
            rest = uri[len("model://") :].lstrip("/")
            name, _, relative = rest.partition("/")
            return self.find(name, element=element) / unquote(relative)
        path = Path(uri)
        return path if path.is_absolute() else (base / path)
