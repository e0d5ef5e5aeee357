"""Modules past STYLE.md's ~400 lines, which are usually two concepts.

A module that stays that long says why in its docstring, in a paragraph that starts with
`Size:` (one class, one algorithm...); the tests of each package list those that do not.
"""

from __future__ import annotations

import ast
from pathlib import Path

MAX_LINES = 400


def unexplained(package: Path) -> list[str]:
    """The modules under `package` over `MAX_LINES` lines without a `Size:` paragraph."""
    found = []
    for path in sorted(package.rglob("*.py")):
        text = path.read_text()
        if text.count("\n") <= MAX_LINES:
            continue
        docstring = ast.get_docstring(ast.parse(text)) or ""
        if not any(part.startswith("Size:") for part in docstring.split("\n\n")):
            found.append(f"{path.relative_to(package.parent)} ({text.count(chr(10))} lines)")
    return found
