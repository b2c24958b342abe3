"""Atomic output: everything is written to a temporary folder beside the
target, validated there, and only then moved into place, so a failed
conversion leaves nothing behind."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path

from .errors import OutputError


def check_target(output: Path, overwrite: bool, extra: tuple[str, ...] = ()) -> None:
    """Fail early when we would overwrite a file the user did not let us replace."""
    if output.suffix.lower() != ".xml":
        raise OutputError("output file must end in .xml", file=output)
    if output.exists() and output.is_dir():
        raise OutputError("output is a directory; give the .xml file to write", file=output)
    for path in (output, *(output.parent / name for name in extra)):
        if path.exists() and not overwrite:
            raise OutputError("already exists; pass --overwrite to replace it", file=path)


def write_atomic(
    output: Path, files: Mapping[str, bytes], validate: Callable[[Path], None]
) -> list[Path]:
    """Write ``files`` (paths relative to ``output``'s folder; ``output.name``
    among them), call ``validate`` on the staged ``output``, then move into place.

    Assets go first and the main file last, so a reader never sees an MJCF
    whose meshes are missing. Returns the final paths.
    """
    folder = output.parent
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".urdf2mjcf-", dir=folder))
    try:
        for rel, data in files.items():
            path = stage / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        validate(stage / output.name)
        order = sorted(files, key=lambda rel: (rel == output.name, "/" not in rel, rel))
        final = []
        for rel in order:
            target = folder / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(stage / rel, target)
            final.append(target)
        return final
    except BaseException:
        if created:
            shutil.rmtree(folder, ignore_errors=True)
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)
