"""Where the facility data (``facility/``, ``meshes/``, ``recipes/``) comes from.

In a checkout they sit at the top level of the repository; a wheel carries
them as ``urdf2mjcf/_data/`` (copied there by ``setup.py``). The root is, in
this order:

1. ``--root`` (or the nearest folder above it holding the data);
2. a checkout at or above the current folder, so that edits to its xacros
   take effect without reinstalling;
3. the installed data: ``urdf2mjcf/_data`` of a wheel, or, for an editable
   install (or a checkout on ``PYTHONPATH``), the checkout the package was
   imported from; there the two are the same files.
"""

from __future__ import annotations

import logging
from importlib import resources
from pathlib import Path

from ..errors import InputError
from ..untrusted import excerpt, is_folder_name

log = logging.getLogger(__name__)

DATA_DIRS = ("facility", "meshes", "recipes")
"""The folders a facility root holds (``setup.py`` ships the same ones)."""


def _is_root(folder: Path) -> bool:
    return (folder / "facility").is_dir() and (folder / "recipes").is_dir()


def _above(start: Path) -> Path | None:
    here = start.resolve()
    return next((f for f in (here, *here.parents) if _is_root(f)), None)


def installed_data() -> Path | None:
    """The data that came with the package: the wheel's copy or, editable, its checkout."""
    package = resources.files("urdf2mjcf")
    # Only a package on the file system can serve xacro and mesh files by path.
    if not isinstance(package, Path):
        return None
    for folder in (package / "_data", package.parent):
        if _is_root(folder):
            return folder.resolve()
    return None


def find_root(start: Path | None = None) -> Path:
    """The facility root: at or above ``start`` (``--root``) if given, else see the module."""
    if start is not None:
        found = _above(Path(start))
        if found is None:
            raise InputError(
                "no facility root (a folder with facility/ and recipes/) here or above",
                file=Path(start),
            )
        return found
    found = _above(Path.cwd()) or installed_data()
    if found is None:
        raise InputError(
            "no facility root (a folder with facility/ and recipes/) here or above, "
            "and the installed package carries none; pass --root",
            file=Path.cwd(),
        )
    log.info("facility root: %s", found)
    return found


def is_installed(root: Path) -> bool:
    """Whether ``root`` is the wheel's own copy (inside the installed package)."""
    return root.resolve().name == "_data" and root.resolve().parent.name == "urdf2mjcf"


def default_output(root: Path, name: str) -> Path:
    """``build/<name>`` in a checkout; in the current folder when the root is the wheel's
    copy, which belongs to the installation and is never written to. ``name`` (the
    recipe's, checked where it is read) must be one plain folder name: never a path
    that leads out of ``build/`` or is ``build/`` itself."""
    if not is_folder_name(name):
        raise InputError(
            f"recipe name '{excerpt(str(name))}' is not a plain folder name", element="name"
        )
    return Path("build") / name if is_installed(root) else root / "build" / name


def recipe_file(root: Path, given: Path | None, default: str) -> Path:
    """The recipe a user named: the path as given if it exists, else the same relative
    path under the root (``make-facility recipes/mira3d-moon.yaml`` from any folder);
    none named: ``default`` under the root."""
    if given is None:
        return root / default
    given = Path(given)
    if given.exists() or given.is_absolute() or not (root / given).is_file():
        return given
    return root / given


def data_path(root: Path, recipe_path: Path | None, rel: str | Path) -> Path:
    """A path a recipe names (xacro, standalone, roles, actuator file): the user's own file
    beside the recipe if there is one, else ours under the facility root."""
    rel = Path(rel)
    if rel.is_absolute():
        return rel
    if recipe_path is not None:
        own = Path(recipe_path).resolve().parent / rel
        if own.exists():
            return own
    return root / rel
