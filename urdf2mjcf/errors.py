"""Every error the package raises, in one tree: one base per product.

- :class:`ConversionError`: the compiler (``urdf2mjcf``, ``batch``, ``verify``,
  ``calibrate``): bad input that cannot be converted; nothing has been written.
- :class:`FacilityError`: a facility bundle (``make-facility``'s output, a recipe's
  files, a runner's waypoints) lacks something or is malformed.
- :class:`RunError`: the runtime (demo, rovers, trials, viewers, servers) cannot go on.

All three are :class:`ForgeError`, which every command catches: it prints
``error: <message>`` and exits with code 2. Every message names the file and the
element and, where it helps, what would be valid. A few runtime errors keep the
built-in kind their callers caught before (``StepError`` is a ``RuntimeError``, a
taken port an ``OSError``).

Internal signals (a value refused while it is read, before the reader names the
file) are plain ``ValueError`` subclasses here too, so no module defines its own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


class ForgeError(Exception):
    """Base of every error the package raises on purpose."""

    def __init__(self, message: str, *, file: Path | str | None = None, element: str | None = None):
        self.file = str(file) if file is not None else None
        self.element = element
        self.detail = message
        parts = []
        if self.file:
            parts.append(self.file)
        if element:
            parts.append(element)
        prefix = ": ".join(parts)
        super().__init__(f"{prefix}: {message}" if prefix else message)


# -- the compiler -------------------------------------------------------------


class ConversionError(ForgeError):
    """Base class of bad input: it cannot be used. Nothing has been written."""


class InputError(ConversionError):
    """The source file is missing, unreadable or not well-formed XML."""


class XacroError(ConversionError):
    """xacro expansion failed (bad macro, missing argument, bad include)."""


class PackageNotFoundError(ConversionError):
    """A ``package://`` URI or ``$(find ...)`` names a package we cannot locate."""


class URDFError(ConversionError):
    """The URDF is structurally invalid (cycle, two roots, unknown joint type, ...)."""


class MeshError(ConversionError):
    """A mesh file is missing, unreadable, an unfetched Git LFS pointer, or unsupported."""


class InertiaError(ConversionError):
    """An inertial is physically impossible and cannot be repaired (negative mass)."""


class ValidationError(ConversionError):
    """MuJoCo rejected the generated model or warned while simulating it."""


class OutputError(ConversionError):
    """The output location cannot be written (exists without --overwrite, not a directory)."""


class MissingExtraError(ConversionError):
    """A command needs an optional extra that is not installed."""


class CertificateFailed(ConversionError):
    """``--verify``: the conversion's certificate failed; nothing has been written.

    A :class:`ConversionError` for callers of the API; the command line reports the
    failing figures and exits with code 1 (the input was fine: the result is not)."""

    def __init__(self, certificate: Any, file: Path | str | None = None):
        self.certificate = certificate  # a certify.Certificate (certify imports this module)
        first = certificate.failures[0] if certificate.failures else certificate.summary()
        super().__init__(f"certificate failed: {first}; nothing written", file=file)


# -- the bundle ---------------------------------------------------------------


class FacilityError(ForgeError):
    """A built facility, or a runner's input (waypoints file), lacks something or is malformed."""


class BundleError(FacilityError):
    """A bundle lacks a file or a field, or is of another schema version."""


class LoadError(FacilityError):
    """The facility lacks something the runner needs (a file, a role, a name)."""


class RoverError(LoadError):
    """The facility lacks something the rover runner needs."""


class ControllerFileError(FacilityError):
    """A ROS 2 controllers file that cannot be served as written."""


# -- the runtime --------------------------------------------------------------


class RunError(ForgeError):
    """The runtime cannot go on: a plan, a step, an executor, a server, a viewer."""


class PlanningError(RunError):
    """No collision-free joint motion: the start or goal is in collision (the message
    names the two bodies), out of the joints' ranges, or no path within the time limit."""


class StepError(RunError, RuntimeError):
    """A step cannot be carried out (unreachable pose, nothing seen)."""


class ExecutorError(RunError):
    """The executor asked for cannot be used (Ray missing, no cluster at the address)."""


class ServeError(RunError):
    """A model cannot be served to ROS 2 as given."""


class PortError(RunError, OSError):
    """A server could not start (its port taken, or not ours to bind)."""

    def __init__(self, errno: int | None, strerror: str | None):
        super().__init__(strerror or "cannot bind")
        self.errno, self.strerror = errno, strerror


class ViewerError(RunError):
    """The viewer could not start, or stopped."""


class CameraUnavailable(RunError, RuntimeError):
    """No image can be rendered here (no OpenGL context, or the renderer stopped)."""


class CommandError(RunError, ValueError):
    """A console or ROS command the runtime refuses; ``status`` is its HTTP status."""

    def __init__(self, message: str, status: int = 400):
        super().__init__(message)
        self.status = status


# -- internal signals ---------------------------------------------------------


class BadNumber(ValueError):
    """Why a value is not a number we use; its text is the one-line error's message."""


class YamlBombError(ValueError):
    """A YAML document whose aliases expand past ``untrusted.YAML_MAX_NODES``."""


class BadManifest(ValueError):
    """A value of facility.json refused (``key`` and ``message``); the reader names the file."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key, self.message = key, message


class BadCommand(ValueError):
    """A ROS command dropped as it is (the reason in the message)."""
