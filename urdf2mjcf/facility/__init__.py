"""Build a simulated facility from recipes: our xacro descriptions, flags,
placements and seeded pose uncertainty, compiled by :mod:`urdf2mjcf`."""

from .build import FacilityReport, build_facility
from .recipe import Recipe, load_recipe

__all__ = ["FacilityReport", "Recipe", "build_facility", "load_recipe"]
