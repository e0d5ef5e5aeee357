"""Every module of hw/ past ~400 lines says why it is one concept (STYLE.md)."""

from __future__ import annotations

from tests.support.module_sizes import unexplained
from tests.support.paths import REPOSITORY


def test_a_long_module_says_why_it_is_not_split() -> None:
    assert unexplained(REPOSITORY / "hw") == []
