"""One base error, specific subclasses.

Every message names the file and the element and, where it helps, what would
be valid. Every command (``urdf2mjcf``, ``make-facility``, ``facility-demo``,
``rover-drive``) prints ``error: <message>`` and exits with code 2.
"""

from __future__ import annotations

from pathlib import Path


class ConversionError(Exception):
    """Base class of bad input: it cannot be used. Nothing has been written."""

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


class FacilityError(ConversionError):
    """A built facility, or a runner's input (waypoints file), lacks something or is malformed."""


class PlanningError(ConversionError):
    """No collision-free joint motion: the start or goal is in collision (the message
    names the two bodies), out of the joints' ranges, or no path within the time limit."""
