"""A built facility's folder, the bundle: its file names, the manifest's schema version,
and reading and checking ``facility.json``.

The builder (``urdf2mjcf.facility``) writes bundles and the runtime
(``urdf2mjcf.runner``) reads them; both take the format from here, so that the
runtime needs nothing but the bundle: no facility root, no recipes of a checkout.
A bundle holds ``scene.xml``, ``facility.json``, ``assets/``, ``components/``, the
recipe it was built from (``recipe.yaml``) and, when its recipe places the robot the
demo drives, the demo it was built for (``demo.yaml``); ``facility.json`` names the
two copies under ``"bundle"``. docs/facility.md describes every file and field.
"""

from __future__ import annotations

import json
from pathlib import Path, PurePosixPath

from . import untrusted
from .errors import BundleError, ForgeError

MANIFEST = "facility.json"
SCENE = "scene.xml"
RECIPE = "recipe.yaml"
"""The copy of the recipe the facility was built from, as built (see facility/build.py)."""
DEMO = "demo.yaml"
"""The copy of the demo (waypoints file) the facility was built for."""
SCHEMA_VERSION = 1
"""The bundle format: the files above and the manifest's fields (docs/facility.md).
Raised when a field the runtime reads changes meaning or a file it needs moves; a
bundle of another version is refused, never half read."""
BUNDLE_KEY = "bundle"
"""The manifest's section naming the recipe and demo copies (relative to the bundle)."""

DEMO_ROBOT = "robot"
"""The component the demo drives (its roles): a recipe that places none gets no demo."""
DEMOS = "recipes/demo"
"""The demos under a facility root: ``<recipe name>.yaml`` for a recipe of its own."""
PUBLISHED_DEMO = "imetro.yaml"
"""The published demo, for a recipe with none of its own."""


def demo_source(root: Path, recipe_name: str) -> Path | None:
    """The demo a facility of ``recipe_name`` is built for: ``recipes/demo/<name>.yaml``
    under the facility root when there is one (the compact layout's), else the published
    ``recipes/demo/imetro.yaml``; None when the root holds neither."""
    demos = Path(root) / DEMOS
    if recipe_name and "/" not in recipe_name and "\\" not in recipe_name:
        own = demos / f"{recipe_name}.yaml"
        if own.is_file():
            return own
    published = demos / PUBLISHED_DEMO
    return published if published.is_file() else None


def facility_files(path: str | Path, *, error: type[ForgeError] = BundleError) -> tuple[Path, Path]:
    """``(scene.xml, facility.json)`` of a bundle given as its folder or a scene file;
    ``error`` naming the path when it is not one."""
    path = Path(path)
    if path.is_dir():
        scene = path / SCENE
        if not scene.is_file():
            raise error(
                f"no {SCENE}: not a facility folder (build one with make-facility)", file=path
            )
    elif not path.exists():
        raise error("does not exist", file=path)
    elif path.suffix.lower() != ".xml":
        raise error("not a facility: give its folder or its scene.xml", file=path)
    else:
        scene = path
    manifest = scene.parent / MANIFEST
    if not manifest.is_file():
        raise error(f"not a facility built by make-facility: no {MANIFEST} beside it", file=scene)
    return scene, manifest


def read_manifest(path: Path, *, error: type[ForgeError] = BundleError) -> dict:
    """A facility.json of this :data:`SCHEMA_VERSION` as a dict with a ``components``
    mapping; ``error`` naming the file (and the field) otherwise."""
    raw = untrusted.read_file(path, "report", error=error, what="manifest")
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else "not JSON"
        raise error(f"not a manifest of make-facility: {reason}", file=path) from None
    if isinstance(data, dict):
        check_schema_version(data, path, error=error)
    if not isinstance(data, dict) or not isinstance(data.get("components"), dict):
        raise error(
            "not a manifest of make-facility (no components)", file=path, element="components"
        )
    return data


def check_schema_version(data: dict, path: Path, *, error: type[ForgeError] = BundleError) -> None:
    """The manifest's ``schema_version`` is the one this version reads."""
    version = data.get("schema_version")
    if type(version) is int and version == SCHEMA_VERSION:
        return
    if "schema_version" not in data:
        said = "missing: the bundle was built by an older make-facility"
    else:
        shown = untrusted.excerpt(json.dumps(version), 40)
        said = f"{shown} is not {SCHEMA_VERSION}, the version this runtime reads"
    raise error(f"{said}; rebuild it with make-facility", file=path, element="schema_version")


def bundled_file(
    folder: Path,
    manifest: dict,
    key: str,
    path: Path,
    *,
    error: type[ForgeError] = BundleError,
) -> Path | None:
    """The file the manifest's ``bundle.<key>`` names inside ``folder`` (``path``: the
    manifest, for errors); None when it names none (``null``). A name that is not a
    plain relative path inside the bundle, or a file that is not there, is ``error``."""
    element = f"{BUNDLE_KEY}.{key}"
    section = manifest.get(BUNDLE_KEY)
    if not isinstance(section, dict) or key not in section:
        raise error("missing; rebuild the facility with make-facility", file=path, element=element)
    rel = section[key]
    if rel is None:
        return None
    pure = PurePosixPath(rel) if isinstance(rel, str) and rel else None
    if pure is None or pure.is_absolute() or ".." in pure.parts or "\\" in rel:
        shown = untrusted.excerpt(json.dumps(rel), 60)
        raise error(f"{shown} is not a file name inside the bundle", file=path, element=element)
    target = Path(folder) / rel
    if not target.is_file():
        raise error(
            f"'{untrusted.excerpt(rel, 60)}' is not in the bundle; rebuild it with make-facility",
            file=path,
            element=element,
        )
    return target
