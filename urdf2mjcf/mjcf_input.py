"""An MJCF model we did not write, loaded as a stranger's input.

``urdf2mjcf verify``'s model, a bundle's ``scene.xml`` (``facility-demo``,
``rover-drive``, the Gymnasium environments) and anything else that hands MuJoCo a
file from elsewhere go through :func:`load_model`:

1. every document MuJoCo will read while parsing (the model, its includes at any
   depth, its ``<model>`` assets, its ``<flexcomp>`` files) is found as MuJoCo finds
   it, checked a regular file within its size limit and read strictly
   (:mod:`urdf2mjcf.mjcf_files`);
2. the work it asks for is counted on the expanded tree: elements, bodies and
   flexcomp points after every replicate and attachment, nesting, built-in meshes
   (:func:`urdf2mjcf.mjcf_bounds.check_model`);
3. in a child process of its own (:mod:`urdf2mjcf.isolated`: SIGTERM and Ctrl-C end
   it at once, it has :data:`COMPILE_TIMEOUT` seconds and :data:`COMPILE_MEMORY`
   bytes), MuJoCo parses it; every mesh, texture, height field and skin file its
   parse names is checked where MuJoCo will open it, with the sizes it would
   allocate; MuJoCo compiles it; every compiled number must be finite.

Each failure is one :class:`~urdf2mjcf.errors.ConversionError` of the caller's class
naming the file and element (one ``error:`` line, exit code 2).

A program that shows the model in a process of its own (the viewer) calls
:func:`check_files` first: steps 1 and 2 and the checks of step 3, without the compile.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Any

from . import isolated, mjcf_bounds, mjcf_files
from .errors import ForgeError, InputError

COMPILE_TIMEOUT = 300.0
"""Seconds MuJoCo may take to parse and compile a model (the largest one the bounds
allow takes about a minute here)."""
COMPILE_MEMORY = 32 * 2**30
"""Bytes of address space the compiling process may map beyond what it shares with
ours (MuJoCo reserves ``<size memory>``, up to 16 GiB, while it compiles)."""


def load_model(
    path: Path | str, *, error: type[ForgeError] = InputError, what: str = "model"
) -> Any:
    """The ``mujoco.MjModel`` of the MJCF file at ``path``, a stranger's input;
    ``error`` (one line naming the file and element) for anything we refuse or
    MuJoCo rejects."""
    return _run(path, error, what, compile=True)


def check_files(
    path: Path | str, *, error: type[ForgeError] = InputError, what: str = "model"
) -> None:
    """What :func:`load_model` checks, without compiling: for a program that then has
    MuJoCo open ``path`` itself (the viewer)."""
    _run(path, error, what, compile=False)


def _run(path: Path | str, error: type[ForgeError], what: str, *, compile: bool) -> Any:
    model = mjcf_files.read_model(path, error=error, what=what)
    mjcf_bounds.check_model(model, error)
    try:
        return isolated.call(
            partial(_in_child, model, error, compile),
            timeout=COMPILE_TIMEOUT,
            memory=COMPILE_MEMORY,
        )
    except isolated.ChildFailed as exc:
        raise error(exc.detail, file=exc.file, element=exc.element) from None
    except isolated.ChildLost as exc:
        raise error(f"MuJoCo could not compile it: {exc}", file=path) from None


def _in_child(model: mjcf_files.Model, error: type[ForgeError], compile: bool) -> Any:
    """Parse, check what the parse names and allocates, compile, check the numbers."""
    import warnings

    import mujoco

    # a warning is no error of the model's, and only our own lines reach the terminal
    mujoco.set_mju_user_warning(lambda msg: None)
    warnings.simplefilter("ignore")
    try:
        spec = mujoco.MjSpec.from_file(model.path)
    except ValueError as exc:
        raise error(f"MuJoCo cannot load it: {_reason(exc)}", file=model.path) from None
    found = mjcf_files.check_asset_files(spec, model, error)
    mjcf_bounds.check_images(found, model.path, error)
    mjcf_bounds.check_spec(spec, model.path, error)
    if not compile:
        return None
    try:
        m = spec.compile()
    except ValueError as exc:
        raise error(f"MuJoCo cannot load it: {_reason(exc)}", file=model.path) from None
    mjcf_bounds.check_compiled(m, model.path, error)
    return m


def _reason(exc: Exception) -> str:
    return "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
