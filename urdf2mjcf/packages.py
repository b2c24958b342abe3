"""Find ROS packages and resolve resource URIs without a ROS installation.

Lookup order for a package name (first hit wins; docs/cli.md has the user's view):

1. ``--package NAME=DIR`` given explicitly;
2. ``--package-path DIR``: each sub-folder of DIR is a package, known by its
   folder name and by the ``<name>`` in its ``package.xml``; a DIR that is
   itself a package counts too;
3. ``ROS_PACKAGE_PATH`` (same rule as ``--package-path``);
4. ``AMENT_PREFIX_PATH``: ``<prefix>/share/<name>``;
5. the package that encloses the source: an ancestor folder whose
   ``package.xml`` names it, or whose folder name is the package name.

When none of these knows the name, fallbacks guess from the files people
actually ship. Each guess is recorded in :attr:`PackageResolver.notes` (the
parse pass turns them into warnings) and is an error when ``strict``:

6. a folder of that name beside the source or beside one of its ancestors
   (``package://meshes/x.stl`` with a ``meshes`` folder next to the URDF);
7. for a file (:meth:`PackageResolver.resolve` only): the same relative path
   inside the source's own package (nearest ancestor with ``package.xml``,
   else each ancestor, nearest first), for descriptions whose package was
   renamed (``abb_irb140_support`` URIs inside ``abb_irb140_description``);
8. for a file: a folder of that name a few levels below the source's own package
   that holds the relative path (URIs whose real package prefix was cut off,
   ``package://visual/base_link.dae``).

A file reference that resolves (by any step above, or as a relative path) to
a path that does not exist gets one more guess, a note like the others:

9. a file of the same name (case-sensitive, same extension) a few levels
   below the folder the reference resolved into: for a relative path the
   source's folder, then its own package (nearest ancestor with
   ``package.xml``); for a ``package://`` URI that package's folder
   (``meshes/coarse/link_0.stl`` shipped as ``meshes/link_0.stl``). Exactly
   one such file is used; several are an error naming them; none leaves the
   path as written, for the mesh pass to report. Of several, the one whose
   folders end like the reference's (``.../iiwa14/visual/link_0.obj``) is used
   when it is the only one sharing that many.
10. for a relative path (``./meshes/x.stl`` written from a ``urdf/`` folder), the same
    path one folder up, then the file's name in a ``meshes`` folder beside the source or
    one folder up: where a package's layout keeps its meshes. A note like the others.

Before the guesses 9 and 10 (and for a ``package://`` URI whose package is not found),
the folders the description's own ``<mujoco><compiler meshdir=... texturedir=...
assetdir=...>`` names (relative to the source) are searched for the path as written,
then for its file name alone, as MuJoCo's own URDF import finds it (without and with
``strippath``): that is how the description says where its files are, so it is no
guess.

``package://NAME`` with nothing after NAME, where NAME looks like a file
(``package://wheel.obj``), is the file NAME inside the folder given for that
package, else (a guess) a file NAME beside the source or an ancestor.

A file found by none of these is an error naming the URI (the parse pass drops
such a mesh with a warning unless ``strict``).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from urllib.parse import unquote

from . import untrusted
from .errors import ConversionError, PackageNotFoundError

_NAME_RE = re.compile(rb"<name>\s*([^<\s]+)\s*</name>")

DEEP_SEARCH_DEPTH = 5
"""How far below the own package fallback 8 looks (``meshes/<model>/visual`` is 3)."""
DEEP_SEARCH_MAX_DIRS = 20_000
"""Stop indexing a tree this large: the guess is not worth a long walk."""


def _package_xml_name(folder: Path) -> str | None:
    # a regular file within the description limit: a package.xml that is a FIFO or
    # /dev/zero (found while searching folders) is skipped, never opened
    try:
        text = untrusted.read_file(folder / "package.xml", "description")
    except ConversionError:
        return None
    match = _NAME_RE.search(text)
    return match.group(1).decode() if match else None


def _subdirs(folder: Path) -> list[Path]:
    """Sorted sub-folders (no hidden ones, no symlink loops); [] if unreadable."""
    try:
        entries = sorted(os.scandir(folder), key=lambda e: e.name)
    except OSError:
        return []
    out = []
    for entry in entries:
        try:
            if not entry.name.startswith(".") and entry.is_dir(follow_symlinks=False):
                out.append(Path(entry.path))
        except OSError:
            continue
    return out


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


def _index_files(root: Path) -> dict[str, list[Path]]:
    """File name -> files below ``root`` (``root`` itself included), breadth first,
    sorted within a level, at most ``DEEP_SEARCH_DEPTH`` levels down."""
    index: dict[str, list[Path]] = {}
    level, seen = [root], 0
    for _ in range(DEEP_SEARCH_DEPTH + 1):
        next_level = []
        for folder in level:
            try:
                entries = sorted(os.scandir(folder), key=lambda e: e.name)
            except OSError:
                continue
            for entry in entries:
                if entry.name.startswith("."):
                    continue
                try:
                    if entry.is_dir(follow_symlinks=False):
                        next_level.append(Path(entry.path))
                        seen += 1
                    elif entry.is_file():
                        index.setdefault(entry.name, []).append(Path(entry.path))
                except OSError:
                    continue
            if seen >= DEEP_SEARCH_MAX_DIRS:
                return index
        level = next_level
    return index


def _index_tree(root: Path) -> dict[str, list[Path]]:
    """Folder name -> folders below ``root``, breadth first, sorted within a level."""
    index: dict[str, list[Path]] = {}
    level, seen = [root], 0
    for _ in range(DEEP_SEARCH_DEPTH):
        next_level = []
        for folder in level:
            for sub in _subdirs(folder):
                index.setdefault(sub.name, []).append(sub)
                next_level.append(sub)
                seen += 1
                if seen >= DEEP_SEARCH_MAX_DIRS:
                    return index
        level = next_level
    return index


def _closest(found: list[Path], path: Path) -> list[Path]:
    """Of several files named like ``path``, the one whose folders end like ``path``'s
    (``.../iiwa_description/meshes/iiwa14/visual/link_0.obj`` for
    ``package://drake/manipulation/models/iiwa_description/meshes/iiwa14/visual/link_0.obj``)
    when exactly one shares more of them than any other and at least one; else all."""

    def shared(candidate: Path) -> int:
        n = 0
        for a, b in zip(reversed(candidate.parts[:-1]), reversed(path.parts[:-1]), strict=False):
            if a != b:
                break
            n += 1
        return n

    scores = [shared(f) for f in found]
    best = max(scores)
    return [found[scores.index(best)]] if best > 0 and scores.count(best) == 1 else found


def _in_folders(uri: str, folders: Sequence[Path]) -> Path | None:
    """The file ``uri`` names, in the first of ``folders`` that holds it: a relative path
    as written below the folder (MuJoCo's reading), else its file name alone (MuJoCo's
    with ``strippath``, and the only reading of a ``package://`` URI)."""
    name = unquote(uri.rstrip("/").rsplit("/", 1)[-1])
    if not name or name in (".", ".."):
        return None
    plain = "://" not in uri and not uri.startswith("file:") and not Path(uri).is_absolute()
    for folder in folders:
        for candidate in ((folder / unquote(uri)) if plain else None, folder / name):
            if candidate is not None and candidate.is_file():
                return candidate
    return None


@dataclass(frozen=True)
class PackageResolver:
    """Maps package names to folders and resource URIs to files."""

    source: Path
    """The file being converted; relative paths and the upward walk start here."""
    packages: Mapping[str, Path] = field(default_factory=dict)
    package_paths: tuple[Path, ...] = ()
    use_environment: bool = True
    strict: bool = False
    """A fallback guess (steps 6-8) is an error instead of a note."""
    notes: list[tuple[str, str]] = field(default_factory=list, compare=False, repr=False)
    """``(element, message)`` for each guess made, once per package and folder."""
    _memo: dict = field(default_factory=dict, init=False, compare=False, repr=False)
    """Resolved URIs and directory probes: each is looked at once per conversion."""

    # -- what is on disk (cached) ------------------------------------------

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

    @cached_property
    def _ancestors(self) -> tuple[Path, ...]:
        """The source's folder, its parent, ... up to the file-system root."""
        return tuple(self.source.resolve().parents)

    def _xml_name(self, folder: Path) -> str | None:
        key = ("xml", folder)
        if key not in self._memo:
            self._memo[key] = _package_xml_name(folder)
        return self._memo[key]

    @cached_property
    def _own_package(self) -> Path | None:
        """The nearest ancestor with a ``package.xml``: the package holding the source."""
        return next((a for a in self._ancestors if (a / "package.xml").is_file()), None)

    @cached_property
    def _tree(self) -> tuple[Path, dict[str, list[Path]]]:
        """Every folder below the own package (else below the source folder's parent)."""
        ancestors = self._ancestors
        root = self._own_package or (ancestors[1] if len(ancestors) > 1 else ancestors[0])
        return root, _index_tree(root)

    def _beside(self, name: str) -> list[Path]:
        """Folders called ``name`` beside the source or beside an ancestor, nearest first."""
        key = ("beside", name)
        if key not in self._memo:
            self._memo[key] = [a / name for a in self._ancestors if (a / name).is_dir()]
        return self._memo[key]

    # -- lookup ------------------------------------------------------------

    def _exact(self, name: str) -> Path | None:
        """Steps 1-5: the package itself, no guessing."""
        if name in self.packages:
            return Path(self.packages[name]).resolve()
        if name in self._indexed:
            return self._indexed[name]
        for ancestor in self._ancestors:
            if ancestor.name == name or self._xml_name(ancestor) == name:
                return ancestor
        return None

    def _guess(
        self,
        key: tuple,
        element: str | None,
        message: str,
        fix: str = "pass --package or --package-path",
    ) -> None:
        """Record a fallback once; with ``strict`` it is an error instead."""
        if self.strict:
            raise PackageNotFoundError(
                f"{message}; --strict allows no such guess: {fix}",
                file=self.source,
                element=element,
            )
        if key not in self._memo:
            self._memo[key] = True
            self.notes.append((element or "package", message))

    def _not_found(self, name: str, element: str | None, extra: str = "") -> PackageNotFoundError:
        return PackageNotFoundError(
            f"package '{name}' not found{extra}; pass --package {name}=DIR or --package-path "
            "with the folder that contains it",
            file=self.source,
            element=element,
        )

    def find(self, name: str, *, element: str | None = None) -> Path:
        """The folder of package ``name`` (steps 1-6); PackageNotFoundError if unknown."""
        found = self._exact(name)
        if found is not None:
            return found
        beside = self._beside(name)
        if not beside:
            raise self._not_found(name, element)
        return self._use_beside(name, beside[0], element)

    def _use_beside(self, name: str, folder: Path, element: str | None) -> Path:
        where = "the source" if folder.parent == self._ancestors[0] else "an ancestor of the source"
        message = f"package '{name}' is on no package path; using the folder {folder}"
        self._guess(("guess", name, folder), element, f"{message} beside {where}")
        return folder

    def _package_file(self, name: str, relative: str, element: str | None) -> Path:
        """``package://name/relative``: steps 1-5, else the first guess where the file exists."""
        found = self._exact(name)
        if found is not None:
            return found / relative  # the package exists; a missing file is the mesh pass's call
        for folder in self._beside(name):
            if (folder / relative).is_file():
                return self._use_beside(name, folder, element) / relative
        if relative:
            own = self._own_package
            for home in (own,) if own is not None else self._ancestors:
                if (home / relative).is_file():
                    label = self._xml_name(home) if own is not None else None
                    what = f"package '{label}'" if label else "the folder"
                    self._guess(
                        ("guess", name, home),
                        element,
                        f"package '{name}' not found; using the same paths inside {what} "
                        f"({home}), which holds the source",
                    )
                    return home / relative
            root, tree = self._tree
            for folder in tree.get(name, ()):
                if (folder / relative).is_file():
                    self._guess(
                        ("guess", name, folder),
                        element,
                        f"package '{name}' not found; using the folder {folder} "
                        f"(below {root}), which holds '{relative}'",
                    )
                    return folder / relative
        raise self._not_found(name, element, f" and no folder near the source holds '{relative}'")

    def _bare(self, name: str, element: str | None) -> Path:
        """``package://NAME`` with nothing after the name. Where NAME looks like a file
        (``package://wheel.obj``, seen in exports): the file NAME inside the folder given
        as that package, else a file NAME beside the source or an ancestor (a guess)."""
        if not Path(name).suffix:
            return self.find(name, element=element)
        found = self._exact(name)
        if found is not None:
            return found / name if (found / name).is_file() else found
        for folder in self._ancestors:
            if (folder / name).is_file():
                self._guess(
                    ("bare", name, folder),
                    element,
                    f"'package://{name}' names a file, not a package; using {folder / name}",
                    fix=f"write '{name}' as a path relative to the source",
                )
                return folder / name
        raise PackageNotFoundError(
            f"'package://{name}' names a file, not a package, and no file '{name}' is beside "
            f"the source; pass --package {name}=DIR with DIR the folder holding {name}",
            file=self.source,
            element=element,
        )

    def resolve(
        self,
        uri: str,
        *,
        element: str | None = None,
        base: Path | None = None,
        asset_dirs: Sequence[Path] = (),
    ) -> Path:
        """Resolve ``package://``, ``model://``, ``file://``, absolute and relative references.

        Odd forms seen in the wild: ``package:///pkg/x`` is ``package://pkg/x``
        unless ``/pkg/x`` is an existing absolute file; ``package://./x`` and
        ``file://x`` (no third slash) are relative. Relative paths are
        relative to ``base`` (default: the source file's folder). A file under
        a known package need not exist; one found by a fallback does.
        ``asset_dirs``: the folders the description's ``<mujoco><compiler>`` names
        (absolute), searched for the file's name before any guess.
        """
        base = base or self._ancestors[0]  # the source's folder, resolved once
        key = ("uri", uri, base, tuple(asset_dirs))
        if key not in self._memo:
            try:
                path = self._resolve(uri, element, base)
            except PackageNotFoundError:
                found = _in_folders(uri, asset_dirs)
                if found is None:
                    raise
                path = found
            if path.suffix and not path.exists():
                path = (
                    _in_folders(uri, asset_dirs)
                    or self._same_name(uri, path, element, base)
                )
            if path.suffix and not path.exists():
                path = self._layout(uri, path, element, base)
            self._memo[key] = path
        return self._memo[key]

    # -- step 10: where a package's layout keeps its meshes -------------------

    def _layout(self, uri: str, path: Path, element: str | None, base: Path) -> Path:
        """Step 10: a relative reference found one folder up, or by its name in a
        ``meshes`` folder beside the source or one folder up; else ``path``."""
        if "://" in uri or uri.startswith("file:") or Path(uri).is_absolute():
            return path
        relative = Path(unquote(uri))
        up = base.parent
        for candidate, where in (
            (up / relative, "one folder up"),
            (base / "meshes" / relative.name, "in the meshes folder beside the source"),
            (up / "meshes" / relative.name, "in the meshes folder one folder up"),
        ):
            if candidate != path and candidate.is_file():
                self._guess(
                    ("layout", uri, base),
                    element,
                    f"'{uri}' does not exist ({path}); using {candidate}, {where}, where "
                    "the package's layout keeps it",
                    fix="write the path where the file is",
                )
                return candidate
        return path

    # -- step 9: the same file name elsewhere in the package ----------------

    def _files(self, root: Path) -> dict[str, list[Path]]:
        """The file index of ``root``, built once per conversion."""
        key = ("files", root)
        if key not in self._memo:
            self._memo[key] = _index_files(root)
        return self._memo[key]

    def _search_roots(self, uri: str, path: Path, base: Path) -> list[Path]:
        """Where a missing ``path`` may have been shipped under another folder."""
        if uri.startswith(("package://", "model://")):
            rest = unquote(uri.split("://", 1)[1]).lstrip("/")
            name, _, relative = rest.partition("/")
            if name in (".", ".."):
                roots = [base]
            else:  # the package folder: ``path`` minus its relative part
                parts = len(Path(relative).parts)
                roots = [path.parents[parts - 1]] if 0 < parts <= len(path.parents) else []
        elif Path(uri).is_absolute() or uri.startswith("file:///"):
            return []  # an absolute path names no folder of ours
        else:
            roots = [base]
        own = self._own_package
        if own is not None and own not in roots and all(own in r.parents for r in roots):
            roots.append(own)  # a relative path: the source's package, after its folder
        return [r for r in roots if r.is_dir()]

    def _same_name(self, uri: str, path: Path, element: str | None, base: Path) -> Path:
        """Step 9: the one file called ``path.name`` below where ``uri`` points, else ``path``."""
        for root in self._search_roots(uri, path, base):
            found = self._files(root).get(path.name, [])
            several = len(found) > 1
            if several:
                found = _closest(found, path)
            if len(found) > 1:
                shown = ", ".join(str(f) for f in found)
                raise PackageNotFoundError(
                    f"'{uri}' does not exist ({path}); several files of that name below "
                    f"{root}: {shown}; write the path of the one meant",
                    file=self.source,
                    element=element,
                )
            if found:
                self._guess(
                    ("same name", uri, base),
                    element,
                    f"'{uri}' does not exist ({path}); using {found[0]}, "
                    + (
                        "of the files of that name the one whose folders end like the URI's"
                        if several
                        else "the only file of that name"
                    )
                    + f" below {root}",
                    fix="write the path where the file is",
                )
                return found[0]
        return path

    def _resolve(self, uri: str, element: str | None, base: Path) -> Path:
        for scheme in ("package://", "model://"):  # Gazebo model URIs: a folder, like a package
            if uri.startswith(scheme):
                rest = unquote(uri[len(scheme) :])
                if rest.startswith("/") and Path(rest).is_file():
                    return Path(rest)  # an absolute path written as a package URI
                name, _, relative = rest.lstrip("/").partition("/")
                if not name:
                    raise PackageNotFoundError(
                        f"malformed package URI '{uri}'", file=self.source, element=element
                    )
                if name in (".", ".."):
                    return base / name / relative
                if not relative:
                    return self._bare(name, element)
                return self._package_file(name, relative, element)
        if uri.startswith("file:"):
            rest = unquote(uri[len("file:") :])
            if rest.startswith("//"):
                rest = rest[2:]  # file:///abs -> /abs; file://rel -> rel (seen in exports)
                if rest.startswith("localhost/"):
                    rest = rest[len("localhost") :]
            path = Path(rest)
            return path if path.is_absolute() else base / path
        path = Path(uri)
        return path if path.is_absolute() else (base / path)
