"""The code's structure from its own imports and definitions: modules, their sizes, the
functions in them, and the import graph with each arrow's kind.

An arrow is *top* (a module-level import: runs at import time), *lazy* (inside a function:
runs at call time) or *typing* (under `if TYPE_CHECKING:`: never runs).  A circle is a
strongly connected set of modules.  `python -m tests.support.structure` prints a summary
(the table of a layout change's closing note).
"""

from __future__ import annotations

import ast
import sys
from collections import defaultdict
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

from tests.support.paths import REPOSITORY

TOPS = ("planner", "hw", "app", "bench", "migrations")


class Arrow(StrEnum):
    TOP = "top"
    LAZY = "lazy"
    TYPING = "typing"


@dataclass(frozen=True)
class Module:
    name: str  # dotted
    relative: str  # its path in the repository
    lines: int
    docstring: str
    functions: tuple[tuple[str, int, int], ...]  # (name, first line, length)
    imports: tuple[tuple[str, Arrow], ...]  # (module imported, how)


def modules(root: Path = REPOSITORY, tops: Iterable[str] = TOPS) -> dict[str, Module]:
    paths = {
        _dotted(path.relative_to(root)): path
        for top in tops
        for path in sorted((root / top).rglob("*.py"))
    }
    return {name: _read(name, path, root, set(paths)) for name, path in paths.items()}


def _dotted(relative: Path) -> str:
    name = ".".join(relative.with_suffix("").parts)
    return name.removesuffix(".__init__")


def _read(name: str, path: Path, root: Path, known: set[str]) -> Module:
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    functions = tuple(
        (node.name, node.lineno, (node.end_lineno or node.lineno) - node.lineno + 1)
        for node in ast.walk(tree)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
    )
    imports = tuple(_imports(tree, package, known))
    docstring = ast.get_docstring(tree) or ""
    relative = str(path.relative_to(root))
    return Module(name, relative, text.count("\n"), docstring, functions, imports)


def _imports(tree: ast.Module, package: str, known: set[str]) -> Iterator[tuple[str, Arrow]]:
    def visit(node: ast.AST, how: Arrow) -> Iterator[tuple[str, Arrow]]:
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                yield from visit(child, Arrow.TYPING)
            for child in node.orelse:
                yield from visit(child, how)
            return
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and how is Arrow.TOP:
            how = Arrow.LAZY
        if isinstance(node, ast.Import):
            for alias in node.names:
                found = _resolve(alias.name, known)
                if found:
                    yield found, how
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parts, *([node.module] if node.module else [])])
            for alias in node.names:
                full = f"{base}.{alias.name}"
                found = full if full in known else _resolve(base, known)
                if found:
                    yield found, how
        for child in ast.iter_child_nodes(node):
            yield from visit(child, how)

    yield from visit(tree, Arrow.TOP)


def _resolve(name: str, known: set[str]) -> str | None:
    while name:
        if name in known:
            return name
        name = name.rpartition(".")[0]
    return None


def arrows(found: dict[str, Module], kinds: Iterable[Arrow]) -> dict[str, set[str]]:
    """Module → the modules it imports by `kinds` (a package's own submodules importing
    their package's `__init__` and the other way round are ties inside one package)."""
    wanted = set(kinds)
    graph: dict[str, set[str]] = defaultdict(set)
    for module in found.values():
        for target, how in module.imports:
            if how in wanted and target != module.name:
                graph[module.name].add(target)
    return graph


def circles(found: dict[str, Module], kinds: Iterable[Arrow]) -> list[list[str]]:
    """The strongly connected sets of more than one module (Tarjan, iteratively)."""
    graph = arrows(found, kinds)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = 0
    for root in sorted(found):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.append(member)
                        if member == node:
                            break
                    if len(group) > 1:
                        out.append(sorted(group))
            elif child not in index:
                index[child] = low[child] = counter
                counter += 1
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph.get(child, ())))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return out


def group_of(name: str, depth: int = 2) -> str:
    """The package a module belongs to for layering: `planner.runner.tick` → `planner.runner`."""
    return ".".join(name.split(".")[:depth])


def summary(found: dict[str, Module]) -> list[str]:
    lines = []
    for top in TOPS:
        mine = [m for m in found.values() if m.name.split(".")[0] == top]
        lines.append(f"{top}: {len(mine)} modules, {sum(m.lines for m in mine)} lines")
    for kinds, what in (
        ((Arrow.TOP,), "at import time"),
        ((Arrow.TOP, Arrow.LAZY), "at import or call time"),
        (tuple(Arrow), "with typing-only imports"),
    ):
        found_circles = circles(found, kinds)
        lines.append(f"circles {what}: {len(found_circles)}")
        lines += [f"    {', '.join(c)}" for c in found_circles]
    long = sorted((m for m in found.values() if m.lines > 400), key=lambda m: -m.lines)
    lines.append(f"modules over 400 lines: {len(long)}")
    lines += [f"    {m.lines:5d} {m.relative}" for m in long]
    functions = sorted(
        ((length, f"{m.relative}:{line}", name) for m in found.values()
         for name, line, length in m.functions if length > 60),
        reverse=True,
    )  # fmt: skip
    lines.append(f"functions over 60 lines: {len(functions)}")
    lines += [f"    {length:5d} {where} {name}" for length, where, name in functions]
    return lines


if __name__ == "__main__":
    root = Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else REPOSITORY
    print("\n".join(summary(modules(root))))
