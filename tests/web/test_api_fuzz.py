"""Fuzz the JSON API from its own OpenAPI schema (schemathesis): no input may cause a 5xx.

Every operation of /openapi.json gets valid (positive) and invalid (negative) requests as an
admin (bearer token), on a station of its own, so whatever the requests do to it (restart
mode, cancelled intentions, an experiment played) cannot disturb other tests.  The token is
fixed, so negative requests break parameters and bodies, not the sign-in (401 and 403 are
tested in tests/web/test_api.py).  Besides the absence of server errors, answers must use
documented status codes and content types, match the documented response schemas, and
invalid requests must be refused.  Bounded and derandomized: each operation gets `EXAMPLES`
cases per mode, so the run is the same every time and takes well under a minute.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import schemathesis
from hypothesis import HealthCheck, given, settings
from hypothesis.errors import Unsatisfiable
from schemathesis import GenerationMode
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    negative_data_rejection,
    response_schema_conformance,
    status_code_conformance,
)

from tests.support.stations import RunningStation, start_station

EXAMPLES = 25
CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_schema_conformance,
]
NEGATIVE_CHECKS = [*CHECKS, negative_data_rejection]


@pytest.fixture(scope="module")
def fuzzed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(Path(tmp_path_factory.mktemp("fuzz")), api_docs=True)
    yield running
    running.stop()


def fuzz(
    operation: schemathesis.APIOperation,
    mode: GenerationMode,
    headers: dict[str, str],
    statuses: dict[int, int],
    path: dict[str, object] | None = None,
) -> None:
    """Send `EXAMPLES` generated requests to `operation` and check each answer; `path`
    fixes path parameters (names the model has), the rest is generated."""
    checks = CHECKS if mode is GenerationMode.POSITIVE else NEGATIVE_CHECKS

    strategy = operation.as_strategy(generation_mode=mode, path_parameters=path, headers=headers)

    @settings(
        max_examples=EXAMPLES,
        derandomize=True,
        database=None,
        deadline=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(case=strategy)
    def run(case: schemathesis.Case) -> None:
        response = case.call_and_validate(checks=checks)
        statuses[response.status_code] = statuses.get(response.status_code, 0) + 1

    try:
        run()
    except Unsatisfiable:
        # with the token fixed, an operation without parameters or body has nothing to break
        assert mode is GenerationMode.NEGATIVE, operation.label


def real_names(station: RunningStation) -> dict[str, dict[str, object]]:
    """Path parameters the demo station knows, per path."""
    model = station.live.view.model.station
    effect = next(t.name for t in model.model.transitions if t.kind.value == "effect")
    return {
        "/api/intentions/{name}/start": {"name": model.intentions[0].name},
        "/api/intentions/{name}/cancel": {"name": model.intentions[0].name},
        "/api/operations/{name}/reset": {"name": model.operations[0].name},
        "/api/effects/{name}/reenable": {"name": effect},
        "/api/maintenance/{transition}/done": {"transition": "operator.reset_r1_tc"},
        "/api/cards/{card}/done": {"card": "place_bp4"},
        "/api/approvals/{step}": {"step": 0},
        "/api/models/{number}": {"number": 1},
        "/api/models/{number}/activate": {"number": 1},
        "/api/experiments/{experiment}/play": {"experiment": "e3_lock_fails_on_attach"},
    }


def test_no_request_gets_a_server_error(fuzzed: RunningStation) -> None:
    client = fuzzed.client()
    headers = {"Authorization": f"Bearer {fuzzed.token(client, 'admin')}"}
    schema = schemathesis.openapi.from_asgi("/openapi.json", fuzzed.built.app)
    operations = [result.ok() for result in schema.get_all_operations()]
    assert len(operations) >= 23, [o.label for o in operations]
    statuses: dict[int, int] = {}
    started = time.monotonic()
    for operation in operations:
        for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE):
            fuzz(operation, mode, headers, statuses)
    # random names mostly meet a 404; with real ones the requests reach the runner
    known = real_names(fuzzed)
    for operation in operations:
        if operation.path in known:
            fuzz(operation, GenerationMode.POSITIVE, headers, statuses, known[operation.path])
    seconds = time.monotonic() - started
    sent = sum(statuses.values())
    print(f"\nfuzz: {len(operations)} operations, {sent} requests in {seconds:.1f} s: {statuses}")
    assert sent >= len(operations) * 2
    assert not any(status >= 500 for status in statuses)
