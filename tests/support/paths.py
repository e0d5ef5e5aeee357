"""Where things are, for every test wherever it sits in the tree."""

from __future__ import annotations

from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[2]
TESTS = REPOSITORY / "tests"
SCREENSHOTS = TESTS / "screenshots"  # a browser test's picture when it fails (not kept in git)
MINI_STATION = TESTS / "support" / "models" / "mini_station.yaml"
