"""The supervisor cache gives the same planner as synthesis, and never breaks `sp`."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest
import yaml

from app.station import supervisor_cache
from bench import family
from planner.model.expression_text import parse_expr
from planner.planning.query import PlanQuery
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_model, load_station
from planner.reading.yaml_reader import ModelError, scope_for
from tests.support.attacks import poison_cache
from tests.support.paths import MINI_STATION

MINI = MINI_STATION


def plan(directory: Path | None) -> tuple[tuple[str, ...], int]:
    text = MINI.read_text()
    station = load_station(text, str(MINI))
    planner = supervisor_cache.planner(station.model, text, "bdd", directory)
    start = tuple(station.model.initial_values().values())
    result = planner.plan(PlanQuery(start, station.predicates["assemble.goal"]))
    return result.plan, planner.sym.count(planner.bad)


def entries(directory: Path) -> list[Path]:
    """The entries' JSON files (the order and checksums), not the saved closures."""
    return [p for p in directory.glob("*.json") if not p.name.endswith(".specifications.json")]


def test_a_saved_supervisor_plans_exactly_like_a_fresh_one(tmp_path: Path) -> None:
    fresh = plan(None)
    assert plan(tmp_path) == fresh  # synthesised and saved
    assert len(list(tmp_path.glob("*.dddmp"))) == 1
    assert plan(tmp_path) == fresh  # restored


def test_a_damaged_entry_is_synthesised_again(tmp_path: Path) -> None:
    fresh = plan(tmp_path)
    (entry,) = tmp_path.glob("*.dddmp")
    entry.write_bytes(entry.read_bytes()[:40])  # truncated: CUDD's reader would crash on it
    assert plan(tmp_path) == fresh
    (saved,) = entries(tmp_path)
    saved.write_text('{"order": ["v0_0"], "bad_sha256": "0"}')
    assert plan(tmp_path) == fresh
    checksum = hashlib.sha256(entry.read_bytes()).hexdigest()
    saved.write_text(json.dumps({"order": ["v0_0"], "bad_sha256": checksum}))  # wrong order
    assert plan(tmp_path) == fresh
    saved.write_text("[")  # not JSON
    assert plan(tmp_path) == fresh
    (closures,) = tmp_path.glob("*.specifications.json")
    closures.write_text(closures.read_text().replace("1", "2"))  # fails its checksum
    assert plan(tmp_path) == fresh


def test_the_states_bad_for_each_specification_are_restored(tmp_path: Path) -> None:
    """Forbidden-state recovery plans with them; a restored planner has the same sets."""
    text = MINI.read_text()
    station = load_station(text, str(MINI))
    fresh = supervisor_cache.planner(station.model, text, "bdd", tmp_path)
    restored = supervisor_cache.planner(station.model, text, "bdd", tmp_path)
    assert set(restored.bad_by_specification) == {s.name for s in station.model.specifications}
    for name, states in fresh.bad_by_specification.items():
        assert restored.sym.count(restored.bad_by_specification[name]) == fresh.sym.count(states)
        assert restored.sym.count(restored.bad_by_specification[name] & restored.bad) == (
            fresh.sym.count(states)
        )


def test_a_file_in_place_of_the_directory_only_costs_time(tmp_path: Path) -> None:
    blocked = tmp_path / "cache"
    blocked.write_text("a file, not a directory")
    assert plan(blocked) == plan(None)


def test_the_key_depends_on_the_text_and_the_planners_code(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A restored planner skips what the build that saved it did (checking the dynamics,
    synthesis): only the same text under the same code may find it."""
    text = MINI.read_text()
    assert supervisor_cache.key(text) == supervisor_cache.key(text)
    assert supervisor_cache.key(text) != supervisor_cache.key(text + "\n# changed\n")
    before = supervisor_cache.key(text)
    monkeypatch.setattr(supervisor_cache, "code_digest", lambda: "another planner")
    assert supervisor_cache.key(text) != before


def test_a_model_whose_automatics_cycle_is_refused_and_never_saved(tmp_path: Path) -> None:
    cycling = """
variables:
  - {name: a, domain: bool}
transitions:
  - {name: up, kind: automatic, guard: "!a", actions: ["a := true"]}
  - {name: down, kind: automatic, guard: "a", actions: ["a := false"]}
"""
    model = load_model(cycling, "cycle.yaml")
    for _ in range(2):  # refused each time: nothing was saved to skip the check with
        with pytest.raises(ModelError, match="cycle forever"):
            supervisor_cache.planner(model, cycling, "bdd", tmp_path)
    assert entries(tmp_path) == []


def test_the_order_chosen_for_search_is_saved_and_plans_exactly_like_any_other(
    tmp_path: Path,
) -> None:
    """The first plan chooses the variable order for search (`SymbolicPlanner.tune`); the
    cache keeps it, a planner restored with it gives the same plans, state by state, and
    so does a planner held in each of the candidate orders."""
    text = yaml.safe_dump(family.station(3, 2), sort_keys=False)
    model = load_station(text, "family.yaml").model
    scope = scope_for(model.domains)
    start = tuple(model.initial_values().values())
    queries = [
        PlanQuery(start, parse_expr(family.goal(3), scope)),
        PlanQuery(start, parse_expr("r2.pos == bp2 && bp1.state == tightened", scope)),
    ]
    first = supervisor_cache.planner(model, text, "bdd", tmp_path)
    assert not first.tuned
    expected = [first.plan(q) for q in queries]
    assert all(r.found for r in expected) and first.tuned
    supervisor_cache.remember_order(first, text, tmp_path)
    (saved,) = entries(tmp_path)
    entry = json.loads(saved.read_text())
    assert entry["tuned"] and entry["order"] == first.order()

    restored = supervisor_cache.planner(model, text, "bdd", tmp_path)
    assert restored.tuned and restored.order() == entry["order"]
    assert restored.sym.initial_order == entry["order"]  # declared so: no static order made
    results = [restored.plan(q) for q in queries]
    assert results == expected
    assert [r.states for r in results] == [r.states for r in expected]

    for order in (first.sym.initial_order, list(reversed(first.sym.initial_order))):
        other = TransitionPlanner(model)
        other.tuned = True  # keep the order given here
        other.sym.reorder(order)
        assert [other.plan(q) for q in queries] == expected


FAMILY = yaml.safe_dump(family.station(3, 2), sort_keys=False)  # small, with bad states


def forbidden(directory: Path | None) -> tuple[int, dict[str, int]]:
    """How many states a station's supervisor forbids, in all and per specification."""
    model = load_station(FAMILY, "family.yaml").model
    planner = supervisor_cache.planner(model, FAMILY, "bdd", directory)
    each = {name: planner.sym.count(f) for name, f in planner.bad_by_specification.items()}
    return planner.sym.count(planner.bad), each


def _poison(directory: Path) -> None:
    poison_cache(directory, FAMILY)


def test_an_entry_rewritten_to_no_forbidden_states_is_not_believed(tmp_path: Path) -> None:
    fresh = forbidden(tmp_path)
    assert fresh[0] > 0
    _poison(tmp_path)
    assert forbidden(tmp_path) == fresh  # synthesised again: the seal did not match
    (saved,) = entries(tmp_path)
    assert "seal" in json.loads(saved.read_text())
    _poison(tmp_path)
    entry = json.loads(saved.read_text())
    del entry["seal"]  # nor is an entry without a seal
    saved.write_text(json.dumps(entry))
    assert forbidden(tmp_path) == fresh


def test_entries_sealed_with_another_key_are_synthesised_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fresh = forbidden(tmp_path / "cache")
    monkeypatch.setenv("SP_CACHE_KEY_FILE", str(tmp_path / "other.key"))
    _poison(tmp_path / "cache")
    assert forbidden(tmp_path / "cache") == fresh
    assert (tmp_path / "other.key").stat().st_mode & 0o777 == 0o600


def test_without_a_key_the_cache_is_not_used(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    blocked = tmp_path / "blocked"
    blocked.write_text("a file, not a folder")
    monkeypatch.setenv("SP_CACHE_KEY_FILE", str(blocked / "cache.key"))
    assert plan(tmp_path / "cache") == plan(None)
    assert not (tmp_path / "cache").exists()
