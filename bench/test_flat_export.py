"""Compiled station models exported to the flat form (bench/flat_export.py) mean the same."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from bench import cells, flat_export
from bench.pddl_export import FlatModel, bfs_min_length, check_plan
from bench.test_pddl_export import sp
from planner.reading import load_station

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "models" / "examples" / "bolt_and_nutrunner.yaml"


def test_flat_export_of_a_flat_model_keeps_its_meaning() -> None:
    original = yaml.safe_load(EXAMPLE.read_text())
    exported = flat_export.flat_dict(flat_export.read(EXAMPLE).model)
    assert [t["name"] for t in exported["transitions"]] == [
        t["name"] for t in original["transitions"]
    ]
    FlatModel.from_dict(exported)  # parses with the exporter's own parser
    for goal in ("r1.pos == bp1", "nr.running && r1.ref == home", "r1.pos == tool"):
        for closure in (False, True):
            expected = bfs_min_length(original, None, goal, closure=closure)
            assert bfs_min_length(exported, None, goal, closure=closure) == expected


def test_flat_export_of_a_station_plans_as_sp_does(tmp_path: Path) -> None:
    """One cell of bench/cells.py (station form: abilities, automatic finishes, an
    intention's named goal): the export's section 8 optimum is sp's plan length."""
    path = tmp_path / "cell.yaml"
    path.write_text(cells.station_text(1))
    station = flat_export.read(path)
    model = flat_export.flat_dict(station.model, drop=station.restart_transitions)
    goal = flat_export.goal_text(station, "cell_c0.goal")
    assert goal == "c0_part.state == done && c0_r.pos == home"
    answer = sp("plan", str(path), "--goal", "cell_c0.goal", "--no-cache")
    assert answer["status"] == "found"
    check_plan(model, None, goal, answer["plan"], closure=True)
    assert bfs_min_length(model, None, goal, closure=True) == answer["length"] == 12


def test_flat_export_drops_restart_transitions_and_names_clashes() -> None:
    station = flat_export.read(ROOT / "models" / "demo_station.yaml")
    assert station.restart_transitions
    model = flat_export.flat_dict(station.model, drop=station.restart_transitions)
    names = {t["name"] for t in model["transitions"]}
    assert not names & station.restart_transitions
    assert len(names) == len(station.model.transitions) - len(station.restart_transitions)
    clash = {
        "variables": [
            {"name": "p", "domain": ["q", "r"], "initial": "q"},
            {"name": "q", "domain": "bool", "initial": False},
        ],
        "transitions": [{"name": "t", "guard": "p == r", "actions": ["q := true"]}],
    }
    clashing = load_station(yaml.safe_dump(clash), "clash.yaml").model
    with pytest.raises(ValueError, match="also a variable"):
        flat_export.flat_dict(clashing)
