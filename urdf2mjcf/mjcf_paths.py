"""File names as MuJoCo forms them: the same strings, so that the file we check is
the file MuJoCo opens.

MuJoCo (``mujoco::user::FilePath``) joins and reduces paths itself before the
operating system sees them: ``/`` and ``\\`` both separate, ``.`` is dropped and
``..`` removes the folder before it *as text* (a symbolic link is not followed
first), the result is joined with ``/``, and a name is absolute when it starts with
a separator or holds ``:/`` or ``:\\``. Each function here does what its namesake
there does, so a name is checked as the string MuJoCo will hand to ``stat`` and
``fopen``.
"""

from __future__ import annotations

_SEPARATORS = "/\\"


def abs_prefix(path: str) -> str:
    """The part of ``path`` that makes it absolute (``/``, ``\\``, ``C:/``, ...), or
    ``""`` for a relative name (``FilePath::AbsPrefix``; resource-provider prefixes,
    which this process registers none of, are refused before this is asked)."""
    if not path:
        return ""
    if path[0] in _SEPARATORS:
        return path[0]
    for mark in (":/", ":\\"):
        at = path.find(mark)
        if at >= 0:
            return path[: at + 2]
    return ""


def is_absolute(path: str) -> bool:
    return abs_prefix(path) != ""


def reduce(path: str) -> str:
    """``path`` with ``.`` dropped, ``..`` removing the name before it and every
    separator written ``/`` (``FilePath::PathReduce``)."""
    prefix = abs_prefix(path)
    parts: list[str] = []
    start = len(prefix)
    for i in range(start, len(path)):
        if path[i] in _SEPARATORS:
            part = path[start:i]
            start = i + 1
            if part == ".." and parts and parts[-1] != "..":
                parts.pop()
            elif part != ".":
                parts.append(part)
    parts.append(path[start:])
    return prefix + "/".join(parts)


def join(folder: str, name: str) -> str:
    """``name`` in ``folder``, reduced; ``name`` itself when it is absolute
    (``FilePath(folder, name)``)."""
    if is_absolute(name):
        combined = name
    elif folder and folder[-1] not in _SEPARATORS:
        combined = f"{folder}/{name}"
    else:
        combined = folder + name
    return reduce(combined)


def folder_of(path: str) -> str:
    """The folder part of ``path`` with its last separator, ``""`` for a bare name
    (``mju_getResourceDir``: where MuJoCo looks for what a file names)."""
    cut = max(path.rfind("/"), path.rfind("\\"))
    return path[: cut + 1]


def base_name(path: str) -> str:
    """``path`` without its folders (``mjuu_strippath``: ``compiler strippath``)."""
    cut = max(path.rfind("/"), path.rfind("\\"))
    return path[cut + 1 :]
