"""Build a simulated facility from recipes: our xacro descriptions, flags,
placements and seeded pose uncertainty, compiled by :mod:`urdf2mjcf`.

The names below are imported on first use: the runtime reads constants of this
package (``values``, ``fiducials``) and must not load the builder with them."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .build import FacilityReport, build_facility
    from .recipe import Recipe, load_recipe

__all__ = ["FacilityReport", "Recipe", "build_facility", "load_recipe"]
_HOMES = {
    "FacilityReport": "build",
    "build_facility": "build",
    "Recipe": "recipe",
    "load_recipe": "recipe",
}


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib import import_module

    return getattr(import_module(f".{_HOMES[name]}", __name__), name)
