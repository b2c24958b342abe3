"""The demos a facility bundle is built for: which component the demo drives and
where a facility root keeps its demos (the published one, iMETRO's, for a recipe with
none of its own). The builder copies the demo into the bundle (``demo.yaml``, see
``urdf2mjcf.bundle``) and the demo's runtime drives ``DEMO_ROBOT``'s arm roles
(``urdf2mjcf.runner.load``); the bundle's format itself names no demo and no component.
"""

from __future__ import annotations

from pathlib import Path

DEMO_ROBOT = "robot"
"""The component the demo drives (its roles): a recipe that places none gets no demo."""
DEMOS = "recipes/demo"
"""The demos under a facility root: ``<recipe name>.yaml`` for a recipe of its own."""
PUBLISHED_DEMO = "imetro.yaml"
"""The published demo, for a recipe with none of its own."""


def demo_source(root: Path, recipe_name: str) -> Path | None:
    """The demo a facility of ``recipe_name`` is built for: ``recipes/demo/<name>.yaml``
    under the facility root when there is one (the compact layout's), else the published
    ``recipes/demo/imetro.yaml``; None when the root holds neither."""
    demos = Path(root) / DEMOS
    if recipe_name and "/" not in recipe_name and "\\" not in recipe_name:
        own = demos / f"{recipe_name}.yaml"
        if own.is_file():
            return own
    published = demos / PUBLISHED_DEMO
    return published if published.is_file() else None
