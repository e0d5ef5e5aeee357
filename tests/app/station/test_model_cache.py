"""The model cache gives the station the text describes, and never one somebody else wrote."""

from __future__ import annotations

import json
import logging
import os
import pickle
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from app.station import model_cache, supervisor_cache
from planner.model.expression_text import parse_expr
from planner.planning.query import PlanQuery
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.reading.yaml_reader import ModelError, scope_for
from tests.support.paths import MINI_STATION, REPOSITORY

DEMO = REPOSITORY / "models" / "demo_station.yaml"


def reads(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The files `model_cache.load` read from their text (not from the cache)."""
    read: list[str] = []

    def counted(text: str, file: str = "<model>") -> object:
        read.append(file)
        return load_station(text, file)

    monkeypatch.setattr(model_cache, "load_station", counted)
    return read


def test_a_cached_model_is_the_model_read_and_plans_alike(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    read = reads(monkeypatch)
    text = DEMO.read_text(encoding="utf-8")
    fresh = load_station(text, "demo")
    first = model_cache.load(text, "demo", tmp_path)
    cached = model_cache.load(text, "demo", tmp_path)
    assert read == ["demo"]  # the second came from the cache
    assert cached is not first and cached == fresh
    assert cached.model == fresh.model and cached.predicates == fresh.predicates
    goal = parse_expr("bp1.state == tightened", scope_for(fresh.model.domains))
    start = tuple(fresh.model.initial_values().values())
    plans = [
        TransitionPlanner(station.model, "bdd").plan(PlanQuery(start, goal)).plan
        for station in (fresh, cached)
    ]
    assert plans[0] == plans[1] and len(plans[0]) == 32


def test_an_entry_is_for_one_text_one_name_and_this_code(tmp_path: Path) -> None:
    text = MINI_STATION.read_text(encoding="utf-8")
    name = model_cache.entry_name(text, "mini")
    assert model_cache.entry_name(text + "\n", "mini") != name
    assert model_cache.entry_name(text, "model version 2") != name
    supervisor_cache.code_digest.cache_clear()
    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(model_cache, "FORMAT", model_cache.FORMAT + 1)
            assert model_cache.entry_name(text, "mini") != name
    finally:
        supervisor_cache.code_digest.cache_clear()
    model_cache.load(text, "mini", tmp_path / "cache")
    (entry,) = (tmp_path / "cache").iterdir()
    assert entry.name == name + model_cache.SUFFIX
    assert stat.S_IMODE(entry.stat().st_mode) == 0o600
    assert stat.S_IMODE((tmp_path / "cache").stat().st_mode) == 0o700


class Planted:
    """What an attacker's pickle would do when loaded: leave a mark."""

    def __init__(self, mark: Path) -> None:
        self.mark = mark

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return (Path.touch, (str(self.mark),))  # type: ignore[return-value]


def test_an_entry_written_without_the_cache_key_is_never_unpickled(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    text = MINI_STATION.read_text(encoding="utf-8")
    fresh = model_cache.load(text, "mini", tmp_path)
    (entry,) = tmp_path.iterdir()
    mark = tmp_path.parent / f"{tmp_path.name}-unpickled"
    body = pickle.dumps(Planted(mark))
    read = reads(monkeypatch)
    for seal in (b"\0" * model_cache.SEAL, entry.read_bytes()[: model_cache.SEAL]):
        entry.write_bytes(seal + body)  # a forged seal, and the seal of the right entry
        with caplog.at_level(logging.WARNING, logger="app.station.model_cache"):
            assert model_cache.load(text, "mini", tmp_path) == fresh
        assert not mark.exists()
        assert "not sealed with the cache key" in caplog.text
    assert read == ["mini", "mini"]  # read from the text each time, and the entry rewritten
    assert model_cache.load(text, "mini", tmp_path) == fresh and read == ["mini", "mini"]
    entry.write_bytes(entry.read_bytes()[:100])  # truncated: read from the text again
    assert model_cache.load(text, "mini", tmp_path) == fresh and len(read) == 3


def test_a_model_with_problems_is_said_so_and_never_kept(tmp_path: Path) -> None:
    text = "variables:\n  - {name: x, domain: bool}\ntransitions: 3\n"
    for _ in range(2):
        with pytest.raises(ModelError) as refused:
            model_cache.load(text, "broken.yaml", tmp_path)
        assert "broken.yaml:3:14" in str(refused.value)
    assert list(tmp_path.iterdir()) == []


def test_sp_plan_keeps_the_model_read_and_not_with_no_cache(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "app.cli.main", "plan", str(MINI_STATION)]
    command += ["--goal", "assemble.goal", "--json"]
    environment = {**os.environ, "SP_CACHE_DIR": str(tmp_path)}

    def plan(*extra: str) -> list[str]:
        done = subprocess.run(
            [*command, *extra],
            capture_output=True,
            text=True,
            cwd=REPOSITORY,
            env=environment,
            timeout=120,
            check=True,
        )
        answer = json.loads(done.stdout)
        assert answer["status"] == "found", answer
        return list(answer["plan"])

    uncached = plan("--no-cache")
    assert not list(tmp_path.glob(f"*{model_cache.SUFFIX}"))
    assert plan() == uncached  # read, and kept
    assert len(list(tmp_path.glob(f"*{model_cache.SUFFIX}"))) == 1
    assert plan() == uncached  # from the cache
