"""Fuzz the HTML form routes and the pages' query strings (hypothesis): no input may cause
a server error, and the server keeps answering (issue 15).

tests/web/test_api_fuzz.py fuzzes the JSON API from its OpenAPI schema; the pages are not in
it, so their routes are found here by introspection: every POST outside /api, with the
form fields its handler declares (`Form(...)` parameters, with their `max_length` and
bounds), and every GET page with its query parameters.  Each gets bodies and query strings
made of its own field names with random and nasty text: unicode, control characters, empty,
at and beyond the field's length limit, numbers as text (huge, negative, not a number),
expressions nested very deep, a model text with such an expression in a guard; fields
missing, repeated and extra; url-encoded, multipart or raw bytes; with and without htmx.

The caller is the admin (every permission), signed in on a station of the route's group
(`GROUPS`), with the session's CSRF token in every form.  What would make later examples
meaningless is neutralised: a sign-out is followed by a sign-in, a changed admin password is
remembered, sign-in attempts come from addresses of their own and never name the admin (so
the throttle never locks the admin out).  Server errors are collected, not raised at the
first one, so one run reports every route that fails (with its smallest failing requests).
"""

from __future__ import annotations

import re
import sys
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import astuple, dataclass, field
from itertools import count

import pytest
from annotated_types import Ge, Gt, Le, Lt, MaxLen
from fastapi.routing import APIRoute, iter_route_contexts
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from app.people.auth import ROLES
from tests.support.stations import MODEL, RunningStation, form_token, new_password

EXAMPLES = 20  # random examples per route, besides the explicit nasty ones
FEWER = {"/logout": 8}  # each signs the admin out, and in again (argon2: a third of a second)
HUGE = "99999999999999999999"  # past every integer column and C long
DEEP = "(" * 300 + "a" + ")" * 300
NASTY = [
    "",
    " ",
    HUGE,
    "-" + HUGE,
    "-1",
    "0",
    "1e309",
    "nan",
    "\x00",
    "\r\n\t\x1b[0m",
    "\u202e\ufeff\U0001f600",
    DEEP,
    "<script>x</script>",
]
DATES = [
    "2025-05-01T14:30",
    "2025-05-01T16:30:00+02:00",
    "9999-12-31T23:59:59-14:00",
    "0001-01-01T00:00+14:00",
    "1970-01-01T00:00:00Z",
    "2025-13-45T99:99",
]
# routes by path prefix; each group gets a station of its own (first match; else "pages")
GROUPS = {
    "sign-in": ("/login", "/logout"),
    "tasks": ("/password", "/tasks", "/alarms"),
    "station": ("/station", "/simulation"),
    "model": ("/model",),
    "users": ("/users",),
}
PAGES = "pages"  # the GET pages' query strings, and any form route no group claims
NOT_FUZZED = ("/events",)  # an endless stream (its access is in test_security_access.py)
# query parameters the pages read themselves (request.query_params), not as arguments
UNDECLARED = ("seen",)  # a live fragment's digest (app.web.pages.live_fragment)
BOUNDS = (Ge, Gt, Le, Lt)  # annotated_types' bounds; each holds its one number
RECURSION_LIMIT = sys.getrecursionlimit()  # the server's, as it runs outside the tests


# -- the routes, as the app declares them --------------------------------------------------------


@dataclass(frozen=True)
class Field:
    name: str  # as sent (the alias)
    max_length: int | None
    bounds: tuple[float, ...]  # ge, le, gt, lt given, for values around them
    in_query: bool = False  # a URL is at most 64 kB (httpx), and 8 kB for most servers


@dataclass(frozen=True)
class Fuzzed:
    method: str
    path: str
    fields: tuple[Field, ...]

    @property
    def group(self) -> str:
        if self.method == "GET":
            return PAGES
        for group, prefixes in GROUPS.items():
            if self.path.startswith(prefixes):
                return group
        return PAGES

    def __str__(self) -> str:
        return f"{self.method} {self.path}"


def declared(route: APIRoute, query: bool) -> tuple[Field, ...]:
    """The route's form fields (or query parameters), its dependencies' included."""
    found: dict[str, Field] = {}
    pending = [route.dependant]
    while pending:
        dependant = pending.pop()
        pending.extend(dependant.dependencies)
        for param in dependant.query_params if query else dependant.body_params:
            limits = param.field_info.metadata
            longest = next((m.max_length for m in limits if isinstance(m, MaxLen)), None)
            bounds = tuple(float(astuple(m)[0]) for m in limits if isinstance(m, BOUNDS))
            found[param.alias] = Field(param.alias, longest, bounds, query)
    return tuple(found[name] for name in sorted(found))


def fuzzed_routes(station: RunningStation) -> list[Fuzzed]:
    """Every POST outside /api with its form fields, and every GET page with its query
    parameters (FastAPI's own pages and static files aside)."""
    routes = []
    for context in iter_route_contexts(station.built.app.routes):
        route, path = context.original_route, str(context.path)
        if not isinstance(route, APIRoute) or path.startswith("/api") or path in NOT_FUZZED:
            continue
        for method in sorted(set(route.methods) & {"GET", "POST"}):
            fields = declared(route, query=method == "GET")
            if method == "GET":
                fields += tuple(Field(name, None, (), True) for name in UNDECLARED)
            routes.append(Fuzzed(method, path, fields))
    return routes


# -- what is sent --------------------------------------------------------------------------------


def known_values(station: RunningStation) -> dict[str, list[str]]:
    """Values that mean something to the station, per field name (or "path name" where
    routes differ), to get past the first checks into the handlers: names of the model,
    users, versions, alarm keys; the first is the plausible one."""
    model = station.live.model.station
    transitions = model.model.transitions
    text = MODEL.read_text(encoding="utf-8")
    guard = 'guard: "enabled && r1.pos == scan'
    assert guard in text
    deep_guard = text.replace(guard, guard.replace("r1.pos", DEEP), 1)
    small = (
        "variables:\n  - {name: x, domain: bool, initial: false}\n"
        'transitions:\n  - {name: t, guard: "%s", actions: ["x := true"]}\n'
    )
    names = [i.name for i in model.intentions] + [o.name for o in model.operations]
    names += [t.name for t in transitions if t.kind.value == "effect"][:3]
    return {
        "name": [*names, *ROLES, "probe_user"],
        "card": ["place_bp1", "place_bp4"],
        "transition": [t.name for t in transitions if t.kind.value == "maintenance"][:3],
        "step": ["0", "1", "10000", "10001"],
        "decision": ["approve", "reject"],
        "key": ["resource:r1", "resource:r2"],
        "minutes": ["5", "0.0001", "480", "481"],
        "variable": ["frame.state", "bp1.state"],
        "value": ["true", "false", "placed", "empty"],
        "role": list(ROLES),
        "version": ["1", "2", "3"],
        "experiment": sorted(station.built.server.experiments)[:2],
        **{
            f"{path} text": [
                small % "x",
                text,
                deep_guard,
                small % DEEP,
                small % ("!" * 3000 + "x"),
            ]
            for path in ("/model/validate", "/model/save")
        },
        "text": ["signed in", "bolt"],
        "note": ["checked by hand"],
        "reason": ["checked by hand"],
        "resource": ["r1", "r2"],
        "station": [station.live.name],
        "disabled": ["true", "false", "on"],
        "next": ["/", "//evil.example/", "https://evil.example/", "/station"],
        "since": DATES,
        "until": DATES,
        "user": ["admin", "engineer"],
        "kind": ["login", "model", "user"],
        "page": ["1", "2", HUGE],
        "password": ["long-enough-pw-1", new_password("admin")],
        "current_password": [new_password("admin")],
        "new_password": ["long-enough-pw-1"],
        "repeat": ["long-enough-pw-1"],
        "seen": ["0000000000000000"],
    }


def lengths(field: Field) -> list[int]:
    """Lengths at and beyond the field's limit (or merely long when it has none)."""
    longest, most = field.max_length, 6_000 if field.in_query else 4_000_000
    if longest is None:
        return [1_000, most if field.in_query else 100_000]
    return [n for n in (longest, longest + 1, longest * 4) if n <= most]


def long_texts(field: Field) -> list[str]:
    """Texts at those lengths; past 1,000 characters only ASCII, to keep bodies small."""
    return [c * n for n in lengths(field) for c in ("aé(\x00😀" if n <= 1_000 else "a(")]


def around(field: Field) -> list[str]:
    return [f"{b + d:g}" for b in field.bounds for d in (-1, 0, 1)]


def values(field: Field, known: list[str]) -> st.SearchStrategy[str]:
    return st.one_of(
        st.sampled_from([*NASTY, *known, *around(field)]),
        st.text(max_size=40),
        st.integers().map(str),
        st.floats().map(str),
        st.sampled_from(long_texts(field)),
    )


@dataclass(frozen=True)
class Probe:
    """One request's fields (each one value, or several: a repeated field; missing when
    absent), extra fields, htmx or not, and how the form is encoded."""

    fields: dict[str, str | list[str]]
    extra: dict[str, str] = field(default_factory=dict)
    htmx: bool = False
    encoding: str = "urlencoded"  # or "multipart", or "raw": `raw` is the whole body
    raw: bytes = b""

    def size(self) -> int:
        texts = [*self.fields.values(), *self.extra.values()]
        return len(self.raw) + sum(len(t) if isinstance(t, str) else len("".join(t)) for t in texts)

    def shown(self) -> str:
        def short(value: object) -> str:
            text = repr(value)
            return text if len(text) <= 80 else f"{text[:60]}...({len(text)} chars)"

        parts = {**self.fields, **{f"+{k}": v for k, v in self.extra.items()}}
        described = ", ".join(f"{k}={short(v)}" for k, v in parts.items())
        mode = f" {self.encoding}" + (" htmx" if self.htmx else "")
        return f"{{{described}}}{mode}" + (f" raw={short(self.raw)}" if self.raw else "")


def fuzzable(route: Fuzzed) -> list[Field]:
    return [f for f in route.fields if f.name != "csrf_token"]  # always the valid one


def known_for(known: dict[str, list[str]], route: Fuzzed, field: Field) -> list[str]:
    return known.get(f"{route.path} {field.name}") or known.get(field.name, [])


@st.composite
def probes(draw: st.DrawFn, route: Fuzzed, known: dict[str, list[str]]) -> Probe:
    fields: dict[str, str | list[str]] = {}
    for f in fuzzable(route):
        how = draw(st.sampled_from(["one", "one", "one", "missing", "repeated"]))
        if how == "one":
            fields[f.name] = draw(values(f, known_for(known, route, f)))
        elif how == "repeated":
            fields[f.name] = draw(st.lists(values(f, []), min_size=2, max_size=3))
    extra = draw(
        st.dictionaries(st.text(min_size=1, max_size=12), st.text(max_size=20), max_size=2)
    )
    encodings = ["urlencoded", "multipart", "raw"] if route.method == "POST" else ["urlencoded"]
    encoding = draw(st.sampled_from(encodings))
    raw = draw(st.binary(max_size=200)) if encoding == "raw" else b""
    return Probe(fields, extra, draw(st.booleans()), encoding, raw)


def nasty_probes(route: Fuzzed, known: dict[str, list[str]]) -> list[Probe]:
    """Each field at each nasty value and each known one, the others at a plausible value
    (so that the handler runs); each field missing; every field just past its limit."""
    fields = fuzzable(route)
    plausible = {f.name: (known_for(known, route, f) or ["probe"])[0] for f in fields}
    chosen = [
        Probe({**plausible, f.name: value})
        for f in fields
        for value in dict.fromkeys([*NASTY, *known_for(known, route, f), *around(f)])
    ]
    chosen += [Probe({k: v for k, v in plausible.items() if k != f.name}) for f in fields]
    chosen.append(Probe({f.name: "a" * ((f.max_length or 999) + 1) for f in fields}))
    return chosen


# -- sending, and keeping the admin signed in ----------------------------------------------------


@dataclass
class Admin:
    """The admin's session on the group's station."""

    station: RunningStation
    client: TestClient
    csrf: str
    password: str = field(default_factory=lambda: new_password("admin"))
    addresses: Iterator[int] = field(default_factory=count)

    def sign_in_again(self) -> None:
        page = self.client.get("/login")
        form = {"name": "admin", "password": self.password, "csrf_token": form_token(page.text)}
        signed = self.client.post("/login", data=form, follow_redirects=False)
        assert signed.status_code == 303, f"the admin cannot sign in again: {signed.text}"
        self.csrf = form_token(self.client.get("/alarms").text)


def client_of(station: RunningStation, address: str = "testclient") -> TestClient:
    """A client that sees a server error as its status (500), not as an exception."""
    return TestClient(
        station.built.app,
        base_url="http://127.0.0.1",
        raise_server_exceptions=False,
        client=(address, 50000),
    )


def send(admin: Admin, route: Fuzzed, probe: Probe) -> tuple[int, str]:
    """`probe` to `route` as the admin; the status and the redirect's location."""
    client, csrf = admin.client, admin.csrf
    fields = dict(probe.fields)
    if route.path == "/login" and route.method == "POST":
        # from an address of its own, never as the admin: failures are throttled per
        # address and per name, and the admin must be able to sign in again
        client = client_of(admin.station, f"10.0.0.{next(admin.addresses) % 250 + 1}")
        csrf = form_token(client.get("/login").text)
        fields = {k: v for k, v in fields.items() if k != "name" or not is_admin(v)}
    headers = {"HX-Request": "true"} if probe.htmx else {}
    if route.method == "GET":
        response = client.get(
            route.path, params={**probe.extra, **fields}, headers=headers, follow_redirects=False
        )
        return response.status_code, response.headers.get("location", "")
    form: dict[str, str | list[str]] = {**probe.extra, **fields, "csrf_token": csrf}
    if probe.encoding == "raw":
        headers["Content-Type"] = "application/x-www-form-urlencoded"
        headers["X-CSRF-Token"] = csrf
        response = client.post(
            route.path, content=probe.raw, headers=headers, follow_redirects=False
        )
    elif probe.encoding == "multipart":
        upload = {"attachment": ("a.txt", b"\x00\xff text", "text/plain")}
        response = client.post(
            route.path, data=form, files=upload, headers=headers, follow_redirects=False
        )
    else:
        response = client.post(route.path, data=form, headers=headers, follow_redirects=False)
    location = response.headers.get("location", "")
    if route.path == "/password" and response.status_code == 303 and location == "/":
        given = fields.get("new_password")
        admin.password = given if isinstance(given, str) else given[-1]
    return response.status_code, location


@contextmanager
def served_recursion_limit() -> Iterator[None]:
    """Hypothesis raises the interpreter's recursion limit while it runs an example (room
    for the test's own frames); the server shares the interpreter, and would then accept
    nesting that overflows its stack in production.  So requests go out under its limit."""
    raised = sys.getrecursionlimit()
    sys.setrecursionlimit(RECURSION_LIMIT)
    try:
        yield
    finally:
        sys.setrecursionlimit(raised)


def is_admin(value: str | list[str]) -> bool:
    return any(v.strip().lower() == "admin" for v in ([value] if isinstance(value, str) else value))


def still_signed_in(admin: Admin) -> None:
    """Sign the admin in again if the request ended the session (a sign-out)."""
    answer = admin.client.get("/fragments/alarms", follow_redirects=False)
    assert answer.status_code in (200, 303), f"the server answers {answer.status_code}"
    if answer.status_code == 303:
        admin.sign_in_again()


# -- the test ------------------------------------------------------------------------------------


@dataclass
class Failures:
    """Server errors per route; the three smallest failing requests of each are kept (one
    per set of field values: extra fields and encodings aside)."""

    found: dict[str, dict[str, tuple[int, int, str]]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)

    def add(self, route: Fuzzed, status: int, probe: Probe) -> None:
        key = str(route)
        self.counts[key] = self.counts.get(key, 0) + 1
        kept = self.found.setdefault(key, {})
        values = repr(sorted(probe.fields.items()))
        if values not in kept or probe.size() < kept[values][0]:
            kept[values] = (probe.size(), status, probe.shown())

    def report(self) -> str:
        lines = []
        for key, kept in sorted(self.found.items()):
            lines.append(f"{key}: {self.counts[key]} requests answered with a server error, e.g.")
            lines += [f"    {status} for {shown}" for _, status, shown in sorted(kept.values())[:3]]
        return "\n".join(lines)


def fuzz(
    admin: Admin, route: Fuzzed, known: dict[str, list[str]], failures: Failures
) -> Counter[int]:
    """Send the nasty and `EXAMPLES` random requests to `route`; how many got which status."""
    statuses: Counter[int] = Counter()

    @settings(
        max_examples=FEWER.get(route.path, EXAMPLES),
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(probe=probes(route, known))
    def run(probe: Probe) -> None:
        with served_recursion_limit():
            status, location = send(admin, route, probe)
        statuses[status] += 1
        if status >= 500:
            failures.add(route, status, probe)
        if route.path == "/logout" or location.startswith("/login"):
            still_signed_in(admin)

    for nasty in reversed(nasty_probes(route, known)):
        run = example(probe=nasty)(run)
    run()
    # once per route, not per request (half the requests): a stalled or dead server
    # fails the route's next request as well
    assert admin.client.get("/healthz").status_code == 200, f"{route}: the server stopped"
    return statuses


GROUP_NAMES = [*GROUPS, PAGES]


@pytest.mark.parametrize("group", GROUP_NAMES)
def test_no_form_or_query_string_gets_a_server_error(station: RunningStation, group: str) -> None:
    client = client_of(station)
    admin = Admin(station, client, station.login(client, "admin"))
    known = known_values(station)
    routes = [r for r in fuzzed_routes(station) if r.group == group]
    assert routes, f"no route in group {group}"
    failures = Failures()
    started = time.monotonic()
    statuses = {str(route): fuzz(admin, route, known, failures) for route in routes}
    sent = sum(sum(counted.values()) for counted in statuses.values())
    print(f"\nform fuzz, {group}: {sent} requests in {time.monotonic() - started:.1f} s")
    for route, counted in statuses.items():
        print(f"  {route}: {dict(sorted(counted.items()))}")
    # the station's loop still answers: a request it refuses (no such alarm), not a 503
    form = {"key": "no:such-alarm", "csrf_token": admin.csrf}
    answered = admin.client.post("/alarms/unshelve", data=form, follow_redirects=False)
    assert answered.status_code == 303  # refused: back to the page, which says why
    said = re.findall(r'role="alert">([^<]*)<', admin.client.get("/alarms").text)
    assert "no alarm no:such-alarm" in said, said
    if failures.found:
        pytest.fail(f"server errors:\n{failures.report()}", pytrace=False)


def test_every_form_route_is_fuzzed(station: RunningStation) -> None:
    """The POST routes outside /api are the forms of the pages; each declares its fields
    (a handler reading `await request.form()` itself would escape this fuzz)."""
    posts = [r for r in fuzzed_routes(station) if r.method == "POST"]
    assert len(posts) >= 20, [str(r) for r in posts]
    formless = {str(r) for r in posts if not r.fields}
    buttons = {"POST /station/restart/leave", "POST /account/tokens"}
    assert formless <= buttons | {"POST /simulation/devices/put-back"}, formless
    pages = [r for r in fuzzed_routes(station) if r.method == "GET"]
    assert {"/model", "/model/diff", "/audit", "/audit.csv"} <= {r.path for r in pages}
