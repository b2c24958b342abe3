"""Safe output.

Atomic: everything is written to a temporary folder beside the target,
validated there, and only then moved into place, so a failed run leaves
nothing behind.

Ours only: we never delete or overwrite what we did not write. An existing
file is replaced only with ``--overwrite`` (or, for a JSON report, when it is
one of ours: it names our command as ``"generator"``). An existing folder is
built into only when it is empty or holds our manifest from an earlier run;
then the files that manifest lists are replaced and everything else in the
folder is kept. ``--overwrite`` lets us build into any folder, still keeping
the files we did not write.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import Any

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


def _temp_folder(parent: Path, prefix: str, made: list[Path]) -> Path:
    """Make a new, uniquely named folder in ``parent``, its name put in ``made``
    before it exists: an interrupt (Ctrl-C, SIGTERM) landing the instant after the
    folder is made still leaves the caller its name to remove (``tempfile.mkdtemp``
    returns it only afterwards, and a SIGTERM sent on seeing the folder lands there)."""
    while True:
        path = parent / f"{prefix}{secrets.token_hex(6)}"
        if path.exists():  # someone's: never put in ``made``, not even for an instant
            continue
        made.append(path)
        try:
            path.mkdir(mode=0o700)
        except FileExistsError:  # another process took the name this instant: not ours
            made.remove(path)
            continue
        return path


def _remove_all(folders: Sequence[Path]) -> None:
    for folder in folders:
        shutil.rmtree(folder, ignore_errors=True)


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; the ones created, deepest first."""
    missing = [p for p in (folder, *folder.parents) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    return missing


def _remove_if_empty(folders: Sequence[Path]) -> None:
    for f in folders:  # deepest first; one a user has put something in stays
        try:
            f.rmdir()
        except OSError:
            return


def write_atomic(
    output: Path, files: Mapping[str, bytes], validate: Callable[[Path], None]
) -> list[Path]:
    """Write ``files`` (paths relative to ``output``'s folder; ``output.name``
    among them), call ``validate`` on the staged ``output``, then move into place.

    Assets go first and the main file last, so a reader never sees an MJCF
    whose meshes are missing. Returns the final paths. Files already in the
    folder that are not in ``files`` are never touched.
    """
    folder = output.parent
    created = _make_parents(folder)
    made: list[Path] = []
    final: list[Path] = []
    try:
        stage = _temp_folder(folder, ".urdf2mjcf-", made)
        for rel, data in files.items():
            path = stage / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        validate(stage / output.name)
        order = sorted(files, key=lambda rel: (rel == output.name, "/" not in rel, rel))
        for rel in order:
            target = folder / rel
            new = not target.exists()
            _make_parents(target.parent)
            os.replace(stage / rel, target)
            if new:
                final.append(target)
        return [folder / rel for rel in order]
    except BaseException:
        for path in final:  # only files that did not exist before: nothing of the user's
            path.unlink(missing_ok=True)
        _remove_all(made)
        _remove_if_empty(created)
        raise
    finally:
        _remove_all(made)


# -- single files we write (JSON reports) -------------------------------------------------


def _json_object(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def check_file(path: Path, overwrite: bool, generator: str) -> None:
    """Before the work: refuse to write ``path`` over a file we did not write.

    A file is ours when it is a JSON object whose ``"generator"`` is ``generator``."""
    if path.is_dir():
        raise OutputError("is a folder; give the file to write", file=path)
    if path.exists() and not overwrite:
        data = _json_object(path)
        if data is None or data.get("generator") != generator:
            raise OutputError(
                f"already exists and is not a report of {generator}; "
                "pass --overwrite to replace it",
                file=path,
            )


def write_json(path: Path, data: Mapping[str, Any], generator: str) -> None:
    """``data`` as JSON with ``"generator"`` first, written atomically (temp file, rename)."""
    text = json.dumps({"generator": generator, **data}, indent=2, default=float) + "\n"
    created = _make_parents(path.parent)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}-", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        _remove_if_empty(created)
        raise


# -- folders we build (make-facility's output, facility-demo's frames) --------------------


def list_files(folder: Path) -> list[str]:
    """Every file under ``folder``, as sorted relative POSIX paths."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())


def _inside(folder: Path, rel: Any) -> bool:
    """Whether a manifest's entry is a plain relative path that stays inside ``folder``."""
    if not isinstance(rel, str) or not rel:
        return False
    pure = PurePosixPath(rel)
    if pure.is_absolute() or ".." in pure.parts or "\\" in rel:
        return False
    return (folder / rel).resolve().is_relative_to(folder.resolve())


def owned_files(folder: Path, manifest_name: str, generator: str) -> list[str] | None:
    """The files (relative paths) our manifest in ``folder`` says an earlier run wrote,
    the manifest included; None when there is no manifest of ours."""
    data = _json_object(folder / manifest_name)
    if data is None or data.get("generator") != generator:
        return None
    files = data.get("files")
    if not isinstance(files, list) or not all(_inside(folder, rel) for rel in files):
        return None  # a list we cannot trust is no licence to delete
    return sorted({*files, manifest_name})


def check_folder(folder: Path, overwrite: bool, manifest_name: str, generator: str) -> list[str]:
    """Before the work: may we build into ``folder``? Returns the files an earlier run of
    ours left there (to be replaced). Refuses a file, and a non-empty folder without our
    manifest unless ``overwrite``."""
    if not folder.exists():
        return []
    if not folder.is_dir():
        raise OutputError("exists and is not a folder", file=folder)
    owned = owned_files(folder, manifest_name, generator)
    if owned is not None:
        return owned
    if any(folder.iterdir()) and not overwrite:
        raise OutputError(
            f"folder is not empty and holds no {manifest_name} of an earlier {generator}; "
            "pass --overwrite to write into it (files we did not write are kept)",
            file=folder,
        )
    return []


@contextmanager
def staged_folder(output: Path) -> Iterator[Path]:
    """A temporary folder beside ``output`` to build in. On failure it is removed, with
    any parent folders made for it, so nothing is left behind."""
    created = _make_parents(output.parent)
    made: list[Path] = []
    try:
        yield _temp_folder(output.parent, f".{output.name}-", made)
    except BaseException:
        _remove_all(made)
        _remove_if_empty(created)
        raise
    _remove_all(made)


def install_folder(
    stage: Path, output: Path, previous: Sequence[str], *, overwrite: bool, last: str
) -> list[str]:
    """Move every file of ``stage`` into ``output`` (``last``, the manifest, last of all).

    ``previous`` (from :func:`check_folder`) are the files an earlier run wrote; those
    the new run lacks are removed. Anything else in ``output`` is kept; a file of the
    user's at a path we write is replaced only with ``overwrite``. A failure part-way
    puts the earlier files back. Returns the files written (relative paths).
    """
    new = sorted(list_files(stage), key=lambda rel: (rel == last, "/" not in rel, rel))
    if not output.exists():
        os.replace(stage, output)
        return new
    ours = set(previous)
    clash = [rel for rel in new if rel not in ours and (output / rel).exists()]
    if clash and not overwrite:
        raise OutputError(
            f"would replace '{clash[0]}', which we did not write; pass --overwrite to replace it",
            file=output,
        )
    made: list[Path] = []
    moved: list[str] = []
    placed: list[str] = []
    try:
        trash = _temp_folder(output.parent, f".{output.name}-old-", made)
        for rel in sorted(ours | set(clash)):
            src = output / rel
            if src.is_file() or src.is_symlink():
                (trash / rel).parent.mkdir(parents=True, exist_ok=True)
                os.replace(src, trash / rel)
                moved.append(rel)
        for rel in new:
            target = output / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(stage / rel, target)
            placed.append(rel)
    except BaseException:
        for rel in placed:
            (output / rel).unlink(missing_ok=True)
        for rel in moved:
            os.replace(trash / rel, output / rel)
        raise
    finally:
        _remove_all(made)
    kept = set(new)
    for rel in moved:  # folders that only held our old files go too
        if rel not in kept:
            parents = (output / rel).parents
            _remove_if_empty([p for p in parents if p.is_relative_to(output) and p != output])
    return new
