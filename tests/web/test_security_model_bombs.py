"""Issue 26: no engineer's model can stall the station.  Against a real HTTP server, while
a predicate bomb, YAML alias bombs and a valid model whose supervisor takes minutes to
synthesise are validated, saved and activated (several at once), the station loop keeps its
period (p99 < 150 ms; before: 0.9-1.9 s gaps, 7 s and +420 MB for 23 predicate levels):
reading and synthesis run in child processes within the model budget, on all cores but one.
The over-budget activation is refused in words, version 1 runs on, and every validation is
audited."""

from __future__ import annotations

import gc
import itertools
import math
import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from app.station.model_budget import ModelBudget
from tests.support.bombs import alias_bomb, predicate_bomb, synthesis_bomb
from tests.support.machine import Beside
from tests.support.stations import RunningStation, start_station

# as many children at once as the server's default: all cores but one
BUDGET = ModelBudget(seconds=2.0, read_seconds=15.0, memory=1024 * 2**20)
BOMBING = 8.0  # seconds: some 80 rounds at 0.1 s


@pytest.fixture
def guarded(tmp_path: Path) -> Iterator[RunningStation]:
    """A served demo station whose models must build within 2 s; what start-up built kept out
    of the collector's full collections, as `sp serve` does (app.cli.station), here with the
    test process's own objects too (those would make each full collection hold the GIL)."""
    running = start_station(tmp_path, period=0.1, speed=1.0, model_budget=BUDGET)
    running.serve()
    gc.collect()
    gc.freeze()
    try:
        yield running
    finally:
        running.stop()
        gc.unfreeze()


def refusals(station: RunningStation, subject: str) -> int:
    with station.built.server.store.engine.connect() as connection:
        found = connection.exec_driver_sql(
            "SELECT count(*) FROM audit WHERE kind = 'model' AND subject = ? AND user = ?",
            (subject, "engineer"),
        ).scalar()
    return int(found or 0)


def test_a_predicate_bomb_is_a_located_problem_at_once(station: RunningStation) -> None:
    client = station.client()
    token = station.login(client, "engineer")
    started = time.monotonic()
    answer = client.post("/model/validate", data={"csrf_token": token, "text": predicate_bomb(40)})
    assert answer.status_code == 200, answer.text[:300]
    assert "more than 100000 terms" in answer.text
    assert 'data-line="26"' in answer.text  # p16: the first past the limit
    api = station.token(station.client(), "engineer")
    saved = client.post(
        "/api/models",
        json={"text": predicate_bomb(40), "note": "bomb"},
        headers={"Authorization": f"Bearer {api}"},
    )
    assert saved.status_code == 422 and "line 26, column" in saved.json()["detail"]
    assert time.monotonic() - started < 30
    assert refusals(station, "validation refused") == 2  # each validation, as refused


def station_gaps(
    station: RunningStation, began: float, ended: float, machine: dict[str, list[Any]]
) -> tuple[list[float], int]:
    """The loop's gaps between round starts from `began` to `ended` (monotonic clock), sorted,
    and how many were left out: those a stall of the whole machine overlapped (the host
    stops the virtual machine).  From each gap the machine's share is taken out: the time the
    loop's thread sat runnable waiting for a CPU (`StationLoop`), the longest such wait of one
    other thread of the station meanwhile (one that held the interpreter lock while the
    machine ran other work), and the most the host took from one CPU meanwhile.  What is left
    is the time the station kept its own loop waiting on the interpreter, a lock or a child."""
    rounds = [(start, queued) for start, _, queued in tuple(station.live.loop.rounds)]
    rounds = [(start, queued) for start, queued in rounds if began <= start <= ended]
    loop = station.live.loop.thread
    assert loop is not None
    samples = [
        (at, {t: s for t, s in threads.items() if int(t) != loop.native_id}, steal)
        for at, threads, steal in machine["queued"]
    ]
    kept, stalled = [], 0
    for (before, queued), (after, later) in itertools.pairwise(rounds):
        if any(at < after and before < at + length for at, length in machine["stalls"]):
            stalled += 1
            continue
        _, first, stole = next((s for s in reversed(samples) if s[0] <= before), samples[0])
        _, last, steals = next((s for s in samples if s[0] >= after), samples[-1])
        waited = max((last[t] - first.get(t, last[t]) for t in last), default=0.0)
        taken = max((b - a for a, b in zip(stole, steals, strict=True)), default=0.0)
        kept.append(after - before - (later - queued) - waited - taken)
    return sorted(kept), stalled


def test_model_bombs_stall_neither_the_loop_nor_the_server(guarded: RunningStation) -> None:
    """The bombs come from clients in a process of their own, as from engineers' machines;
    a bystander process tells the machine's own stalls (a throttled virtual machine stops
    every process for ~100 ms now and then) from the station's."""
    api = guarded.token(guarded.client(), "engineer")
    bystander = Beside.start("stalls", str(os.getpid()))
    with httpx.Client(base_url=guarded.url, timeout=120) as http:
        auth = {"Authorization": f"Bearer {api}"}
        saved = http.post(
            "/api/models", json={"text": synthesis_bomb(), "note": "2^21"}, headers=auth
        )
        assert saved.status_code == 201, saved.text  # valid: only its supervisor is too large
        number = saved.json()["number"]
        clients = Beside.start("bombs", guarded.url, api, str(BOMBING))
        time.sleep(1)  # the clients are saving by now
        activated = http.post(f"/api/models/{number}/activate", headers=auth)
        began, answers = clients.result()
        ended = time.monotonic()
        watched, machine = bystander.result()
        health = http.get("/healthz").json()

    assert activated.status_code == 422, activated.text
    detail = activated.json()["detail"]
    assert "the supervisor is too large to build within 2 s" in detail
    assert f"model version {number}" in detail and "version 1 runs on" in detail
    assert {status for status, _ in answers} == {422}, answers[:5]
    assert all("line" in detail for _, detail in answers)
    gaps, stalled = station_gaps(guarded, max(began, watched), ended, machine)
    # 8 s of 0.1 s rounds: the loop kept its period; the rounds a stall of the whole machine
    # overlapped are left out of the measure (a throttled host took 39 of 74 once), so
    # enough must be left to measure
    assert len(gaps) + stalled >= 60 and len(gaps) >= 20, (len(gaps), stalled, machine["stalls"])
    p99 = gaps[math.ceil(0.99 * len(gaps)) - 1]
    assert p99 < 0.150, (p99, gaps[-5:], stalled)  # before: gaps of 0.9-1.9 s
    starts = [start for start, _, _ in guarded.live.loop.rounds if began <= start <= ended]
    longest = max(b - a for a, b in itertools.pairwise(starts))
    assert longest < 1.0, longest  # the machine's stalls too; before: 7 s per 23 levels
    assert health["model"] == 1 and guarded.live.model.number == 1
    rounds = guarded.live.loop_summary()["rounds"]
    guarded.wait(lambda: guarded.live.loop_summary()["rounds"] > rounds, 5)  # still running
    assert refusals(guarded, "validation refused") == len(answers) >= 4
    assert refusals(guarded, "validated") == 1
    assert refusals(guarded, "activation refused: over budget") == 1


def test_the_loop_is_sampled_while_bombs_are_read_one_after_another(
    guarded: RunningStation,
) -> None:
    """The bombs' children leave the server's own threads free: pages answer meanwhile."""
    api = guarded.token(guarded.client(), "engineer")
    auth = {"Authorization": f"Bearer {api}"}
    done = threading.Event()
    pages: list[int] = []

    def browse() -> None:
        with httpx.Client(base_url=guarded.url, timeout=30) as http:
            while not done.is_set():
                pages.append(http.get("/healthz").status_code)
                time.sleep(0.1)

    browser = threading.Thread(target=browse)
    browser.start()
    try:
        with httpx.Client(base_url=guarded.url, timeout=120, headers=auth) as http:
            for text in (predicate_bomb(25), alias_bomb()):
                assert http.post("/api/models", json={"text": text}).status_code == 422
    finally:
        done.set()
        browser.join(timeout=30)
    assert pages and set(pages) == {200}
