"""A built facility's folder, the bundle: its file names, the manifest's schema version,
and opening it: :func:`open_bundle` reads and checks ``facility.json`` once into the
typed :class:`~urdf2mjcf.bundle_manifest.Manifest` the runtime reads.

The builder (``urdf2mjcf.facility``) writes bundles and the runtime
(``urdf2mjcf.runner``) reads them; both take the format from here, so that the
runtime needs nothing but the bundle: no facility root, no recipes of a checkout.
A bundle holds ``scene.xml``, ``facility.json``, ``assets/``, ``components/``, the
recipe it was built from (``recipe.yaml``) and, when its recipe places the robot the
demo drives, the demo it was built for (``demo.yaml``); ``facility.json`` names the
two copies under ``"bundle"``. docs/facility.md describes every file and field.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from . import bundle_manifest, untrusted
from .bundle_manifest import Manifest
from .errors import BundleError, ForgeError

MANIFEST = "facility.json"
SCENE = "scene.xml"
RECIPE = "recipe.yaml"
"""The copy of the recipe the facility was built from, as built (see facility/build.py)."""
DEMO = "demo.yaml"
"""The copy of the demo (waypoints file) the facility was built for."""
SCHEMA_VERSION = bundle_manifest.SCHEMA_VERSION
"""The bundle format: the files above and the manifest's fields (docs/facility.md).
Raised when a field the runtime reads changes meaning or a file it needs moves; a
bundle of another version is refused, never half read."""
BUNDLE_KEY = bundle_manifest.BUNDLE_KEY
"""The manifest's section naming the recipe and demo copies (relative to the bundle)."""


@dataclass(frozen=True)
class Bundle:
    """A bundle opened and checked: its folder, its two main files and its manifest
    as typed values (:class:`~urdf2mjcf.bundle_manifest.Manifest`)."""

    folder: Path
    scene: Path
    manifest_path: Path
    manifest: Manifest

    def file(self, key: str, *, error: type[ForgeError] = BundleError) -> Path | None:
        """The bundle's copy ``key`` (``"recipe"``, ``"demo"``): :func:`bundled_file`."""
        return bundled_file(self.folder, self.manifest, key, self.manifest_path, error=error)


def open_bundle(path: str | Path, *, error: type[ForgeError] = BundleError) -> Bundle:
    """The bundle given as its folder or its scene.xml, its facility.json read once and
    checked (the schema version, every component and role, every field the runtime
    reads); one ``error`` naming the file and the key (``components.robot.roles.joints``)
    otherwise. The scene is not compiled here (``urdf2mjcf.runner.load`` does)."""
    scene, manifest_path = facility_files(path, error=error)
    manifest = bundle_manifest.read_manifest(manifest_path, error=error)
    return Bundle(scene.parent, scene, manifest_path, manifest)


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


def read_manifest(path: Path, *, error: type[ForgeError] = BundleError) -> Manifest:
    """A facility.json of this :data:`SCHEMA_VERSION`, read and checked
    (:func:`urdf2mjcf.bundle_manifest.read_manifest`); ``error`` naming the file and the
    key otherwise."""
    return bundle_manifest.read_manifest(path, error=error)


def bundled_file(
    folder: Path,
    manifest: Manifest,
    key: str,
    path: Path,
    *,
    error: type[ForgeError] = BundleError,
) -> Path | None:
    """The file the manifest's ``bundle.<key>`` names inside ``folder`` (``path``: the
    manifest, for errors); None when it names none (``null``). A key facility.json does
    not give, or a file that is not there, is ``error`` (a name that is not a plain
    relative path was refused as the manifest was read)."""
    element = f"{BUNDLE_KEY}.{key}"
    if key not in manifest.bundle.present:
        raise error("missing; rebuild the facility with make-facility", file=path, element=element)
    rel = getattr(manifest.bundle, key)
    if rel is None:
        return None
    target = Path(folder) / rel
    if not target.is_file():
        raise error(
            f"'{untrusted.excerpt(rel, 60)}' is not in the bundle; rebuild it with make-facility",
            file=path,
            element=element,
        )
    return target
