"""Reading long expressions: how the time to load a model grows with what it holds.

    python -m bench.reading [--runs 3] [--output bench/results/reading.md]

The tests check the shapes (a flat chain is one level, nothing recurses per term, a large
predicate's nodes are looked at a few times, not once per guard that names it); how fast is
measured here, where a machine's load cannot fail a build.  Two shapes grew faster than their
input once: a flat chain of 20,000 `&&` or `||` terms (the tokenizer was quadratic: 2.4 s
instead of 0.3 s) and 1,000 guards naming one predicate of 20,000 conjuncts (each guard walked
it: 6 s instead of 0.5 s).  Each case is loaded at doubling sizes; the growth column is the
time's ratio to the size before: about 2 when the reading is linear, about 4 when quadratic.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from bench.planning import machine
from bench.runner import revision
from planner.reading import load_station

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
MINI = ROOT / "tests" / "support" / "models" / "mini_station.yaml"
GUARD = '"bp1.state == empty"'  # the guard of operator.place_bolts.start in MINI
ATOM = "bp1.state == empty"


def chain(operator: str) -> Callable[[int], str]:
    """The mini station with one guard a flat chain of `n` terms joined by `operator`."""

    def text(n: int) -> str:
        base = MINI.read_text()
        assert base.count(GUARD) == 1, "the mini station's place_bolts guard moved"
        return base.replace(GUARD, '"' + f" {operator} ".join([ATOM] * n) + '"')

    return text


def named_predicate(guards: int) -> str:
    """`guards` transitions whose guards name one predicate of 20,000 conjuncts."""
    big = " && ".join(f"v{i % 50}" for i in range(20_000))
    lines = ["station: s", "variables:", *(f"  - {{name: v{i}, domain: bool}}" for i in range(50))]
    lines += ["resources:", "  - name: r", "    variables:", "      - {name: x, domain: bool}"]
    lines += ["    abilities:", "      - name: a", "        predicates:", f'          big: "{big}"']
    lines += ["        transitions:"]
    lines += [
        f'          - {{name: t{i}, guard: "big && x", actions: ["x := true"]}}'
        for i in range(guards)
    ]
    return "\n".join(lines) + "\n"


CASES: dict[str, tuple[Callable[[int], str], tuple[int, ...]]] = {
    "flat `&&` chain (terms)": (chain("&&"), (5_000, 10_000, 20_000, 40_000)),
    "flat `||` chain (terms)": (chain("||"), (5_000, 10_000, 20_000, 40_000)),
    "guards naming a 20,000-term predicate (guards)": (named_predicate, (250, 500, 1_000, 2_000)),
}


def seconds_to_load(text: str, runs: int) -> float:
    """The median wall time of `load_station(text)` over `runs` runs."""
    times = []
    for _ in range(runs):
        began = time.perf_counter()
        load_station(text, "bench.yaml")
        times.append(time.perf_counter() - began)
    return statistics.median(times)


def measure(runs: int, sizes: int | None = None) -> dict[str, list[tuple[int, float]]]:
    """Each case at its sizes (only the first `sizes` of them when given)."""
    return {
        case: [(n, seconds_to_load(make(n), runs)) for n in ns[:sizes]]
        for case, (make, ns) in CASES.items()
    }


def report(measured: dict[str, list[tuple[int, float]]], runs: int) -> str:
    lines = [
        f"# Reading long expressions\n\n`python -m bench.reading --runs {runs}`, "
        f"{time.strftime('%Y-%m-%d')}, {revision()}. Machine: {machine()}",
        "",
        "| case | size | median s | growth over the size before |",
        "| --- | --- | --- | --- |",
    ]
    for case, points in measured.items():
        before = None
        for n, seconds in points:
            growth = "" if before is None or before <= 0 else f"{seconds / before:.2f}"
            lines.append(f"| {case} | {n:,} | {seconds:.3f} | {growth} |")
            before = seconds
    lines += [
        "",
        "Sizes double from row to row: a growth near 2 is linear reading, near 4 quadratic.",
    ]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per size (%(default)s)")
    parser.add_argument("--output", type=Path, default=RESULTS / "reading.md", help="%(default)s")
    args = parser.parse_args()
    text = report(measure(args.runs), args.runs)
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)


if __name__ == "__main__":
    main()
