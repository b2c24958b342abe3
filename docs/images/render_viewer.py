"""Take the screenshots in docs/viewing.md: the commands themselves, their pages loaded
in headless Chromium (as tests/browser.py starts it).

    python docs/images/render_viewer.py
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from PIL import Image  # noqa: E402
from playwright.sync_api import sync_playwright  # noqa: E402

from tests.browser import CHROMIUM_FLAGS, chromium_path  # noqa: E402

OUT = Path(__file__).resolve().parent


def _url(proc: subprocess.Popen, stream: str) -> str:
    pipe = getattr(proc, stream)
    for raw in pipe:
        line = raw.decode()
        print(line, end="")
        if line.startswith("viewing "):
            threading.Thread(target=lambda: [print(x.decode(), end="") for x in pipe]).start()
            return line.split(" at ")[1].split(" ")[0]
    raise RuntimeError("no address printed")


def _shot(page, url: str, name: str, settle_ms: int = 3000) -> None:
    loaded = threading.Event()
    page.on("console", lambda m: "scene initialized successfully" in m.text and loaded.set())
    page.goto(url)
    while not loaded.is_set():
        page.wait_for_timeout(250)
    page.wait_for_timeout(settle_ms)
    page.screenshot(path=str(OUT / name))
    Image.open(OUT / name).convert("RGB").quantize(256).save(OUT / name, optimize=True)
    print("wrote", OUT / name)


def main() -> None:
    work = Path(tempfile.mkdtemp())
    arm = work / "demo_arm.urdf.xacro"
    shutil.copy(ROOT / "examples" / "demo_arm.urdf.xacro", arm)
    mira = work / "mira"
    subprocess.run(
        ["make-facility", "recipes/mira3d-floor.yaml", "-o", str(mira), "--no-components", "-q"],
        check=True,
        cwd=ROOT,
    )
    with sync_playwright() as pw, tempfile.TemporaryDirectory() as profile:
        browser = pw.chromium.launch_persistent_context(
            profile,
            executable_path=chromium_path(),
            headless=True,
            args=list(CHROMIUM_FLAGS),
            viewport={"width": 1024, "height": 640},
        )
        page = browser.pages[0]
        view = subprocess.Popen(
            ["urdf2mjcf", "view", str(arm), "use_gripper:=true", "--no-browser"],
            stdout=subprocess.PIPE,
        )
        url = _url(view, "stdout")
        _shot(page, url, "view-demo-arm.png")
        # a typo saved: the terminal's error line, the page's console, the model kept
        arm.write_text(arm.read_text().replace("${length / 2}", "${length / 2", 1))
        time.sleep(4)
        _shot(page, url, "view-error.png")
        page.goto("about:blank")
        view.terminate()
        view.wait()

        drive = subprocess.Popen(
            ["rover-drive", str(mira), "--distance", "4", "--settle", "20", "--arm"]
            + ["--view", "--pace", "0.5"],
            stderr=subprocess.PIPE,
        )
        url = _url(drive, "stderr")
        _shot(page, url, "view-rover-drive.png", settle_ms=1000)
        page.goto("about:blank")
        drive.wait()
        browser.close()
    shutil.rmtree(work)


if __name__ == "__main__":
    main()
