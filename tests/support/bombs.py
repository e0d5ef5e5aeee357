"""Models made to stall a station (issue 26): each small, each standing for far more."""

from __future__ import annotations


def predicate_bomb(levels: int, join: str = "&&") -> str:
    """A station whose ability's predicates each name the one before twice: `levels` lines
    that would stand for 2^levels terms written out."""
    lines = [
        "station: bomb",
        "resources:",
        "  - name: r",
        "    variables:",
        "      - {name: a, domain: bool, kind: command}",
        "      - {name: b, domain: bool, kind: measured}",
        "    abilities:",
        "      - name: t",
        "        predicates:",
        '          p0: "a && !b"',
    ]
    lines += [f'          p{i}: "p{i - 1} {join} p{i - 1}"' for i in range(1, levels + 1)]
    lines += [
        "        transitions:",
        f'          - {{name: start, guard: "p{levels}", actions: ["a := true"]}}',
        '          - {name: go, kind: effect, guard: "a && !b", actions: ["b := true"]}',
        "intentions:",
        '  - {name: i, goal: "r.b"}',
    ]
    return "\n".join(lines) + "\n"


def synthesis_bomb(pairs: int = 21) -> str:
    """A valid flat model of 2 * `pairs` booleans and one specification whose supervisor
    takes exponential time to synthesise: x_i and y_i never both, with the xs all before the
    ys (a minute and more at 21 pairs)."""
    names = [f"x{i}" for i in range(pairs)] + [f"y{i}" for i in range(pairs)]
    lines = ["variables:"]
    lines += [f"  - {{name: {v}, domain: bool, initial: false, kind: measured}}" for v in names]
    lines.append("transitions:")
    lines += [
        f'  - {{name: set_{v}, kind: effect, guard: "!{v}", actions: ["{v} := true"]}}'
        for v in names
    ]
    both = " || ".join(f"(x{i} && y{i})" for i in range(pairs))
    lines += ["specifications:", f'  - {{name: never_pairs, invariant: "!({both})"}}']
    return "\n".join(lines) + "\n"


def alias_bomb(width: int = 9, depth: int = 9) -> str:
    """Anchors naming anchors: `depth` levels of `width` aliases each (width^depth nodes)."""
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    for level in range(1, depth + 1):
        aliases = ", ".join([f"*a{level - 1}"] * width)
        lines.append(f"a{level}: &a{level} [{aliases}]")
    return "\n".join(lines) + "\nstation: bombed\n"
