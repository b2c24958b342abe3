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
import logging
import os
import re
import secrets
import shutil
import socket
import stat
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path, PurePosixPath
from typing import Any, BinaryIO

from .errors import ForgeError, OutputError
from .untrusted import limit_bytes, read_file

log = logging.getLogger(__name__)

MARKER = ".urdf2mjcf-staging"
"""In every staging and trash folder we make: which process made it (JSON)."""
JOURNAL = ".urdf2mjcf-journal"
"""In a trash folder: what the install moved, so that a killed one can be undone."""
_BACKUP = ".urdf2mjcf-old"
"""In a staging folder of :func:`write_atomic`: the files it replaced, until it is done."""

# -- our marks: which folders and files beside an output are ours, and stale ----------------


def _start_time(pid: int) -> str | None:
    """When process ``pid`` started (clock ticks since boot, Linux), or None: with the
    pid it names one process, never a later one that reuses the number."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat.rsplit(")", 1)[-1].split()
    return fields[19] if len(fields) > 19 and fields[0] != "Z" else None


def _alive(pid: Any, start: Any = None) -> bool:
    """Whether process ``pid`` (started at ``start``, when known) still runs here."""
    if not isinstance(pid, int) or pid <= 0:
        return False
    if pid == os.getpid():
        return True
    if Path("/proc/self/stat").exists():  # Linux: a zombie or a reused pid is no owner
        now = _start_time(pid)
        return now is not None and (start is None or str(start) == now)
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _mark(folder: Path, kind: str) -> None:
    """Write our :data:`MARKER` into a folder we just made."""
    data = {
        "pid": os.getpid(),
        "start": _start_time(os.getpid()),
        "host": socket.gethostname(),
        "kind": kind,
        "command": sys.argv,
    }
    (folder / MARKER).write_text(json.dumps(data) + "\n")


def _stale_mark(folder: Path) -> dict | None:
    """Our marker in ``folder`` when the process that wrote it is gone (on this host)."""
    marker = folder / MARKER
    if not marker.is_file() or marker.is_symlink():
        return None
    data = _json_object(marker)
    if data is None or data.get("host") != socket.gethostname():
        return None
    return None if _alive(data.get("pid"), data.get("start")) else data


def _hex_name(prefix: str) -> re.Pattern[str]:
    return re.compile(re.escape(prefix) + r"[0-9a-f]{12}")


def _tmp_name(prefix: str) -> re.Pattern[str]:
    return re.compile(re.escape(prefix) + r"(\d+)\.[0-9a-f]{12}\.tmp")


def clean_stale(parent: Path, name: str) -> None:
    """Remove what a killed run of ours left beside ``parent / name``: its staging and
    trash folders (our marker, its process gone; a trash folder's install is undone
    first), an empty one made the instant before the marker, and temporary files whose
    name holds a process id that is gone. Anything else is someone's and stays."""
    try:
        entries = sorted(parent.iterdir())
    except OSError:
        return
    stage, old, tmp = _hex_name(f".{name}-"), _hex_name(f".{name}-old-"), _tmp_name(f".{name}.")
    ours = _hex_name(".urdf2mjcf-")
    for entry in entries:
        if entry.is_symlink():
            continue
        if entry.is_dir() and any(p.fullmatch(entry.name) for p in (stage, old, ours)):
            _clean_folder(entry, parent / name)
        elif (m := tmp.fullmatch(entry.name)) and entry.is_file() and not _alive(int(m[1])):
            log.info("removing %s, left by a run that was killed", entry)
            entry.unlink(missing_ok=True)


_EMPTY_GRACE_S = 60.0
"""An empty staging folder younger than this may be a concurrent run's, not yet marked."""


def _clean_folder(folder: Path, output: Path) -> None:
    if not any(folder.iterdir()):  # made, killed before its marker: empty, nothing to lose
        # but not one a concurrent run made an instant ago and is about to mark
        if time.time() - folder.stat().st_mtime > _EMPTY_GRACE_S:
            folder.rmdir()
        return
    data = _stale_mark(folder)
    if data is None:
        return
    if data.get("kind") == "trash" and not _undo_install(folder, output):
        return
    log.info("removing %s, left by a run that was killed", folder)
    shutil.rmtree(folder, ignore_errors=True)


def check_target(output: Path, overwrite: bool, extra: tuple[str, ...] = ()) -> None:
    """Fail early when we would overwrite a file the user did not let us replace (a
    symlink, even a dangling one, is a file there)."""
    if output.suffix.lower() != ".xml":
        raise OutputError("output file must end in .xml", file=output)
    if output.is_dir():
        raise OutputError("output is a directory; give the .xml file to write", file=output)
    for path in (output, *(output.parent / name for name in extra)):
        try:
            mode = os.lstat(path).st_mode
        except OSError:
            continue  # nothing there (a folder we cannot read fails when it is written)
        if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):  # never opened, never replaced
            raise OutputError(
                f"is {_kind(mode)}, not a regular file; refused, even with --overwrite",
                file=path,
            )
        if not overwrite:
            raise OutputError("already exists; pass --overwrite to replace it", file=path)
    clean_stale(output.parent, "urdf2mjcf")


def _temp_folder(parent: Path, prefix: str, made: list[Path], kind: str = "staging") -> Path:
    """Make a new, uniquely named folder in ``parent`` holding our :data:`MARKER`, its
    name put in ``made`` before it exists: an interrupt (Ctrl-C, SIGTERM) landing the
    instant after the folder is made still leaves the caller its name to remove
    (``tempfile.mkdtemp`` returns it only afterwards, and a SIGTERM sent on seeing the
    folder lands there). A kill -9 before the marker leaves an empty folder, which
    :func:`clean_stale` removes."""
    while True:
        path = parent / f"{prefix}{secrets.token_hex(6)}"
        if os.path.lexists(path):  # someone's: never put in ``made``, not even for an instant
            continue
        made.append(path)
        try:
            path.mkdir(mode=0o700)
        except FileExistsError:  # another process took the name this instant: not ours
            made.remove(path)
            continue
        _mark(path, kind)
        return path


def _remove_all(folders: Sequence[Path]) -> None:
    for folder in folders:
        shutil.rmtree(folder, ignore_errors=True)


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; the ones created, deepest first."""
    missing = [p for p in (folder, *folder.parents) if not os.path.lexists(p)]
    folder.mkdir(parents=True, exist_ok=True)
    return missing


def _remove_if_empty(folders: Sequence[Path]) -> None:
    for f in folders:  # deepest first; one a user has put something in stays
        try:
            f.rmdir()
        except OSError:
            return


def _home(output: Path) -> Path:
    """The folder to stage ``output`` in: beside where it really is. A symlink at
    ``output`` may lead to another file system, where a rename from beside the link
    fails (EXDEV)."""
    if output.is_symlink() and output.is_dir():
        return output.resolve().parent
    return output.parent


# -- files of one conversion (urdf2mjcf -o) -------------------------------------------------


class _FilesInstall:
    """Staged files moved into ``folder`` and, until :meth:`discard`, the earlier files
    they replaced (hard links in the staging folder), so :meth:`rollback` can put them
    back. ``created``: the folders made for ``folder`` (deepest first), removed by
    :meth:`discard` when the install never happened or was rolled back: a failed run
    leaves no folder it made."""

    def __init__(
        self,
        stage: Path,
        folder: Path,
        order: list[str],
        made: list[Path],
        created: Sequence[Path] = (),
    ):
        self.stage, self.folder, self.order, self.made = stage, folder, order, made
        self.created = list(created)
        self.placed: list[tuple[str, bool]] = []
        self.dirs: list[list[Path]] = []
        self.done = False
        """Installed for good (the run succeeded): its folders stay."""

    def install(self) -> None:
        backup = self.stage / _BACKUP
        for rel in self.order:
            target = self.folder / rel
            kept = os.path.lexists(target)
            if kept:
                (backup / rel).parent.mkdir(parents=True, exist_ok=True)
                try:
                    os.link(target, backup / rel, follow_symlinks=False)
                except OSError:  # no hard links here: a copy serves
                    shutil.copy2(target, backup / rel, follow_symlinks=False)
            self.dirs.append(_make_parents(target.parent))
            os.replace(self.stage / rel, target)
            self.placed.append((rel, kept))

    def rollback(self) -> None:
        for rel, kept in reversed(self.placed):
            target = self.folder / rel
            if kept:
                os.replace(self.stage / _BACKUP / rel, target)
            else:
                target.unlink(missing_ok=True)
        self.placed.clear()
        for dirs in reversed(self.dirs):
            _remove_if_empty(dirs)

    def discard(self) -> None:
        _remove_all(self.made)
        if not self.done:
            _remove_if_empty(self.created)


class Together:
    """The outputs of one run, installed together or not at all (see :func:`together`)."""

    def __init__(self) -> None:
        self.installs: list[_FilesInstall] = []
        self.finally_: list[Callable[[], None]] = []

    def last(self, step: Callable[[], None]) -> None:
        """Run ``step`` (a report's rename) after every staged install; if it fails, they
        are rolled back."""
        self.finally_.append(step)

    def _commit(self) -> None:
        done: list[_FilesInstall] = []
        try:
            for inst in self.installs:
                done.append(inst)
                inst.install()
            for step in self.finally_:
                step()
            for inst in done:
                inst.done = True
        except BaseException:
            for inst in reversed(done):
                inst.rollback()
            raise


_TOGETHER: ContextVar[Together | None] = ContextVar("urdf2mjcf_output_together", default=None)


@contextmanager
def together() -> Iterator[Together]:
    """Within the block, :func:`write_atomic` stages and validates but installs only when
    the block ends without an error, followed by the steps given to
    :meth:`Together.last`; a failure of any of them undoes the others."""
    batch = Together()
    token = _TOGETHER.set(batch)
    try:
        yield batch
        _TOGETHER.reset(token)
        batch._commit()
    finally:
        if _TOGETHER.get() is batch:
            _TOGETHER.reset(token)
        for inst in batch.installs:
            inst.discard()


def write_atomic(
    output: Path, files: Mapping[str, bytes], validate: Callable[[Path], None]
) -> list[Path]:
    """Write ``files`` (paths relative to ``output``'s folder; ``output.name``
    among them), call ``validate`` on the staged ``output``, then move into place.

    Assets go first and the main file last, so a reader never sees an MJCF
    whose meshes are missing. Returns the final paths. Files already in the
    folder that are not in ``files`` are never touched. Inside :func:`together`
    the move waits for the end of its block.
    """
    folder = output.parent
    created = _make_parents(folder)
    made: list[Path] = []
    inst: _FilesInstall | None = None
    try:
        stage = _temp_folder(folder, ".urdf2mjcf-", made)
        for rel, data in files.items():
            if not _inside(stage, rel):  # names from a description or a cache entry
                raise OutputError(f"refused to write {rel!r}: not inside its folder", file=output)
            path = stage / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
        validate(stage / output.name)
        order = sorted(files, key=lambda rel: (rel == output.name, "/" not in rel, rel))
        inst = _FilesInstall(stage, folder, order, made, created)
        batch = _TOGETHER.get()
        if batch is not None:
            batch.installs.append(inst)  # it installs, and removes the stage, at its end
            made = []
        else:
            inst.install()
            inst.done = True
        return [folder / rel for rel in order]
    except BaseException:
        if inst is not None:
            inst.rollback()
        _remove_all(made)
        _remove_if_empty(created)
        raise
    finally:
        _remove_all(made)


# -- single files we write (JSON reports, plots, recordings) -------------------------------


def _json_object(path: Path) -> dict | None:
    """The JSON object in ``path``, or None: also when it is not a regular file (a FIFO
    at an output path must not block us) or is over the report size limit."""
    try:
        data = json.loads(read_file(path, "report").decode("utf-8"))
    except (ForgeError, OSError, UnicodeDecodeError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def read_own(path: Path, reader: Callable[[BinaryIO], Any]) -> Any:
    """``reader`` of the regular file at ``path`` (opened without blocking, not through
    a symlink, checked again once open), or None: a FIFO, a device, a socket or a
    symlink at an output path is never opened to see whether it is ours (a FIFO
    would block the run before it starts)."""
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb") as f:
            fd = -1
            return reader(f)
    except Exception:  # noqa: BLE001 (not ours, whatever it holds: truncated, not the format)
        return None
    finally:
        if fd >= 0:
            os.close(fd)


def check_output_file(
    path: Path,
    overwrite: bool,
    ours: Callable[[BinaryIO], bool],
    not_ours: str,
    element: str | None = None,
) -> None:
    """Before the work: may we write the file ``path``? Every output file's one check.

    Nothing there: yes. A folder: no. A FIFO, a device or a socket: never, not even
    with ``overwrite`` (it is never opened, nor replaced: ``--report /dev/null`` must
    not replace the device). A symlink (even a dangling one): only with ``overwrite``,
    which replaces the link, never its target. A regular file: with ``overwrite``, or
    when ``ours`` (given the file, opened by :func:`read_own`) says we wrote it;
    else an OutputError saying it ``not_ours`` ("is not a report of rover-drive")."""
    if path.is_dir():
        raise OutputError("is a folder; give the file to write", file=path, element=element)
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputError(
            f"cannot write here: {exc.strerror or exc}", file=path, element=element
        ) from None
    if stat.S_ISLNK(mode):
        if not overwrite:
            raise OutputError(
                "already exists (a symlink); pass --overwrite to replace the link (its "
                "target is never written)",
                file=path,
                element=element,
            )
        return
    if not stat.S_ISREG(mode):
        raise OutputError(
            f"is {_kind(mode)}, not a regular file; refused, even with --overwrite (it is "
            "never opened or replaced)",
            file=path,
            element=element,
        )
    if not overwrite and read_own(path, ours) is not True:
        raise OutputError(
            f"already exists and {not_ours}; pass --overwrite to replace it",
            file=path,
            element=element,
        )


def _json_of(f: BinaryIO) -> dict | None:
    data = json.loads(f.read(limit_bytes("report") + 1).decode("utf-8"))
    return data if isinstance(data, dict) else None


def check_file(path: Path, overwrite: bool, generator: str) -> None:
    """Before the work: refuse to write ``path`` over a file we did not write
    (:func:`check_output_file`).

    A file is ours when it is a JSON object whose ``"generator"`` is ``generator``."""

    def ours(f: BinaryIO) -> bool:
        data = _json_of(f)
        return data is not None and data.get("generator") == generator

    check_output_file(path, overwrite, ours, f"is not a report of {generator}")


class Reserved:
    """A temporary file beside ``path``, made before the work so that a folder we cannot
    write in fails the run before any output is installed; :meth:`commit` renames it
    into place, :meth:`discard` removes it (and the folders made for it). Its name holds
    our process id: after a kill -9 the next run writing beside it removes it
    (:func:`clean_stale`)."""

    def __init__(self, path: Path, tmp: Path, created: Sequence[Path] = ()):
        self.path, self.tmp = path, tmp
        self.created = list(created)
        self.committed = False

    def write(self, data: bytes) -> None:
        try:
            with open(self.tmp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
        except OSError as exc:  # a full disk, a quota: said naming the file, nothing left
            raise OutputError(f"cannot write: {exc.strerror or exc}", file=self.path) from None

    def commit(self) -> None:
        os.replace(self.tmp, self.path)
        self.committed = True

    def discard(self) -> None:
        """Remove the temporary file unless it was committed (then: nothing to do)."""
        if not self.committed:
            self.tmp.unlink(missing_ok=True)
            _remove_if_empty(self.created)


def _temp_file(path: Path, made: list[Path]) -> Path:
    """A new empty file beside ``path``, named with our process id (see
    :func:`clean_stale`), put in ``made`` before it exists (see :func:`_temp_folder`)."""
    while True:
        tmp = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(6)}.tmp"
        made.append(tmp)
        try:  # the user's umask, not mkstemp's 0600: a file as any other they write
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            made.remove(tmp)
            continue
        return tmp


def reserve(path: Path) -> Reserved:
    """Reserve ``path`` (see :class:`Reserved`): its temporary file made now, what a
    killed run left beside it removed first; the caller commits or discards it."""
    path = Path(path)
    try:
        created = _make_parents(path.parent)
    except OSError as exc:
        raise OutputError(f"cannot write here: {exc.strerror or exc}", file=path) from None
    made: list[Path] = []
    try:
        clean_stale(path.parent, path.name)
        try:
            tmp = _temp_file(path, made)
        except OSError as exc:  # a folder we cannot write in: said before the work
            raise OutputError(f"cannot write here: {exc.strerror}", file=path) from None
    except BaseException:
        for tmp in made:
            tmp.unlink(missing_ok=True)
        _remove_if_empty(created)
        raise
    return Reserved(path, tmp, created)


@contextmanager
def reserved_file(path: Path) -> Iterator[Reserved]:
    """Reserve ``path`` (see :class:`Reserved`): made now, renamed by ``commit``, removed
    (with the parent folders made for it) when the block ends without one."""
    res = reserve(path)
    try:
        yield res
    finally:
        res.discard()


def json_bytes(data: Mapping[str, Any], generator: str) -> bytes:
    """``data`` as our JSON, ``"generator"`` first."""
    text = json.dumps({"generator": generator, **data}, indent=2, default=float) + "\n"
    return text.encode()


def write_json(path: Path, data: Mapping[str, Any], generator: str) -> None:
    """``data`` as JSON with ``"generator"`` first, written atomically (temp file, rename)."""
    with reserved_file(path) as slot:
        slot.write(json_bytes(data, generator))
        slot.commit()


# -- folders we build (make-facility's output, facility-demo's frames) --------------------


def list_files(folder: Path) -> list[str]:
    """Every file under ``folder``, as sorted relative POSIX paths (not our marker)."""
    return sorted(
        p.relative_to(folder).as_posix()
        for p in folder.rglob("*")
        if p.is_file() and p.relative_to(folder).as_posix() != MARKER
    )


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


def recover(folder: Path) -> None:
    """Undo what a killed run of ours left at ``folder``: an install cut short (its
    trash folder's journal), staging folders, the marker of a staging folder that was
    renamed into place."""
    clean_stale(_home(folder), folder.name)
    if folder.is_dir() and _stale_mark(folder) is not None:
        (folder / MARKER).unlink(missing_ok=True)


def check_folder(folder: Path, overwrite: bool, manifest_name: str, generator: str) -> list[str]:
    """Before the work: may we build into ``folder``? Returns the files an earlier run of
    ours left there (to be replaced). Refuses a file, a symlink to nothing, and a
    non-empty folder without our manifest unless ``overwrite``."""
    recover(folder)
    if not folder.exists():
        if os.path.lexists(folder) and not overwrite:
            raise OutputError(
                "already exists (a symlink to nothing); pass --overwrite to replace it",
                file=folder,
            )
        return []
    if not folder.is_dir():
        raise OutputError("exists and is not a folder", file=folder)
    owned = owned_files(folder, manifest_name, generator)
    if owned is not None:
        return owned
    if any(p.name != MARKER for p in folder.iterdir()) and not overwrite:
        raise OutputError(
            f"folder is not empty and holds no {manifest_name} of an earlier {generator}; "
            "pass --overwrite to write into it (files we did not write are kept)",
            file=folder,
        )
    return []


@contextmanager
def staged_folder(output: Path) -> Iterator[Path]:
    """A temporary folder beside ``output`` (beside where a symlink there leads) to build
    in. On failure it is removed, with any parent folders made for it, so nothing is
    left behind."""
    home = _home(output)
    created = _make_parents(home)
    made: list[Path] = []
    try:
        yield _temp_folder(home, f".{output.name}-", made)
    except BaseException:
        _remove_all(made)
        _remove_if_empty(created)
        raise
    _remove_all(made)


_FILES = "files"
"""In a trash folder: the earlier files, at their paths (apart from our marker and journal)."""


def _journal(trash: Path, output: Path, new: Sequence[str], phase: str) -> None:
    """Record, atomically, where an install stands: ``saving`` (earlier files going into
    the trash), ``placing`` (new files going into the output), ``done``."""
    data = {"output": str(output.resolve()), "phase": phase, "new": list(new)}
    tmp = trash / f"{JOURNAL}.tmp"
    tmp.write_text(json.dumps(data) + "\n")
    os.replace(tmp, trash / JOURNAL)


def _undo_install(trash: Path, output: Path) -> bool:
    """Put back the earlier files of an install that was killed (its journal in
    ``trash``); True when the trash holds nothing of the user's any more."""
    journal = _json_object(trash / JOURNAL)
    if journal is None:  # killed before the journal (nothing moved), or being removed
        return True
    if journal.get("phase") == "done":
        return True
    if journal.get("output") != str(output.resolve()):
        return False
    log.warning("undoing the install into %s that was killed; the earlier files go back", output)
    new = journal.get("new")
    if journal.get("phase") == "placing" and isinstance(new, list):
        for rel in new:  # after ``saving`` no path of the new build held a file: ours
            if _inside(output, rel):
                target = output / rel
                if target.is_symlink() or target.is_file():
                    target.unlink()
                _remove_if_empty([p for p in target.parents if p.is_relative_to(output)][:-1])
    old, whole = trash / _FILES, True
    for f in sorted(old.rglob("*")) if old.is_dir() else []:
        if f.is_dir() and not f.is_symlink():
            continue
        target = output / f.relative_to(old)
        if os.path.lexists(target):  # someone wrote here since: keep both, the trash too
            whole = False
            continue
        _make_parents(target.parent)
        os.replace(f, target)
    return whole


def _discard_trash(trash: Path) -> None:
    """Remove a trash folder whose install is done, its marker last: a kill part-way
    leaves one that :func:`clean_stale` still knows as ours."""
    shutil.rmtree(trash / _FILES, ignore_errors=True)
    for name in (f"{JOURNAL}.tmp", JOURNAL, MARKER):
        (trash / name).unlink(missing_ok=True)
    shutil.rmtree(trash, ignore_errors=True)


def install_folder(
    stage: Path, output: Path, previous: Sequence[str], *, overwrite: bool, last: str
) -> list[str]:
    """Move every file of ``stage`` into ``output`` (``last``, the manifest, last of all).

    ``previous`` (from :func:`check_folder`) are the files an earlier run wrote; those
    the new run lacks are removed. Anything else in ``output`` is kept; a file of the
    user's at a path we write is replaced only with ``overwrite``. A failure part-way
    puts the earlier files back; so does the next run after a kill (the journal in the
    trash folder). Returns the files written (relative paths).
    """
    new = sorted(list_files(stage), key=lambda rel: (rel == last, "/" not in rel, rel))
    if not output.exists():
        if os.path.lexists(output):  # a symlink to nothing: check_folder let it go
            if not overwrite:
                raise OutputError(
                    "already exists (a symlink to nothing); pass --overwrite to replace it",
                    file=output,
                )
            output.unlink()
        os.replace(stage, output)
        (output / MARKER).unlink(missing_ok=True)
        return new
    ours = set(previous)
    clash = [rel for rel in new if rel not in ours and os.path.lexists(output / rel)]
    if clash and not overwrite:
        raise OutputError(
            f"would replace '{clash[0]}', which we did not write; pass --overwrite to replace it",
            file=output,
        )
    made: list[Path] = []
    moved: list[str] = []
    placed: list[str] = []
    dirs: list[list[Path]] = []
    try:
        trash = _temp_folder(_home(output), f".{output.name}-old-", made, kind="trash")
        _journal(trash, output, new, "saving")
        for rel in sorted(ours | set(clash)):
            src = output / rel
            if src.is_file() or src.is_symlink():
                (trash / _FILES / rel).parent.mkdir(parents=True, exist_ok=True)
                os.replace(src, trash / _FILES / rel)
                moved.append(rel)
        _journal(trash, output, new, "placing")
        for rel in new:
            target = output / rel
            dirs.append(_make_parents(target.parent))
            os.replace(stage / rel, target)
            placed.append(rel)
        _journal(trash, output, new, "done")
    except BaseException:
        try:
            for rel in placed:
                (output / rel).unlink(missing_ok=True)
            for rel in moved:
                os.replace(trash / _FILES / rel, output / rel)
            for created in reversed(dirs):
                _remove_if_empty(created)
        except BaseException:  # the trash keeps what did not go back; the next run does it
            made.clear()
            raise
        raise
    finally:
        for folder in made:
            _discard_trash(folder)
    kept = set(new)
    for rel in moved:  # folders that only held our old files go too
        if rel not in kept:
            parents = (output / rel).parents
            _remove_if_empty([p for p in parents if p.is_relative_to(output) and p != output])
    return new


def check_not_dangling(path: Path, overwrite: bool) -> None:
    """Refuse a symlink to nothing at ``path`` unless ``overwrite``: a file is there,
    even if ``path.exists()`` says no (checks that only ask that would replace it)."""
    if path.is_symlink() and not path.exists() and not overwrite:
        raise OutputError(
            "already exists (a symlink to nothing); pass --overwrite to replace it", file=path
        )
