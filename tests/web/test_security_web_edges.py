"""Edges of the station server that a hostile client, or a generated model, pushes on (issue
15): nesting deep enough to overflow Python's stack, numbers too large for SQLite, the
security headers on every answer (and pages that live within their policy), the redirect
after a form, and connections that never finish their request."""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn
from fastapi.testclient import TestClient
from hypothesis import given
from hypothesis import strategies as st
from pysat.solvers import Cadical195
from starlette.types import Receive, Scope, Send

from app.web import http_server
from app.web.headers import SecurityHeaders
from planner.bdd.symbolic import SymbolicModel
from planner.model import expressions
from planner.model.expression_syntax import parse_syntax
from planner.model.expression_text import _resolve, parse_expr
from planner.model.expressions import MAX_NESTING, Expr, depth, format_expr, variables_of
from planner.model.flat import Model
from planner.model.semantics import compile_expr
from planner.planning.bmc import _Encoding
from planner.planning.symmetry import Symmetry
from planner.reading import load_model, load_station
from planner.reading.yaml_reader import ModelError, scope_for
from planner.runner import LeaveRestart
from tests.browser.test_browser_operator import screenshot, sign_in
from tests.support.paths import MINI_STATION
from tests.support.stations import ROOT, RunningStation, form_token, free_port, sign_in_with_forms

MINI = MINI_STATION
GUARD = '"bp1.state == empty"'  # the guard of operator.place_bolts.start in MINI
ATOM = "bp1.state == empty"
TRANSITION = "operator.place_bolts"
HX = {"hx-request": "true"}


# ---- 1. nesting ----------------------------------------------------------------------------------


def parens(n: int) -> str:
    return "(" * n + ATOM + ")" * n


def negations(n: int) -> str:
    return "!" * n + ATOM


def implications(n: int) -> str:
    return " -> ".join([ATOM] * (n + 1))


def alternating(n: int) -> str:
    """`&&` and `||` in turn, each around the one before: n operators deep, n - 1 parentheses."""
    text = ATOM
    for i in range(n - 1):
        text = f"({text}) {'&&' if i % 2 else '||'} !nr.running"
    return text


def negated_conjunctions(n: int) -> str:
    """`!(nr.run && !(nr.run && ...))`: two levels (of parser and operators) per `!(`."""
    text = ATOM
    for _ in range(n // 2):
        text = f"!(nr.run && {text})"
    return "!" * (n % 2) + text


SHAPES = {
    f.__name__: f for f in (parens, negations, implications, alternating, negated_conjunctions)
}


def with_guard(guard: str, base: str | None = None) -> str:
    text = base if base is not None else MINI.read_text()
    assert text.count(GUARD) == 1
    return text.replace(GUARD, f'"{guard}"')


def guard_column(text: str, offset: int) -> tuple[int, int]:
    """Line and (1-based) column of character `offset` of the injected guard."""
    start = text.index('guard: "', text.index("place_bolts")) + len('guard: "')
    line = text[:start].count("\n") + 1
    return line, start - (text.rfind("\n", 0, start) + 1) + offset + 1


@contextlib.contextmanager
def stack_budget(frames: int) -> Iterator[None]:
    """Python's recursion limit `frames` above the current depth: what runs inside would also
    run under a caller that much shallower than the limit (a web request, the planning worker)."""
    here, frame = 0, sys._getframe()
    while frame is not None:
        here, frame = here + 1, frame.f_back  # type: ignore[assignment]
    before = sys.getrecursionlimit()
    sys.setrecursionlimit(here + frames)
    try:
        yield
    finally:
        sys.setrecursionlimit(before)


def sp_check(path: Path) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "app.cli.main", "check", str(path)]
    return subprocess.run(command, capture_output=True, text=True, timeout=120, cwd=ROOT)


@pytest.mark.parametrize("shape", SHAPES)
def test_nesting_past_the_limit_is_refused_at_its_place(shape: str, tmp_path: Path) -> None:
    with pytest.raises(ModelError, match="nested more than 100 deep"):  # was a RecursionError
        load_station(with_guard(SHAPES[shape](10_000)), "deeper.yaml")
    guard = SHAPES[shape](MAX_NESTING + 1)
    text = with_guard(guard)
    with pytest.raises(ModelError) as caught:
        load_station(text, "deep.yaml")
    (problem,) = caught.value.diagnostics
    assert "nested more than 100 deep" in problem.message
    assert "the guard of transition 'operator.place_bolts.start'" in problem.message
    offset = {  # where the parser stops: the token that opens level 101
        "parens": lambda: MAX_NESTING,
        "negations": lambda: MAX_NESTING,
        "implications": lambda: len(implications(MAX_NESTING)) + 1,
        "negated_conjunctions": lambda: guard.rindex("("),
        "alternating": lambda: 0,  # 100 parentheses, 101 operators: the whole expression
    }[shape]()
    assert (problem.location.line, problem.location.column) == guard_column(text, offset)

    # `sp check` says the same, without a traceback
    path = tmp_path / "deep.yaml"
    path.write_text(text)
    checked = sp_check(path)
    assert checked.returncode == 2, checked.stderr
    assert "Traceback" not in checked.stderr
    assert f"{path}:{problem.location.line}:{problem.location.column}:" in checked.stderr


def test_predicates_built_on_predicates_count_with_their_depth() -> None:
    """Each predicate alone is within the limit; written out, the second is not."""
    text = MINI.read_text()
    first = '          enabled: "!run && !running"\n'
    deep = alternating(60).replace(ATOM, "run").replace("nr.running", "running")
    deeper = alternating(60).replace(ATOM, "deep1").replace("nr.running", "running")
    text = text.replace(first, first + f'          deep1: "{deep}"\n          deep2: "{deeper}"\n')
    with pytest.raises(ModelError) as caught:
        load_station(text, "deep.yaml")
    (problem,) = caught.value.diagnostics
    assert problem.location.line == text[: text.index("deep2:")].count("\n") + 1
    assert "predicate 'deep2'" in problem.message
    assert "nested more than 100 deep (118 operators, counting those of the predicates" in (
        problem.message  # 60 + 59, less one: deep2's innermost `||` merges with deep1's top
    )


def test_yaml_nested_past_the_limit_is_refused_not_a_crash() -> None:
    """libyaml's composer recursed in C: 100,000 brackets killed the process (SIGSEGV)."""
    for text in (
        "station: x\nvariables: " + "[" * 100_000 + "]" * 100_000 + "\n",
        "station: x\nvariables:\n" + "".join("  " * i + "- \n" for i in range(1, 200)),
    ):
        with pytest.raises(ModelError) as caught:
            load_station(text, "deep.yaml")
        assert "nested more than 100 deep" in str(caught.value)


def walk_everywhere(model: Model, expr: Any) -> None:
    """Each recursive walker over expressions: reparse its text, names, evaluation, hash and
    equality, BDD (planner.bdd.symbolic), SAT (planner.planning.bmc), the symmetry image."""
    sym = SymbolicModel(model)
    names = {v.name: v.domain for v in model.variables}
    index = model.variable_index
    state = tuple(v.initial for v in model.variables)
    with Cadical195() as solver:
        encoding = _Encoding(sym, solver)
        encoding.add_state()
        identity = Symmetry("a", "b", {}, {}, {}, frozenset(), None)
        with stack_budget(500):
            again = parse_expr(format_expr(expr), scope_for(names))
            assert again == expr and hash(again) == hash(expr)
            assert "bp1.state" in variables_of(expr)
            compile_expr(expr, index)(state)
            sym.expr(expr)
            encoding.lit(expr, 0)
            assert identity.expr(expr) == expr


def test_aliases_that_multiply_a_model_are_refused_at_their_place() -> None:
    """Anchors naming anchors: a few hundred bytes that stand for millions of nodes are
    refused before the model is composed, at the alias that passes the bound; a model that
    uses aliases as people do loads."""
    anchors = "defs:\n  - &a0 {name: x, domain: bool}\n" + "".join(
        f"  - &a{k} [" + ", ".join([f"*a{k - 1}"] * 10) + "]\n" for k in range(1, 7)
    )
    bomb = anchors + "variables: [*a6]\ntransitions: []\n"
    assert len(bomb) < 500
    with pytest.raises(ModelError) as caught:
        load_model(bomb, "bomb.yaml")
    [message] = [str(d) for d in caught.value.diagnostics]
    assert message.startswith("bomb.yaml:7:10: YAML: aliases repeat more than")
    shared = "variables:\n  - &flag {name: x, domain: bool}\ntransitions:\n"
    shared += "  - {name: t, guard: '!x', actions: &set ['x := true']}\n"
    shared += "  - {name: u, guard: 'x', actions: *set}\n"
    model = load_model(shared, "shared.yaml")
    assert [t.name for t in model.transitions] == ["t", "u"]


@pytest.mark.parametrize("shape", SHAPES)
def test_nesting_at_the_limit_works_everywhere(shape: str, tmp_path: Path) -> None:
    text = with_guard(SHAPES[shape](MAX_NESTING))
    with stack_budget(500):
        station = load_station(text, "deep.yaml")
    guard = station.model.transition(TRANSITION).guard
    assert depth(guard) <= MAX_NESTING
    walk_everywhere(station.model, guard)
    path = tmp_path / "deep.yaml"
    path.write_text(text)
    checked = sp_check(path)
    assert checked.returncode == 0, checked.stderr
    assert "valid" in checked.stdout


def test_a_long_flat_chain_is_one_level() -> None:
    """How its reading time grows with its length (it grew quadratically once): bench/reading.py."""
    terms = 20_000
    for operator in ("&&", "||"):
        guard = f" {operator} ".join([ATOM] * terms)
        with stack_budget(200):  # nothing recurses per term
            station = load_station(with_guard(guard), "long.yaml")
        expr = station.model.transition(TRANSITION).guard
        assert depth(expr) == 1 and len(expr.args) == terms  # type: ignore[union-attr]
        walk_everywhere(station.model, expr)


NAMES = {"a": (False, True), "b": (False, True), "x": ("p", "q"), "y": ("p", "q")}
ATOMS = ("a", "b", "true", "false", "x == p", "x != q", "x == y", "x != y", "a == false", "P", "N")
TEXTS = st.recursive(
    st.sampled_from(ATOMS),
    lambda inner: st.one_of(
        inner.map(lambda e: f"!({e})"),
        st.lists(inner, min_size=2, max_size=3).map(lambda es: "(" + " && ".join(es) + ")"),
        st.lists(inner, min_size=2, max_size=3).map(lambda es: "(" + " || ".join(es) + ")"),
        st.tuples(inner, inner).map(lambda lr: f"({lr[0]} -> {lr[1]})"),
    ),
    max_leaves=30,
)


@given(TEXTS)
def test_the_depth_counted_while_resolving_is_the_depth_of_the_result(text: str) -> None:
    """`resolve` counts depth as it builds (flattening, double negations, predicates) instead
    of walking the result; it must come out as `depth` would measure it."""
    plain = scope_for(NAMES)
    predicates = {"P": parse_expr("a && (b || x == p)", plain), "N": parse_expr("!a", plain)}
    expr, levels = _resolve(parse_syntax(text), scope_for(NAMES, predicates))
    assert levels == depth(expr)


def test_guards_naming_a_large_predicate_do_not_walk_it_each_time(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Counted, not timed: the operands looked at while the model is read (a guard `big && x`
    is a new conjunction of 20,001 operands; measuring it walked them, once per guard)."""
    big = " && ".join(f"v{i % 50}" for i in range(20_000))
    lines = ["station: s", "variables:", *(f"  - {{name: v{i}, domain: bool}}" for i in range(50))]
    lines += ["resources:", "  - name: r", "    variables:", "      - {name: x, domain: bool}"]
    lines += ["    abilities:", "      - name: a", "        predicates:", f'          big: "{big}"']
    lines += ["        transitions:"]
    lines += [f'          - {{name: t{i}, guard: "big && x", actions: ["x := true"]}}'
              for i in range(1000)]  # fmt: skip
    looked_at = 0
    operands = expressions._operands

    def counted(node: Expr) -> tuple[Expr, ...]:
        nonlocal looked_at
        found = operands(node)
        looked_at += len(found)
        return found

    monkeypatch.setattr(expressions, "_operands", counted)
    load_station("\n".join(lines) + "\n", "big.yaml")
    # the predicate's 20,000 operands a few times over, not once for each of the 1,000 guards
    assert 20_000 <= looked_at < 10 * 20_000, looked_at  # (its size measured once, too)


def engineer(station: RunningStation) -> tuple[TestClient, str]:
    client = station.client()
    return client, station.login(client, "engineer")


def test_the_model_editor_refuses_deep_models_and_saves_those_at_the_limit(
    station: RunningStation,
) -> None:
    client, token = engineer(station)
    base = station.live.model.text
    demo_guard = '"card == idle && done == idle"'
    line = base[: base.index(demo_guard)].count("\n") + 1
    for levels, url in ((101, "/model/validate"), (5000, "/model/validate"), (101, "/model/save")):
        deep = base.replace(demo_guard, f'"{"(" * levels}card == idle{")" * levels}"', 1)
        answer = client.post(url, data={"csrf_token": token, "text": deep}, headers=HX)
        assert answer.status_code in (200, 422), url  # 5000 was a RecursionError: a 500
        assert "nested more than 100 deep" in answer.text
        assert f'data-line="{line}"' in answer.text

    # a YAML bomb of brackets is a located problem too, not a dead station
    bomb = "station: x\nvariables: " + "[" * 100_000 + "]" * 100_000 + "\n"
    answer = client.post("/model/validate", data={"csrf_token": token, "text": bomb}, headers=HX)
    assert answer.status_code == 200 and "nested more than 100 deep" in answer.text

    at_limit = base.replace(demo_guard, f'"{"(" * 100}card == idle{")" * 100} && done == idle"')
    saved = client.post(
        "/model/save", data={"csrf_token": token, "text": at_limit}, follow_redirects=False
    )
    assert saved.status_code == 303, saved.text
    assert saved.headers["location"] == "/model?version=2"
    assert client.get("/model", params={"version": 2}).status_code == 200
    diff = client.get("/model/diff", params={"version": 2})
    assert diff.status_code == 200 and "(" * 100 in diff.text


# ---- 2. integers too large for SQLite ------------------------------------------------------------

HUGE = "99999999999999999999"  # > 2**64: SQLite raised OverflowError, a 500


def test_numbers_too_large_for_the_database_are_a_4xx_with_a_message(
    station: RunningStation,
) -> None:
    client, token = engineer(station)
    for huge in (HUGE, str(2**63), str(2**31)):
        for answer in (
            client.get("/model", params={"version": huge}),
            client.get("/model/diff", params={"version": huge}),
            client.post("/model/activate", data={"csrf_token": token, "version": huge}),
            client.post("/model/activate", data={"csrf_token": token, "version": huge}, headers=HX),
        ):
            # a plain form's refusal is said by the page it redirects to (followed)
            plain = bool(answer.history)
            assert answer.status_code == (200 if plain else 422), (answer.request.url, answer.text)
            assert "version" in answer.text and "less than or equal to" in answer.text
    assert client.get("/model", params={"version": 999_999_999}).status_code == 404
    assert client.get("/audit", params={"page": HUGE}).status_code == 200  # the last page
    api = {"authorization": f"Bearer {station.token(client, 'engineer')}"}
    assert client.get(f"/api/models/{HUGE}", headers=api).status_code == 422
    operator = station.client()
    operator_token = station.login(operator, "operator")
    refused = operator.post("/tasks/approve", data={"csrf_token": operator_token, "step": HUGE})
    assert refused.status_code == 200 and "less than or equal to" in refused.text


# ---- 3. security headers -------------------------------------------------------------------------


def assert_secured(response: httpx.Response) -> None:
    where = f"{response.request.method} {response.request.url} ({response.status_code})"
    policy = response.headers.get("content-security-policy", "")
    for directive in (
        "default-src 'self'",
        "object-src 'none'",
        "base-uri 'none'",
        "frame-ancestors 'none'",
        "form-action 'self'",
    ):
        assert directive in policy, where
    assert "unsafe-eval" not in policy, where
    assert "script-src 'self';" in policy and "unsafe-inline" not in policy, where
    assert response.headers.get("x-frame-options") == "DENY", where
    assert response.headers.get("x-content-type-options") == "nosniff", where
    assert response.headers.get("referrer-policy") == "same-origin", where


def test_every_kind_of_answer_carries_the_security_headers(station: RunningStation) -> None:
    anonymous = station.client()
    for answer in (
        anonymous.get("/login"),  # a page
        anonymous.get("/static/js/hmi.js"),  # static files
        anonymous.get("/static/nothing.css"),  # a 404 from them
        anonymous.get("/no/such/page"),  # the error page
        anonymous.get("/", follow_redirects=False),  # a redirect
        anonymous.get("/api/status"),  # the API, refused: 401
        anonymous.get("/events"),  # the event stream (signed out: one event)
        anonymous.get("/healthz"),
        anonymous.get("/openapi.json"),  # off by default: 404 (test_api_docs.py)
    ):
        assert_secured(answer)

    client, token = engineer(station)
    for answer in (
        client.get("/station/fragments/status"),  # a fragment
        client.post("/model/validate", data={"csrf_token": token, "text": "x"}, headers=HX),
        client.get("/model", params={"version": "x"}),  # 422
        client.post("/station/restart/enter", data={"reason": "x"}),  # 403: no CSRF token
    ):
        assert_secured(answer)


def test_no_answer_with_station_data_is_kept_by_a_browser_or_a_proxy(
    station: RunningStation,
) -> None:
    """`Cache-Control: no-store` on every answer but the static files: after sign-out the
    back button of a shared terminal shows nothing of the station."""
    anonymous = station.client()
    client, token = engineer(station)
    api = {"authorization": f"Bearer {station.token(client, 'engineer')}"}
    answers = (
        anonymous.get("/login"),
        anonymous.get("/no/such/page"),
        anonymous.get("/api/status"),
        client.get("/station"),
        client.get("/station/fragments/status"),
        client.get("/model"),
        client.get("/station/timeline"),
        client.post("/model/validate", data={"csrf_token": token, "text": "x"}, headers=HX),
        client.get("/api/station", headers=api),
        client.get("/healthz"),
    )
    for answer in answers:
        where = f"{answer.request.method} {answer.request.url} ({answer.status_code})"
        assert answer.headers.get("cache-control") == "no-store", where
    script = anonymous.get("/static/js/hmi.js")
    assert script.status_code == 200 and "no-store" not in script.headers.get("cache-control", "")
    icon = anonymous.get("/favicon.ico")
    assert icon.headers.get("cache-control") == "public, max-age=86400"


def test_an_unexpected_error_still_carries_the_security_headers() -> None:
    async def broken(scope: Scope, receive: Receive, send: Send) -> None:
        raise RuntimeError("a bug")

    client = TestClient(SecurityHeaders(broken), raise_server_exceptions=False)
    answer = client.get("/anything")
    assert answer.status_code == 500 and answer.text == "Internal Server Error"
    assert_secured(answer)


def test_templates_have_no_inline_script_style_or_handler() -> None:
    """What the policy would block: the pages must not need it."""
    import re

    for template in (ROOT / "templates").glob("*.html"):
        html = re.sub(r"\{#.*?#\}", "", template.read_text(), flags=re.S)  # comments
        for pattern in (
            r"<script(?![^>]*\bsrc=)[^>]*>",  # inline script
            r"<style\b",
            r"\sstyle=",
            r"\shx-on[:-]",
            r"\son[a-z]+=",  # onclick=...
            r"js:",  # hx-vals='js:...' (eval)
            r"javascript:",
        ):
            assert not re.search(pattern, html), f"{template.name}: {pattern}"


def until(page: Any, condition: Callable[[], bool], seconds: float = 10) -> None:
    """Wait in Playwright's own loop: its events (page.on) are not delivered during sleep."""
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, f"not reached within {seconds} s"
        page.wait_for_timeout(50)


@pytest.fixture
def desktop(browser: Any) -> Iterator[Any]:
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = context.new_page()
    page.set_default_timeout(20_000)
    page.on("dialog", lambda dialog: dialog.accept())
    yield page
    context.close()


def test_the_pages_live_within_their_policy_in_a_browser(
    served: RunningStation, desktop: Any
) -> None:
    from playwright.sync_api import expect

    page = desktop
    violations: list[str] = []
    page.on(
        "console",
        lambda m: violations.append(m.text) if "Content Security Policy" in m.text else None,
    )
    page.expose_function("reportViolation", lambda text: violations.append(text))
    page.add_init_script(
        """document.addEventListener("securitypolicyviolation", (e) => window.reportViolation(
             `${e.violatedDirective} ${e.blockedURI} ${e.sourceFile}:${e.lineNumber}`));"""
    )
    requests: list[str] = []
    page.on("request", lambda request: requests.append(request.url))

    page.goto(served.url + "/login")
    page.locator("form[action='/login']").wait_for()
    sign_in(page, served, "admin")
    for path, ready in (
        ("/", "#tasks"),
        ("/alarms", "#alarms"),
        ("/model", "#model-text"),
        ("/simulation", "main h1"),
        ("/audit", ".audit-filter"),
        ("/users", "main h1"),
        ("/station/details", "#restart-reason"),
    ):
        page.goto(served.url + path)
        page.locator(ready).first.wait_for()
        page.wait_for_selector("#conn[data-state='live']")  # htmx and its SSE extension run
    assert not served.live.view.state.restart_mode

    # the station page: the form's answer swaps in the mode and its way out (no hx-on handler)
    page.fill("#restart-reason", "checking the policy")
    with page.expect_response(lambda r: r.url.endswith("/station/restart/enter")) as answer:
        page.get_by_role("button", name="Enter restart mode").click()
    assert answer.value.ok
    served.wait(lambda: served.live.view.state.restart_mode, 10)
    expect(page.get_by_role("button", name="Leave restart mode").first).to_be_visible()
    expect(page.locator("#restart-reason")).to_have_count(0)  # not offered again while in it

    # ... and the live parts send the digest they show (was a js: hx-vals): none on the first
    # fetch (the page's own copy has none), the fetched one's on the next change
    parts = tuple(f"{served.url}/station/fragments/{p}?seen=" for p in ("plans", "variables"))

    def digests() -> list[str]:  # sent by the live parts the form's answer does not replace
        return [url[url.index("seen=") + 5 :] for url in requests if url.startswith(parts)]

    until(page, lambda: "" in digests())
    served.live.act(LeaveRestart(user="admin")).result(10)
    until(page, lambda: any(digests()))
    screenshot(page, "security-station-restart.png")
    assert violations == []


# ---- 4. the redirect after a form ----------------------------------------------------------------


REFERERS = (
    ("https://evil.example/x", "/"),
    ("http://evil.example/alarms", "/"),
    ("http://127.0.0.1:8080/alarms", "/"),  # another port is another site
    ("https://127.0.0.1/alarms", "/"),  # and another scheme
    ("http://127.0.0.1//evil.example/x", "/"),  # "//evil.example/x" would leave
    ("http://127.0.0.1/\\evil.example/x", "/"),  # browsers read "/\\" as "//"
    ("http://127.0.0.1:x/alarms", "/"),
    ("not a url", "/"),
    ("", "/"),
    ("http://127.0.0.1/alarms?shown=all", "/alarms?shown=all"),
    ("http://127.0.0.1:80/alarms", "/alarms"),  # the default port, spelled out
)


@pytest.mark.parametrize(("referer", "expected"), REFERERS)
def test_the_way_back_is_a_path_of_this_station(referer: str, expected: str) -> None:
    from starlette.requests import Request

    from app.web.pages import same_origin_path

    headers = [(b"host", b"127.0.0.1")] + ([(b"referer", referer.encode())] if referer else [])
    scope = {"type": "http", "scheme": "http", "server": ("127.0.0.1", 80), "path": "/tasks/done"}
    request = Request({**scope, "method": "POST", "headers": headers, "query_string": b""})
    assert same_origin_path(request) == expected


def test_a_form_post_from_another_site_is_sent_back_to_the_station(
    station: RunningStation,
) -> None:
    from planner.runner import StartIntention

    client = station.client()
    token = station.login(client, "operator")
    station.live.act(StartIntention(user="engineer", name="assemble_engine")).result(10)
    station.wait(lambda: station.live.view.state.values["operator.card"] != "idle", 60)
    card = station.live.view.state.values["operator.card"]
    answer = client.post(
        "/tasks/done",
        data={"csrf_token": token, "card": card},
        headers={"referer": "https://evil.example/x"},
        follow_redirects=False,
    )
    assert answer.status_code == 303, answer.text
    assert answer.headers["location"] == "/"


# ---- 5. connections that never finish their request ----------------------------------------------

LIMIT = 1.0  # the head timeout the tests serve with (10 s in `sp serve`)
# closed by the time-out, not by keep-alive's 5 s, with room for a busy machine's late timer
CLOSED_BY = LIMIT + 3.0


def closed_after(sock: socket.socket, send: Callable[[], None] = lambda: None) -> float:
    """Seconds until the server closes `sock` (reading and dropping what it sends), calling
    `send` between reads."""
    started = time.monotonic()
    sock.settimeout(0.2)
    while time.monotonic() - started < 10 * LIMIT + 5:
        try:
            send()
            if sock.recv(65536) == b"":
                return time.monotonic() - started
        except TimeoutError:
            continue
        except OSError:  # reset, or a broken pipe on the next send
            return time.monotonic() - started
    raise AssertionError("the server kept the connection open")


def connect(url: str) -> socket.socket:
    host, port = url.removeprefix("http://").split(":")
    return socket.create_connection((host, int(port)), timeout=5)


def test_an_event_stream_ends_with_its_session(station: RunningStation) -> None:
    """Signed out elsewhere (another tab, or an admin ending the session), a page's event
    stream is told so and closed: it does not go on showing the station to nobody."""
    url = station.serve()
    with httpx.Client(base_url=url, timeout=30) as browser:
        sign_in_with_forms(browser, "auditor", first="auditor" not in station.changed)
        station.changed.add("auditor")
        token = form_token(browser.get("/alarms").text)
        with browser.stream("GET", "/events") as events:
            lines = events.iter_lines()
            assert next(lines).startswith("retry:")
            with httpx.Client(base_url=url, cookies=browser.cookies) as other_tab:
                out = other_tab.post("/logout", data={"csrf_token": token})
                assert out.status_code in (200, 303), out.text
            rest = list(lines)  # the stream ends by itself (else httpx's 30 s time-out)
        assert "event: signed-out" in rest, rest[-6:]
        last = rest.index("event: signed-out")
        assert [line for line in rest[last:] if line] == ["event: signed-out", "data: /login"]


def test_a_body_that_never_arrives_does_not_hold_the_connection(
    station: RunningStation,
) -> None:
    url = station.serve(head_timeout=10.0, body_timeout=LIMIT)
    head = (
        b"POST /login HTTP/1.1\r\nHost: x\r\nContent-Type: application/x-www-form-urlencoded"
        b"\r\nContent-Length: 2000\r\n\r\n"
    )
    with connect(url) as stalled:
        stalled.sendall(head + b"name=a")
        assert closed_after(stalled) < CLOSED_BY
    with connect(url) as trickle:  # a byte at a time does not extend it either
        trickle.sendall(head)
        body = iter(b"p" * 2000)
        assert closed_after(trickle, lambda: trickle.sendall(bytes([next(body)]))) < CLOSED_BY
    with httpx.Client(base_url=url) as client:  # a whole request is answered as ever
        assert client.post("/login", data={"name": "a", "password": "b"}).status_code == 403


def test_connections_that_do_not_finish_a_request_head_are_closed(
    station: RunningStation,
) -> None:
    url = station.serve(head_timeout=LIMIT)
    with connect(url) as silent:
        assert LIMIT * 0.8 < closed_after(silent) < CLOSED_BY
    with connect(url) as half:
        half.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")
        assert closed_after(half) < CLOSED_BY
    with connect(url) as trickle:  # a byte at a time does not extend the deadline
        header = iter(b"GET / HTTP/1.1\r\nHost: x\r\nX-Slow: " + b"y" * 1000)
        assert closed_after(trickle, lambda: trickle.sendall(bytes([next(header)]))) < CLOSED_BY
    for then in (b"GET /healthz HTTP/1.1\r\nHost: x\r\n", b""):  # after a response too
        with connect(url) as kept:
            kept.sendall(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
            assert b"200 OK" in kept.recv(65536)
            kept.sendall(then)
            assert closed_after(kept) < CLOSED_BY

    # a request whose head is in is not timed: its body may take longer
    with connect(url) as slow:
        slow.sendall(
            b"POST /login HTTP/1.1\r\nHost: x\r\nContent-Type: application/x-www-form-urlencoded"
            b"\r\nContent-Length: 20\r\n\r\n"
        )
        time.sleep(LIMIT + 0.5)
        slow.sendall(b"name=a&password=bbbb")
        assert slow.recv(65536).startswith(b"HTTP/1.1 ")
    with httpx.Client(base_url=url) as client:  # and ordinary requests work as ever
        assert client.get("/healthz").status_code == 200
        time.sleep(LIMIT / 2)
        assert client.get("/login").status_code == 200

    # the event stream lives on past the limit, once its head is in
    with httpx.Client(base_url=url, timeout=10) as browser:
        sign_in_with_forms(browser, "engineer", first=True)
        station.changed.add("engineer")
        token = form_token(browser.get("/station").text)
        with browser.stream("GET", "/events") as events:
            lines = events.iter_lines()
            assert next(lines).startswith("retry:") and next(lines) == "event: station"
            time.sleep(2 * LIMIT)
            entered = browser.post(
                "/station/restart/enter",
                data={"csrf_token": token, "reason": "stream"},
                headers=HX,
            )
            assert entered.status_code == 200, entered.text
            for line in lines:  # the first event's data, then the change's (or a time-out)
                if line == "event: station":
                    break
            else:
                raise AssertionError("the event stream ended")


@contextlib.contextmanager
def serving(app: Any) -> Iterator[str]:
    """`app` served as `sp serve` serves the station, on an ephemeral port."""
    port = free_port()
    server = uvicorn.Server(http_server.config(app, "127.0.0.1", port))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while not server.started:
        assert time.monotonic() < deadline, "the server did not start"
        time.sleep(0.02)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(10)


def test_forwarded_for_does_not_change_the_client_address() -> None:
    """uvicorn trusted X-Forwarded-For from 127.0.0.1: any local client could pick its
    address, one per try past the sign-in throttle."""

    async def client_address(scope: Scope, receive: Receive, send: Send) -> None:
        host = (scope.get("client") or ("none",))[0]
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": f"{host} {scope['scheme']}".encode()})

    with serving(client_address) as url:
        headers = {"x-forwarded-for": "10.9.9.9", "x-forwarded-proto": "https"}
        assert httpx.get(url, headers=headers).text == "127.0.0.1 http"
