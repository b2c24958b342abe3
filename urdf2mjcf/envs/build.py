"""A facility built once per recipe, package version and facility data, then reused.

An environment never compiles xacro on reset: it loads a facility built by
make-facility's Python API into a cache folder and randomizes the loaded model.
The folder's name is a hash of everything the build depends on (the recipe's
bytes, the package version, the bundle's schema version, every file under the facility
root's ``facility/``, ``meshes/`` and ``recipes/``), so an edited xacro or mesh, or a
bundle format the runtime no longer reads, is another folder, never a stale one.
``facility.json`` is installed last by the build, so a folder holding it is complete.
Processes building the same folder at once (pytest-xdist workers, a vector of
environments) take turns on a lock file; the second one finds it built.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
from collections.abc import Iterator
from pathlib import Path

from .. import __version__
from ..bundle import MANIFEST, SCHEMA_VERSION
from ..cache import default_cache_dir
from ..facility.build import build_facility
from ..facility.recipe import Recipe, load_recipe
from ..facility.root import DATA_DIRS, find_root, recipe_file

log = logging.getLogger(__name__)

SUBFOLDER = "facilities"
"""Where under the shared cache folder the environments' facilities are built."""

builds = 0
"""Facilities this process has built (a reset never adds to it; tests read it)."""


def _fingerprint(root: Path, recipe_path: Path) -> str:
    """sha256 over the package version, the bundle schema, the recipe's bytes and every
    data file's path and bytes (a few hundred kB: hashing them is cheaper than one stale
    build)."""
    h = hashlib.sha256(f"mjcf-forge {__version__} bundle {SCHEMA_VERSION}\n".encode())
    h.update(recipe_path.read_bytes())
    for sub in DATA_DIRS:
        for path in sorted((root / sub).rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts:
                h.update(str(path.relative_to(root)).encode() + b"\0")
                h.update(path.read_bytes())
    return h.hexdigest()


@contextlib.contextmanager
def _locked(lock: Path) -> Iterator[None]:
    """An exclusive lock on the file ``lock`` (kept afterwards: removing it while another
    process waits on it would let a third one in beside it)."""
    try:
        import fcntl
    except ImportError:  # not POSIX: one process at a time is the caller's business
        yield
        return
    with open(lock, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def resolve_recipe(recipe: str | Path, root: Path | None = None) -> tuple[Path, Path, Recipe]:
    """``(facility root, recipe file, recipe)`` for ``recipe``: a path, or a name under
    the facility root's ``recipes/`` (``imetro``, ``mira3d-floor``)."""
    found = find_root(root)
    given = Path(recipe)
    if given.suffix not in (".yaml", ".yml") and not given.exists():
        given = Path("recipes") / f"{recipe}.yaml"
    path = recipe_file(found, given, str(given))
    return found, path, load_recipe(path, root=found)  # an InputError naming a bad file


def facility_folder(
    recipe: str | Path, *, root: Path | None = None, cache_dir: Path | None = None
) -> tuple[Path, Recipe]:
    """The folder of the built facility of ``recipe`` (see :func:`resolve_recipe`),
    building it first if no build of the same inputs exists; and the recipe itself."""
    global builds
    root, path, loaded = resolve_recipe(recipe, root)
    key = _fingerprint(root, path)[:16]
    base = Path(cache_dir) if cache_dir is not None else default_cache_dir() / SUBFOLDER
    folder = base / f"{loaded.name}-{key}"
    if (folder / MANIFEST).is_file():
        return folder, loaded
    base.mkdir(parents=True, exist_ok=True)
    with _locked(base / f".{folder.name}.lock"):
        if not (folder / MANIFEST).is_file():  # another process may have built it meanwhile
            log.info("building %s into %s (once)", path, folder)
            build_facility(loaded, folder, root=root, components=False, overwrite=True)
            builds += 1
    return folder, loaded
