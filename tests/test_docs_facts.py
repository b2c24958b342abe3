"""Facts the docs repeat from the code and the recipes, checked against them: the
example error lines' lists, the iMETRO jitter each page states."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

from urdf2mjcf.facility.recipe import load_recipe
from urdf2mjcf.runner.waypoints import KINDS

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def test_the_example_errors_list_what_the_code_lists():
    text = (DOCS / "cli.md").read_text()
    (kinds,) = re.findall(r"unknown kind 'teleport'; valid: ([\w, ]+)", text)
    assert kinds.split(", ") == list(KINDS)


def test_the_example_error_of_a_flag_is_what_make_facility_prints(tmp_path):
    command = "from urdf2mjcf.cli import make_facility_main; make_facility_main()"
    proc = subprocess.run(
        [sys.executable, "-c", command, "recipes/imetro.yaml", "-o", str(tmp_path / "f")]
        + ["--set", "no_such_flag=1"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2 and not (tmp_path / "f").exists()
    (line,) = proc.stderr.strip().splitlines()
    assert line in (DOCS / "cli.md").read_text().splitlines()


def test_the_jitter_the_docs_state_is_the_published_recipes():
    jitter = load_recipe(ROOT / "recipes" / "imetro.yaml").jitter
    mockup, ctb = jitter["default"], jitter["ctb"]
    cm = lambda r: round(r["position"] * 100)  # noqa: E731
    deg = lambda r: round(math.degrees(r["yaw"]))  # noqa: E731
    demo = " ".join((DOCS / "demo.md").read_text().split())
    assert (
        f"the CTB within {cm(ctb)} cm and {deg(ctb)} deg, the mockups within "
        f"{cm(mockup)} cm and {deg(mockup)} deg"
    ) in demo
    envs = " ".join((DOCS / "envs.md").read_text().split())
    assert (
        f"the mockups move within +-{mockup['position']:.2f} m and +-{deg(mockup)} degrees, "
        f"the CTB within +-{ctb['position']:.2f} m and +-{deg(ctb)} degrees"
    ) in envs


def test_the_primitive_defaults_the_docs_state_are_the_codes():
    from urdf2mjcf.passes.collision import CollisionConfig

    cfg = CollisionConfig()
    for page in ("cli.md", "passes.md"):
        text = " ".join((DOCS / page).read_text().split())
        near = r"`{}(?: \w+)?`[^(]{{0,200}}\(default ([\d.]+)"
        (mm,) = set(re.findall(near.format("--primitive-tolerance"), text))
        (ratio,) = set(re.findall(near.format("--primitive-volume-ratio"), text))
        assert float(mm) == cfg.primitive_tolerance_mm, page
        assert float(ratio) == cfg.primitive_volume_ratio, page
