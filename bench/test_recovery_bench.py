"""Keeps the recovery scenarios of bench/scenarios usable: they load, each with a time limit.

No timing is asserted; the benchmark measures, this only checks that what it measures works.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from app.scenario import ScenarioError, load_scenario
from planner.station import Station, load_station

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "models" / "demo_station.yaml"
BENCH_SCENARIOS = ROOT / "bench" / "scenarios"


@pytest.fixture(scope="module")
def demo() -> Station:
    return load_station(DEMO.read_text(), str(DEMO))


def test_bench_scenarios_load_and_each_has_a_time_limit(demo: Station) -> None:
    paths = sorted(BENCH_SCENARIOS.glob("*.yaml"))
    assert len(paths) >= 9
    for path in paths:
        text = path.read_text()
        scenario = load_scenario(text, str(path), demo)  # else file:line:column: what is wrong
        assert "until" in yaml.safe_load(text), f"{path.name}: it need not finish; give until"
        assert scenario.description and scenario.faults, path.name


def test_a_broken_bench_scenario_is_reported_at_its_line_and_column(demo: Station) -> None:
    path = BENCH_SCENARIOS / "double_both_robots_silent.yaml"
    text = path.read_text().replace("disconnect, resource: r2", "disconect, resource: r2")
    line = next(k for k, s in enumerate(text.splitlines(), 1) if "disconect" in s)
    column = text.splitlines()[line - 1].index("disconect") + 1
    with pytest.raises(ScenarioError) as raised:
        load_scenario(text, str(path), demo)
    assert str(raised.value).startswith(f"{path}:{line}:{column}: faults[1].kind: kind must be")
