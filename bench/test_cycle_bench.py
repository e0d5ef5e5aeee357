"""The cycle benchmark plays a scenario in each mode and reports it as a row."""

from __future__ import annotations

from bench.cycle import MODES, measure, report


def test_a_short_cycle_benchmark_reports_each_mode_and_the_papers_recovery() -> None:
    cycles = measure(["e1_bolt_undone"], MODES)
    assert [(c.scenario, c.mode) for c in cycles] == [("e1_bolt_undone", m) for m in MODES]
    sequential = cycles[0]
    assert sequential.outcome == "finished" and sequential.seconds is not None
    assert sequential.paper == ("OP",) and sequential.recovers_as_the_paper
    assert sequential.operator == sequential.expected_operator
    text = report(cycles)
    row = next(line for line in text.splitlines() if line.startswith("| e1_bolt_undone |"))
    assert f"| {sequential.seconds:.1f} |" in row
    assert text.count("| --- ") == 3 * len(MODES) + 2
    parallel = next(c for c in cycles if c.mode == "parallel")
    assert sequential.at_once == 1 and parallel.at_once >= 2
    assert row.endswith(f"| {sequential.at_once} | {parallel.at_once} | {cycles[2].at_once} |")
