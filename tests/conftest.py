"""Test configuration: hypothesis explores randomly on developers' machines, and replays a
fixed sequence of examples in CI so that main cannot turn red without a change."""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

# `sp` saves synthesised supervisors; tests keep theirs out of the user's cache
if "SP_CACHE_DIR" not in os.environ:
    import tempfile

    os.environ["SP_CACHE_DIR"] = tempfile.mkdtemp(prefix="sp-test-cache-")
