"""Shared fixtures: a per-session decomposition cache, so tests never touch ~/.cache."""

from __future__ import annotations

import fcntl
import os
from collections.abc import Callable
from pathlib import Path

import pytest

from tests import warm_cache
from urdf2mjcf import headless

headless.configure()  # before any test imports mujoco's renderer

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session", autouse=True)
def _session_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    # One cache per test run, shared by the xdist workers of that run, filled once from
    # the pre-warmed decompositions (tests/warm_cache.py) unless the run asks for cold.
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    cache = shared / "urdf2mjcf-cache"
    cache.mkdir(parents=True, exist_ok=True)
    with open(shared / "urdf2mjcf-cache.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # the first worker unpacks; the others wait for it
        done = shared / "urdf2mjcf-cache.warmed"
        if not done.exists():
            if os.environ.get(warm_cache.COLD_ENV) != "1":
                warm_cache.unpack(cache)
            done.touch()
    os.environ["URDF2MJCF_CACHE"] = str(cache)
    return cache


@pytest.fixture(scope="session")
def shipped_bundle(_session_cache: Path) -> Callable[[str], Path]:
    """NAME -> the bundle of recipes/NAME.yaml (no components/), built once per test run
    in the session cache and shared by every worker. Read-only: the runtime never writes
    into a bundle; a test that edits one copies it or builds its own."""
    from urdf2mjcf.envs import build as env_build

    return lambda name: env_build.facility_folder(name, root=ROOT)[0]


@pytest.fixture(scope="session")
def imetro_bundle(shipped_bundle: Callable[[str], Path]) -> Path:
    """The default iMETRO facility, as :func:`shipped_bundle` builds it."""
    return shipped_bundle("imetro")


@pytest.fixture(scope="session")
def gl_context() -> None:
    """Skips the test only where no offscreen OpenGL context can be made."""
    reason = headless.gl_context_error()
    if reason is not None:
        pytest.skip(f"no offscreen OpenGL context: {reason}")


@pytest.fixture
def data_dir() -> Path:
    return DATA


def pytest_report_header() -> str:
    return warm_cache.header()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    # Tests that share a module-scoped fixture run on one xdist worker (--dist loadgroup,
    # pyproject.toml), so what it builds (a facility, a demo run, a served robot) is built
    # once, not once per worker; every other test is scheduled on its own.
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        defs = info.name2fixturedefs.values() if info is not None else ()
        if any(d[-1].scope == "module" for d in defs if d):
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::")[0]))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--update-golden",
        action="store_true",
        default=False,
        help="Rewrite tests/golden/*.xml from the current output instead of comparing.",
    )


@pytest.fixture
def update_golden(request: pytest.FixtureRequest) -> bool:
    return bool(request.config.getoption("--update-golden"))
