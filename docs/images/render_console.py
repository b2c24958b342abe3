"""The console picture in docs/mira3d.md (headless Chromium, Debian's, through Playwright).

    python docs/images/render_console.py

Builds the pair recipe in a temporary folder, serves its console as
``rover-drive --console`` does, drives the collector forward 2 s with its shoulder pan
turned through the API, and takes the page as a browser shows it.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from urdf2mjcf import headless  # noqa: E402

headless.configure()

from playwright.sync_api import sync_playwright  # noqa: E402

from tests.browser import CHROMIUM_FLAGS, chromium_path  # noqa: E402
from urdf2mjcf.facility.build import build_facility  # noqa: E402
from urdf2mjcf.facility.recipe import load_recipe  # noqa: E402
from urdf2mjcf.runner.rover import RoverSim  # noqa: E402
from urdf2mjcf.runner.rover.console import Console  # noqa: E402
from urdf2mjcf.runner.rover.console_sim import ConsoleSim  # noqa: E402

OUT = ROOT / "docs" / "images" / "mira3d-console.png"


def post(url: str, body: dict) -> dict:
    req = urllib.request.Request(url, json.dumps(body).encode(), method="POST")
    req.add_header("Content-Type", "application/json")
    with urllib.request.urlopen(req) as r:
        return json.load(r)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "pair"
        build_facility(load_recipe(ROOT / "recipes" / "mira3d-pair.yaml"), folder, root=ROOT)
        sim = RoverSim(folder)
        sim.settle(0.5)
        with Console(ConsoleSim(sim, pace=1.0)) as console:
            cmd = {"rover": "collector", "wheels": {"left": 2.5, "right": 2.5}}
            post(console.address("command"), {**cmd, "arm": {"ur_shoulder_pan_joint": 0.5}})
            with sync_playwright() as pw, tempfile.TemporaryDirectory() as profile:
                browser = pw.chromium.launch_persistent_context(
                    profile,
                    executable_path=chromium_path(),
                    headless=True,
                    args=list(CHROMIUM_FLAGS),
                    viewport={"width": 1240, "height": 900},
                )
                page = browser.pages[0] if browser.pages else browser.new_page()
                page.goto(console.url)
                page.wait_for_function(
                    "(imgs => imgs.length == 6 && imgs.every(i => i.dataset.frames >= 2))"
                    "([...document.querySelectorAll('#cameras img')])",
                    timeout=120_000,
                )
                time.sleep(2.0)
                page.screenshot(path=str(OUT))
                browser.close()
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
