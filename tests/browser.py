"""A real headless browser for the tests: Debian's Chromium driven by Playwright.

``page()`` opens a fresh page in a fresh browser profile, or skips the test, saying
why, where no browser can start (no ``chromium`` on the machine, or it fails to
launch). The flags keep Chromium off the network: the machine's is closed, and its
background connections would only be refused.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from collections.abc import Iterator
from typing import Any

import pytest

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",  # tests run as root in CI
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)


def chromium_path() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


@contextlib.contextmanager
def page(width: int = 1024, height: int = 768) -> Iterator[Any]:
    """A Playwright page in headless Chromium; skips the test where none can start."""
    exe = chromium_path()
    if exe is None:
        pytest.skip("no browser: Debian's chromium is not installed (apt install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("no browser driver: playwright is not installed (the test extra has it)")
    with sync_playwright() as pw, tempfile.TemporaryDirectory() as profile:
        try:
            browser = pw.chromium.launch_persistent_context(
                profile,
                executable_path=exe,
                headless=True,
                args=list(CHROMIUM_FLAGS),
                viewport={"width": width, "height": height},
            )
        except Exception as exc:  # no display libraries, a sandbox refusal, ...
            pytest.skip(f"the browser did not start: {str(exc).splitlines()[0]}")
        try:
            yield browser.pages[0] if browser.pages else browser.new_page()
        finally:
            browser.close()
