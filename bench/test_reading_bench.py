"""The reading benchmark runs on its smallest sizes and reports a row per size."""

from __future__ import annotations

import re

from bench.reading import CASES, measure, report


def test_a_short_reading_benchmark_reports_each_case_at_its_sizes() -> None:
    measured = measure(runs=1, sizes=2)
    assert set(measured) == set(CASES)
    for case, points in measured.items():
        assert [n for n, _ in points] == list(CASES[case][1][:2])
        assert all(seconds > 0 for _, seconds in points)
    text = report(measured, 1)
    assert len(re.findall(r"^\| flat `&&` chain \(terms\) \| [\d,]+ \| [\d.]+ \|", text, re.M)) == 2
    assert re.search(r"\| guards naming .* \| 500 \| [\d.]+ \| [\d.]+ \|", text)
