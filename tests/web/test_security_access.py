"""Who may use which route: the permission table by every page and API route (issue 15).

Both tables are written out here, independently of app/people/auth.py, so that a slip there (a
permission given to the wrong role) or in a route (the wrong `Requires(...)`, a check
forgotten) fails a test.  Every route the app serves must have a row in `ROUTES`: a new
route without one fails `test_every_route_has_an_expected_access`, so none escapes.

Each row says what a caller may send without changing the station: names that do not
exist, a password too short, an empty model, so that a caller who may use the route is
refused after the permission check (404, 409, 422, with the handler's own message, which
`says` checks; a page's form is answered 303 to its page, which says it) and one who may
not gets the permission's 403.  The API is called with the
session cookie and with a bearer token.  Every unsafe request of a session must also carry
its CSRF token.  One station serves the whole module; only sign-outs use clients of their
own.
"""

from __future__ import annotations

import asyncio
import re
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient
from starlette.routing import Mount

from app.people.auth import PERMISSIONS, ROLES, Permission
from tests.support.stations import RunningStation, form_token, new_password, start_station

TASKS, ALARMS, ACKNOWLEDGE, STATION = "tasks", "alarms", "acknowledge", "station"
CONTROL, MODEL, ACTIVATE, SIMULATE = "control", "model", "activate", "simulate"
AUDIT, USERS = "audit", "users"
PUBLIC, SIGNED_IN = "public", "signed in"  # anyone at all; anyone signed in

# the intended roles (README.md, the demo users' table and "Users and security")
OPERATOR = frozenset({TASKS, ALARMS, ACKNOWLEDGE})
ENGINEER = OPERATOR | {STATION, CONTROL, MODEL, ACTIVATE, SIMULATE, AUDIT}
EXPECTED_PERMISSIONS: dict[str, frozenset[str]] = {
    "operator": OPERATOR,
    "engineer": ENGINEER,
    "auditor": frozenset({ALARMS, AUDIT}),
    "admin": ENGINEER | {USERS},
}
REFUSAL = "role"  # the permission check's 403: "Your role (auditor) cannot …" (app.web.deps)


@dataclass(frozen=True)
class Route:
    """One route, what admits a caller to it, and a request to it that changes nothing.

    `needs` is PUBLIC, SIGNED_IN, or the permissions any one of which admits.  A caller who
    is admitted gets `reached` with `says` in the body or the redirect's location.  Callers
    who are not get the permission's 403, unless `refused` says otherwise; anonymous
    callers get a redirect to /login (pages) or 401 (API), unless `anonymous` says
    otherwise."""

    method: str
    path: str  # the route's template, as the app declares it
    needs: str | frozenset[str]
    url: str = ""  # the request's URL: the path with its parameters filled
    form: dict[str, str] = field(default_factory=dict)
    json: dict[str, Any] | None = None
    reached: int = 200
    says: str = ""
    refused: tuple[int, str] | None = None
    anonymous: tuple[int, str] | None = None
    stream: bool = False  # server-sent events: read the first event only
    signs_out: bool = False  # ends the caller's session: sent from a client of its own

    @property
    def target(self) -> str:
        return self.url or self.path

    @property
    def api(self) -> bool:
        return self.path.startswith("/api")

    def admits(self, role: str) -> bool:
        if self.needs in (PUBLIC, SIGNED_IN):
            return True
        assert isinstance(self.needs, frozenset)
        return bool(self.needs & EXPECTED_PERMISSIONS[role])

    def __str__(self) -> str:
        return f"{self.method} {self.path}"


def needs(*permissions: str) -> frozenset[str]:
    return frozenset(permissions)


ABSENT_ALARM = {"key": "resource:r9"}
OWN_PASSWORD = "(the caller's password)"  # filled in when sent
NO_ALARM = "no alarm"
ROUTES = [
    # static files, health, signing in (the API's documentation is off by default:
    # test_api_docs.py)
    Route("GET", "/static/{path:path}", PUBLIC, url="/static/css/hmi.css"),
    Route("GET", "/healthz", PUBLIC, says='"ok":true'),
    Route("GET", "/favicon.ico", PUBLIC),  # the station's icon (app.web.routes.assets)
    Route("GET", "/login", PUBLIC, says='name="password"'),
    Route("POST", "/login", PUBLIC, form={"name": "nobody"}, reached=422, says="password"),
    Route(
        "POST",
        "/api/token",
        PUBLIC,
        json={"name": "nobody", "password": ""},
        reached=422,
        says="password",
    ),
    Route("POST", "/logout", SIGNED_IN, reached=303, says="/login", signs_out=True),
    Route("GET", "/password", SIGNED_IN, says='name="new_password"'),
    Route(
        "POST",
        "/password",
        SIGNED_IN,
        form={"current_password": OWN_PASSWORD, "new_password": "short", "repeat": "short"},
        reached=422,
        says="at least 10 characters",
    ),
    # one's own account: API tokens issued from this session, listed, revoked one by one
    Route("GET", "/account", SIGNED_IN, says="API tokens"),
    Route("POST", "/account/tokens", SIGNED_IN, reached=303, says="new API token is issued"),
    Route(
        "POST",
        "/account/tokens/revoke",
        SIGNED_IN,
        form={"token": "0" * 16},
        reached=303,
        says="no live API token",
    ),
    Route("GET", "/api/tokens", SIGNED_IN, says='"from_session"'),
    Route(
        "DELETE",
        "/api/tokens/{token_id}",
        SIGNED_IN,
        url="/api/tokens/" + "0" * 16,
        reached=404,
        says="no live API token",
    ),
    # the stream tells a page whose user is signed out to go to /login (EventSource
    # cannot follow a redirect usefully)
    Route(
        "GET",
        "/events",
        SIGNED_IN,
        says="event: station",
        anonymous=(200, "event: signed-out"),
        stream=True,
    ),
    # the operator's pages; the home page sends those without tasks to the audit log
    Route(
        "GET", "/", needs(TASKS), says='<h1 class="visually-hidden">Tasks', refused=(303, "/audit")
    ),
    Route("GET", "/fragments/tasks", needs(TASKS)),
    Route("GET", "/today", needs(TASKS), says="Done today", refused=(303, "/audit")),
    Route(
        "POST",
        "/tasks/done",
        needs(TASKS),
        form={"card": "no-such-card"},
        reached=303,
        says="no longer shown",
    ),
    Route(
        "POST",
        "/tasks/maintenance",
        needs(TASKS),
        form={"transition": "no.such_step"},
        reached=303,
        says="there is no maintenance transition",
    ),
    Route(
        "POST",
        "/tasks/approve",
        needs(TASKS),
        form={"step": "9999"},
        reached=303,
        says="no such recovery step",
    ),
    Route(
        "POST",
        "/tasks/approve-plan",
        needs(TASKS),
        form={"steps": "no.such_step"},
        reached=303,
        says="no recovery plan",
    ),
    Route("GET", "/alarms", needs(ALARMS), says="<h1"),
    Route("GET", "/fragments/alarms", needs(ALARMS)),
    Route(
        "POST",
        "/alarms/acknowledge",
        needs(ACKNOWLEDGE),
        form=ABSENT_ALARM,
        reached=303,
        says=NO_ALARM,
    ),
    Route(
        "POST",
        "/alarms/acknowledge-all",
        needs(ACKNOWLEDGE),
        form={"keys": ABSENT_ALARM["key"]},
        reached=303,
        says="nothing to acknowledge: no alarm",
    ),
    Route(
        "POST",
        "/alarms/shelve",
        needs(ACKNOWLEDGE),
        form={**ABSENT_ALARM, "minutes": "5"},
        reached=303,
        says=NO_ALARM,
    ),
    Route(
        "POST",
        "/alarms/unshelve",
        needs(ACKNOWLEDGE),
        form=ABSENT_ALARM,
        reached=303,
        says=NO_ALARM,
    ),
    # the engineer's pages: station view, controls, model editor, simulation panel
    Route("GET", "/station", needs(STATION), says='data-resource="r1"'),
    Route("GET", "/station/details", needs(STATION), says='data-variable="frame.state"'),
    Route("GET", "/station/fragments/overview", needs(STATION)),
    Route("GET", "/station/fragments/status", needs(STATION)),
    Route("GET", "/station/fragments/plans", needs(STATION)),
    Route("GET", "/station/fragments/variables", needs(STATION)),
    Route("GET", "/station/fragments/set-variable", needs(STATION)),
    Route("GET", "/station/timeline", needs(STATION), says="<h1>Timeline</h1>"),
    Route(
        "POST",
        "/station/intentions/start",
        needs(CONTROL),
        form={"name": "no_such_intention"},
        reached=303,
        says="there is no intention",
    ),
    Route(
        "POST",
        "/station/intentions/cancel",
        needs(CONTROL),
        form={"name": "no_such_intention"},
        reached=303,
        says="there is no intention",
    ),
    Route(
        "POST",
        "/station/restart/enter",
        needs(CONTROL),
        form={"reason": ""},
        reached=303,
        says="a reason for restart mode is required",
    ),
    # leaving restart mode outside it changes nothing (the runner accepts it)
    Route("POST", "/station/restart/leave", needs(CONTROL), reached=303, says="/station"),
    Route(
        "POST",
        "/station/operations/reset",
        needs(CONTROL),
        form={"name": "no_such_operation"},
        reached=303,
        says="there is no operation",
    ),
    Route(
        "POST",
        "/station/effects/reenable",
        needs(CONTROL),
        form={"name": "no.such_effect"},
        reached=303,
        says="there is no effect transition",
    ),
    Route(
        "POST",
        "/station/variables/set",
        needs(CONTROL),
        form={"variable": "no.such_variable", "value": "x", "reason": "probe"},
        reached=303,
        says="there is no estimated or decision variable",
    ),
    Route("GET", "/model", needs(MODEL), says='id="model-text"'),
    Route("POST", "/model/validate", needs(MODEL), form={"text": ""}, says="the model is empty"),
    Route(
        "POST",
        "/model/save",
        needs(MODEL),
        form={"text": ""},
        reached=422,
        says="the model is empty",
    ),
    Route("GET", "/model/diff", needs(MODEL), url="/model/diff?version=1"),
    Route(
        "POST",
        "/model/activate",
        needs(ACTIVATE),
        form={"version": "1"},
        reached=303,
        says="already active",
    ),
    Route("GET", "/model/fragments/station", needs(MODEL)),
    Route("GET", "/simulation", needs(SIMULATE), says="<h1"),
    Route("GET", "/simulation/fragments/status", needs(SIMULATE)),
    Route("GET", "/simulation/fragments/experiments", needs(SIMULATE)),
    Route(
        "POST",
        "/simulation/devices/put-back",
        needs(SIMULATE),
        form={},
        reached=303,
        says="only emulated devices",
    ),
    Route(
        "POST",
        "/simulation/experiment",
        needs(SIMULATE),
        form={"experiment": "no_such_experiment"},
        reached=303,
        says="there is no experiment",
    ),
    # the audit log, users
    Route("GET", "/audit", needs(AUDIT), says="<h1"),
    Route("GET", "/audit.csv", needs(AUDIT), says="subject"),
    Route("GET", "/users", needs(USERS), says='data-user="admin"'),
    Route(
        "POST",
        "/users",
        needs(USERS),
        form={"name": "probe", "role": "operator", "password": "short"},
        reached=303,
        says="at least 10 characters",
    ),
    Route(
        "POST",
        "/users/disable",
        needs(USERS),
        form={"name": "no-such-user", "disabled": "true"},
        reached=303,
        says="there is no user",
    ),
    Route(
        "POST",
        "/users/password",
        needs(USERS),
        form={"name": "no-such-user", "password": "long-enough-pw-1"},
        reached=303,
        says="there is no user",
    ),
    Route(
        "POST",
        "/users/role",
        needs(USERS),
        form={"name": "no-such-user", "role": "operator"},
        reached=303,
        says="there is no user",
    ),
    # the JSON API; the station's state is also what an operator's line system reads
    Route("GET", "/api/station", needs(STATION, TASKS), says='"intentions"'),
    Route("GET", "/api/tasks", needs(TASKS)),
    Route(
        "POST",
        "/api/cards/{card}/done",
        needs(TASKS),
        url="/api/cards/no-such-card/done",
        reached=409,
        says="no longer shown",
    ),
    Route(
        "POST",
        "/api/maintenance/{transition}/done",
        needs(TASKS),
        url="/api/maintenance/no.such_step/done",
        reached=404,
        says="there is no maintenance transition",
    ),
    Route(
        "POST",
        "/api/approvals/{step}",
        needs(TASKS),
        url="/api/approvals/9999",
        json={"decision": "approve"},
        reached=409,
        says="no such recovery step",
    ),
    Route(
        "POST",
        "/api/recovery-plan",
        needs(TASKS),
        json={"decision": "approve", "steps": ["no.such_step"]},
        reached=409,
        says="no recovery plan",
    ),
    Route(
        "POST",
        "/api/intentions/{name}/start",
        needs(CONTROL),
        url="/api/intentions/no_such_intention/start",
        reached=404,
        says="there is no intention",
    ),
    Route(
        "POST",
        "/api/intentions/{name}/cancel",
        needs(CONTROL),
        url="/api/intentions/no_such_intention/cancel",
        reached=404,
        says="there is no intention",
    ),
    Route(
        "POST",
        "/api/restart",
        needs(CONTROL),
        json={"mode": "enter", "reason": " "},
        reached=422,
        says="say why",
    ),
    Route(
        "POST",
        "/api/operations/{name}/reset",
        needs(CONTROL),
        url="/api/operations/no_such_operation/reset",
        reached=404,
        says="there is no operation",
    ),
    Route(
        "POST",
        "/api/estimated",
        needs(CONTROL),
        json={"variable": "no.such_variable", "value": "x", "reason": "probe"},
        reached=404,
        says="there is no estimated or decision variable",
    ),
    Route(
        "POST",
        "/api/effects/{name}/reenable",
        needs(CONTROL),
        url="/api/effects/no.such_effect/reenable",
        reached=404,
        says="there is no effect transition",
    ),
    Route("GET", "/api/alarms", needs(ALARMS)),
    Route(
        "POST",
        "/api/alarms/acknowledge",
        needs(ACKNOWLEDGE),
        json=ABSENT_ALARM,
        reached=404,
        says="there is no active or shelved alarm",
    ),
    Route(
        "POST",
        "/api/alarms/shelve",
        needs(ACKNOWLEDGE),
        json={**ABSENT_ALARM, "minutes": 5},
        reached=404,
        says="there is no active or shelved alarm",
    ),
    Route(
        "POST",
        "/api/alarms/unshelve",
        needs(ACKNOWLEDGE),
        json=ABSENT_ALARM,
        reached=404,
        says="there is no active or shelved alarm",
    ),
    Route("GET", "/api/models", needs(MODEL), says='"number":1'),
    Route("GET", "/api/models/{number}", needs(MODEL), url="/api/models/1", says='"text"'),
    Route(
        "POST",
        "/api/models",
        needs(MODEL),
        json={"text": "x"},
        reached=422,
        says="the model is not valid",
    ),
    Route(
        "POST",
        "/api/models/{number}/activate",
        needs(ACTIVATE),
        url="/api/models/1/activate",
        reached=409,
        says="already active",
    ),
    Route("GET", "/api/experiments", needs(SIMULATE), says='"id"'),
    Route(
        "POST",
        "/api/experiments/{experiment}/play",
        needs(SIMULATE),
        url="/api/experiments/no_such_experiment/play",
        reached=404,
        says="there is no experiment",
    ),
    Route("GET", "/api/audit", needs(AUDIT), says='"records"'),
]
BY_KEY = {(r.method, r.path): r for r in ROUTES}


# -- the callers ---------------------------------------------------------------------------------


@dataclass
class Caller:
    """A client with its session's CSRF token, and (for a role) a bearer token."""

    name: str  # a role, or "anonymous"
    client: TestClient
    csrf: str
    bearer: str = ""


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningStation]:
    running = start_station(Path(tmp_path_factory.mktemp("access")))
    yield running
    running.stop()


@pytest.fixture(scope="module")
def callers(station: RunningStation) -> dict[str, Caller]:
    """Each demo user signed in (first-login password changed) once; anonymous has a
    session too, with its CSRF token from the sign-in page."""
    found = {}
    for role in ROLES:
        client = station.client()
        csrf = station.login(client, role)
        found[role] = Caller(role, client, csrf, station.token(client, role))
    anonymous = station.client()
    found["anonymous"] = Caller("anonymous", anonymous, form_token(anonymous.get("/login").text))
    return found


def cookie_header(client: httpx.Client) -> str:
    return "; ".join(f"{name}={value}" for name, value in client.cookies.items())


def first_event(station: RunningStation, client: httpx.Client) -> tuple[int, str]:
    """The status and first chunk of the event stream, read straight from the ASGI app:
    the test client would wait for the end of a stream that never ends."""

    async def call() -> tuple[int, str]:
        read = asyncio.Event()
        asked = False
        status, chunks = 0, []

        async def receive() -> dict[str, Any]:
            nonlocal asked
            if not asked:
                asked = True
                return {"type": "http.request", "body": b"", "more_body": False}
            await read.wait()  # the client leaves once it has read the first event
            return {"type": "http.disconnect"}

        async def send(message: dict[str, Any]) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
            elif message["type"] == "http.response.body" and message.get("body"):
                chunks.append(message["body"])
                read.set()

        scope = {
            "type": "http",
            "asgi": {"version": "3.0"},
            "http_version": "1.1",
            "method": "GET",
            "scheme": "http",
            "path": "/events",
            "raw_path": b"/events",
            "query_string": b"",
            "root_path": "",
            "headers": [(b"host", b"127.0.0.1"), (b"cookie", cookie_header(client).encode())],
            "client": ("testclient", 50000),
            "server": ("127.0.0.1", 80),
        }
        await asyncio.wait_for(station.built.app(scope, receive, send), 10)
        return status, b"".join(chunks).decode()

    # in a thread of its own: a Playwright test earlier in the session leaves an event loop
    # running in this one, and asyncio.run refuses to start inside it
    with ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(asyncio.run, call()).result()


@dataclass(frozen=True)
class Answer:
    status: int
    text: str
    location: str = ""  # of a redirect

    def shows(self, text: str) -> bool:
        return text.lower() in f"{self.text}{self.location}".lower()

    def __str__(self) -> str:
        """The status and what the answer says: a page's alerts, the start of others."""
        alerts = re.findall(r'role="alert">([^<]*)<', self.text)
        said = " / ".join(dict.fromkeys(alerts)) if alerts else self.text[:200]
        return f"{self.status} {self.location} {said!r}"


def own(value: str, caller: Caller) -> str:
    return new_password(caller.name) if value == OWN_PASSWORD else value


def send(station: RunningStation, route: Route, caller: Caller, bearer: bool) -> Answer:
    """`route`'s request as `caller` sends it: with the session cookie (and its CSRF token
    on a POST), or with the bearer token only."""
    if route.stream:
        return Answer(*first_event(station, caller.client))
    client = caller.client
    headers = {}
    if bearer:
        client = station.client()  # no cookie: the token alone must admit
        headers["Authorization"] = f"Bearer {caller.bearer}"
    elif route.signs_out and caller.name != "anonymous":
        client = station.client()
        headers["X-CSRF-Token"] = station.login(client, caller.name)
    elif route.method in ("POST", "DELETE"):
        headers["X-CSRF-Token"] = caller.csrf
    if route.method == "GET":
        response = client.get(route.target, headers=headers, follow_redirects=False)
    elif route.method == "DELETE":
        response = client.delete(route.target, headers=headers, follow_redirects=False)
    elif route.api:
        response = client.post(
            route.target, json=route.json, headers=headers, follow_redirects=False
        )
    else:
        form = {k: own(v, caller) for k, v in route.form.items()}
        form["csrf_token"] = headers.pop("X-CSRF-Token", "")
        response = client.post(route.target, data=form, headers=headers, follow_redirects=False)
        location = response.headers.get("location", "")
        if response.status_code == 303 and not location.startswith("/login"):
            # a form's outcome, refused or done, is shown by the page it redirects to
            shown = client.get(location, headers=headers, follow_redirects=False)
            return Answer(303, shown.text, location)
    return Answer(response.status_code, response.text, response.headers.get("location", ""))


# -- the tests -----------------------------------------------------------------------------------


def route_keys(station: RunningStation) -> set[tuple[str, str]]:
    """(method, path template) of every route the app serves, included routers and
    mounts too (a mount as GET of its paths)."""
    keys = set()
    for route in iter_route_contexts(station.built.app.routes):
        if isinstance(route.original_route, Mount):
            keys.add(("GET", f"{route.path}/{{path:path}}"))
            continue
        methods = set(route.methods or ())
        if "GET" in methods:
            methods.discard("HEAD")
        keys |= {(method, str(route.path)) for method in methods}
    return keys


def test_every_route_has_an_expected_access(station: RunningStation) -> None:
    served = route_keys(station)
    assert len(served) > 60, sorted(served)
    unlisted = sorted(served - BY_KEY.keys())
    assert not unlisted, f"routes without a row in ROUTES (say who may use them): {unlisted}"
    gone = sorted(BY_KEY.keys() - served)
    assert not gone, f"rows in ROUTES for routes the app does not serve: {gone}"
    assert len(BY_KEY) == len(ROUTES), "a route has two rows"
    assert not [r for r in ROUTES if r.reached in (401, 403)], "reached: past the checks"


def test_the_roles_hold_the_intended_permissions() -> None:
    assert set(ROLES) == set(EXPECTED_PERMISSIONS)
    assert {p.value for p in Permission} == set().union(*EXPECTED_PERMISSIONS.values())
    held = {role.value: {p.value for p in ps} for role, ps in PERMISSIONS.items()}
    assert held == EXPECTED_PERMISSIONS


CALLERS = [*EXPECTED_PERMISSIONS, "anonymous"]
CASES = [
    pytest.param(name, route, bearer, id=f"{name}{'-bearer' if bearer else ''}-{route}")
    for route in ROUTES
    for name in CALLERS
    for bearer in ((False, True) if route.api and name != "anonymous" else (False,))
]


def expected(route: Route, name: str) -> tuple[int, str]:
    """The status `name` gets from `route`, and a text its body or redirect shows."""
    if name == "anonymous" and route.needs != PUBLIC:
        if route.anonymous is not None:
            return route.anonymous
        return (401, "sign in first") if route.api else (303, "/login")
    if name == "anonymous" or route.admits(name):
        # the handler ran, and refused the harmless arguments with its own message
        return route.reached, route.says
    return route.refused or (403, f"{REFUSAL} ({name}) cannot")


@pytest.mark.parametrize(("name", "route", "bearer"), CASES)
def test_a_route_admits_exactly_whom_its_permissions_admit(
    station: RunningStation, callers: dict[str, Caller], name: str, route: Route, bearer: bool
) -> None:
    answer = send(station, route, callers[name], bearer)
    status, says = expected(route, name)
    shown = f"{route} as {name}{' (bearer)' if bearer else ''}: {answer}"
    assert answer.status < 500, shown
    assert (answer.status, answer.shows(says)) == (status, True), (
        f"{shown}; expected {status} {says!r}"
    )


UNSAFE = [r for r in ROUTES if r.method in ("POST", "DELETE") and r.needs != PUBLIC]


@pytest.mark.parametrize("route", UNSAFE, ids=str)
def test_a_session_without_the_csrf_token_is_refused(
    station: RunningStation, callers: dict[str, Caller], route: Route
) -> None:
    """A cookie session's unsafe request without its CSRF token does nothing (a bearer
    request needs none: no cookie that another site's page could ride on)."""
    client = station.client() if route.signs_out else callers["admin"].client
    if route.signs_out:
        station.login(client, "admin")
    if route.method == "DELETE":
        response = client.delete(route.target, follow_redirects=False)
    elif route.api:
        response = client.post(route.target, json=route.json, follow_redirects=False)
    else:
        response = client.post(route.target, data=route.form, follow_redirects=False)
    answer = Answer(response.status_code, response.text, response.headers.get("location", ""))
    if route.signs_out:  # refused quietly: back to the sign-in page, still signed in
        assert client.get("/alarms", follow_redirects=False).status_code == 200, answer
    else:
        assert (answer.status, answer.shows("expired")) == (403, True), f"{route}: {answer}"
