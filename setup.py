"""Build hook: the wheel carries the facility data as ``urdf2mjcf/_data/``.

The repository keeps ``facility/``, ``meshes/`` and ``recipes/`` at its top
level (the project's layout); ``make-facility`` outside a checkout reads the
copy in the installed package (``urdf2mjcf/facility/root.py``). Everything
else is configured in ``pyproject.toml``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
DATA_DIRS = ("facility", "meshes", "recipes")
# What a build reads: descriptions, configs, recipes, meshes, heightmaps (and the
# heightmap's extent). Not the mesh scripts nor the READMEs.
DATA_SUFFIXES = {".xacro", ".xml", ".yaml", ".stl", ".png", ".json"}


def data_files(top: Path) -> list[Path]:
    """The shipped files, relative to ``top``, sorted (a reproducible wheel)."""
    return sorted(
        path.relative_to(top)
        for name in DATA_DIRS
        for path in (top / name).rglob("*")
        if path.is_file() and path.suffix.lower() in DATA_SUFFIXES
    )


class BuildPyWithData(build_py):
    def run(self) -> None:
        super().run()
        # An editable install reads the checkout itself; nothing to copy.
        if getattr(self, "editable_mode", False):
            return
        target = Path(self.build_lib) / "urdf2mjcf" / "_data"
        shutil.rmtree(target, ignore_errors=True)  # no stale files from an earlier build
        for rel in data_files(HERE):
            (target / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(HERE / rel, target / rel)


setup(cmdclass={"build_py": BuildPyWithData})
