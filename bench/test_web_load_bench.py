"""The load benchmark runs end to end on a real `sp serve`, briefly, and leaves nothing behind
(python -m bench.web_load does the same with 50 clients for a minute)."""

from __future__ import annotations

import math
import os
import re

from bench.devices import children
from bench.web_load import kinds, measure, report

ALWAYS = (  # what ten clients ask for in a few seconds whatever the station does meanwhile
    "GET /events (to the first event)",
    "GET / (task page)",
    "GET /station",
    "GET /alarms",
    "GET /audit",
    "GET /api/station",
    "GET /api/tasks",
    "POST /login, wrong password",
    "POST /api/token, wrong password",
)


def test_a_short_load_run_reports_every_row_with_sane_numbers() -> None:
    before = set(children(os.getpid()))
    result = measure(clients=10, seconds=6.0, think=1.0)
    assert sorted(result.roles.elements()) == sorted(
        ["operator"] * 4 + ["engineer"] * 3 + ["auditor", "line system", "intruder"]
    )
    assert 5.5 < result.seconds < 8.0
    assert {name: kind.errors for name, kind in result.kinds.items() if kind.errors} == {}
    for name in ALWAYS:
        assert result.kinds[name].seconds, f"no {name} in the window"
    actions = [k for name, k in result.kinds.items() if name.startswith("POST /api/")]
    assert sum(len(k.seconds) for k in actions) >= 2
    for kind in result.kinds.values():
        assert all(0.0 < s < 10.0 for s in kind.seconds)
    # a wrong password is refused (401, or 429 once the address is throttled), not an error
    wrong = [result.kinds[n] for n in ALWAYS if "wrong password" in n]
    assert sum(k.statuses["401"] for k in wrong) > 0
    assert all(k.refused == len(k.seconds) for k in wrong)
    assert result.events["station"] > 0
    loop = result.loop
    assert 50 <= loop["rounds"] <= 70  # a round every 0.1 s over the window
    assert 90.0 <= loop["period_ms_p50"] <= 110.0
    assert loop["period_ms_p50"] <= loop["period_ms_p99"] <= loop["period_ms_max"] < 5000.0
    assert 0.0 < loop["round_ms_p50"] <= loop["round_ms_max"] < loop["period_ms_max"]
    assert all(math.isfinite(p) and p >= 0.0 for p in result.cpu.values())
    assert 0.0 < result.cpu["loop"] <= result.cpu["server"]
    text = report(result, "python -m bench.web_load --clients 10 --seconds 6")
    for name in kinds():
        assert re.search(rf"\| {re.escape(name)} \| \d+ \| 0 \| \d+ \|", text), name
    assert re.search(r"\| period between round starts \| \d+ \| [\d.]+ \| [\d.]+ \|", text)
    assert "| `sp serve`, all threads |" in text
    # the server and its planning worker are gone
    assert set(children(os.getpid())) <= before
