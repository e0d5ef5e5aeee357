"""Issue 26: no engineer's model can stall the station.  Against a real HTTP server, while
a predicate bomb, YAML alias bombs and a valid model whose supervisor takes minutes to
synthesise are validated, saved and activated (several at once), the station loop keeps its
period (p99 < 150 ms; before: 0.9-1.9 s gaps, 7 s and +420 MB for 23 predicate levels):
reading and synthesis run in child processes within the model budget.  The over-budget
activation is refused in words, version 1 runs on, and every validation is audited."""

from __future__ import annotations

import gc
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

from app.station.model_budget import ModelBudget
from tests.support.bombs import alias_bomb, predicate_bomb, synthesis_bomb
from tests.support.stations import RunningStation, start_station

BUDGET = ModelBudget(seconds=2.0, read_seconds=15.0, memory=1024 * 2**20, at_once=2)


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


def test_model_bombs_stall_neither_the_loop_nor_the_server(guarded: RunningStation) -> None:
    api = guarded.token(guarded.client(), "engineer")
    auth = {"Authorization": f"Bearer {api}"}
    with httpx.Client(base_url=guarded.url, timeout=120, headers=auth) as http:
        saved = http.post("/api/models", json={"text": synthesis_bomb(), "note": "2^21"})
        assert saved.status_code == 201, saved.text  # valid: only its supervisor is too large
        number = saved.json()["number"]
        quiet = http.get("/healthz").json()["loop"]["now"]
        time.sleep(4)  # the loop on this machine as it is, before the bombs
        idle = http.get("/healthz", params={"since": quiet}).json()["loop"]
        since = idle["now"]

        deadline = time.monotonic() + 8  # some 80 rounds: p99 is not one round's gap

        def save(text: str) -> list[httpx.Response]:
            answers = []
            with httpx.Client(base_url=guarded.url, timeout=120, headers=auth) as own:
                while not answers or time.monotonic() < deadline:
                    answers.append(own.post("/api/models", json={"text": text, "note": "b"}))
            return answers

        bombs = [predicate_bomb(30), predicate_bomb(60, "->"), alias_bomb(), alias_bomb(12, 7)]
        with ThreadPoolExecutor(max_workers=4) as pool:
            saves = [pool.submit(save, text) for text in bombs]
            activated = http.post(f"/api/models/{number}/activate")
            answers = [answer for s in saves for answer in s.result()]
        summary = http.get("/healthz", params={"since": since}).json()
        health = http.get("/healthz").json()

    assert activated.status_code == 422, activated.text
    detail = activated.json()["detail"]
    assert "the supervisor is too large to build within 2 s" in detail
    assert f"model version {number}" in detail and "version 1 runs on" in detail
    assert {a.status_code for a in answers} == {422}, [a.text[:200] for a in answers]
    assert all("line" in a.json()["detail"] for a in answers)
    loop = summary["loop"]
    assert loop["rounds"] > 10, loop
    # the design's bound: 150 ms at a 100 ms period; a machine busy with others may stretch
    # even the idle loop's gaps, and then the bombs may add no more than a period to them
    assert loop["period_ms_p99"] < max(150, idle["period_ms_p99"] + 100), (loop, idle)
    assert loop["period_ms_max"] < 1000, loop  # before: 0.9-1.9 s, and 7 s per 23 levels
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
