"""Test configuration: hypothesis explores randomly on developers' machines, and replays a
fixed sequence of examples in CI so that main cannot turn red without a change; running
stations and Debian's Chromium for the web tests."""

from __future__ import annotations

import os

import pytest
from hypothesis import Phase, settings

# No explain phase: it keeps every failing example's frames alive until the test ends, and
# with them the examples' BDD managers (C memory Python does not count). A failing
# property test over planners grew to 12 GB that way and CI was killed before it could
# report the failure; without the phase the same run stays near 1 GB.
PHASES = tuple(p for p in Phase if p is not Phase.explain)
settings.register_profile("dev", phases=PHASES)
settings.register_profile("ci", derandomize=True, database=None, print_blob=True, phases=PHASES)
settings.load_profile("ci" if os.environ.get("CI") else "dev")

# `sp` saves synthesised supervisors; tests keep theirs out of the user's cache
if "SP_CACHE_DIR" not in os.environ:
    import tempfile

    os.environ["SP_CACHE_DIR"] = tempfile.mkdtemp(prefix="sp-test-cache-")
if "SP_CACHE_KEY_FILE" not in os.environ:  # its key too, out of the cache's folder
    import tempfile

    keys = tempfile.mkdtemp(prefix="sp-test-cache-key-")
    os.environ["SP_CACHE_KEY_FILE"] = os.path.join(keys, "cache.key")


@pytest.fixture
def station(tmp_path):  # type: ignore[no-untyped-def]
    """A running demo station on a fresh SQLite file (in-process; `station.serve()` for a
    real HTTP server)."""
    from tests.support.stations import start_station

    running = start_station(tmp_path)
    yield running
    running.stop()


CHROMIUM = "/usr/bin/chromium"  # Debian's; scripts/install puts it there, never a download
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


@pytest.fixture(scope="session")
def browser():  # type: ignore[no-untyped-def]
    """One headless Chromium for the session, driven by Playwright."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(
            executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS
        )
        yield launched
        launched.close()


@pytest.fixture
def served(tmp_path):  # type: ignore[no-untyped-def]
    """A running demo station served by uvicorn on 127.0.0.1 (for the browser tests)."""
    from tests.support.stations import start_station

    running = start_station(tmp_path)
    running.serve()
    yield running
    running.stop()
