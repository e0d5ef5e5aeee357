"""What each route declares it requires, read from the app itself (issue 26).

test_security_access.py sends each route's request as each role; but two permissions held by
the same roles (activation and model editing: engineer and admin) can be swapped on a route
and every answer stays the same.  Here each route's declared permission is read from its
dependencies (the `app.web.deps.Requires` instances it depends on) and compared with the
permission table of test_security_access.py, exactly: every route, and the routes that
declare none (public, or checked by the handler itself) listed by name.
"""

from __future__ import annotations

from collections.abc import Iterable
from types import SimpleNamespace
from typing import Any, cast

import pytest
from fastapi import FastAPI
from fastapi.routing import iter_route_contexts
from starlette.routing import Mount

from app.web.app import create_app
from app.web.deps import Requires
from app.web.server import Server
from tests.web.test_security_access import PUBLIC, ROUTES, SIGNED_IN

Key = tuple[str, str]
NOTHING = "declares no permission"

# routes whose permission the handler checks itself, on an optional caller: it sends those
# without it somewhere else instead of refusing them (/login, /audit)
CHECKED_BY_THE_HANDLER = {("GET", "/"), ("GET", "/today"), ("GET", "/alarms")}
# routes for anyone, or for anyone signed in (the handler reads the session), by name
DECLARE_NOTHING = {
    ("GET", "/static/{path:path}"),
    ("GET", "/healthz"),
    ("GET", "/favicon.ico"),
    ("GET", "/login"),
    ("POST", "/login"),
    ("POST", "/api/token"),
    ("POST", "/logout"),
    ("GET", "/password"),
    ("POST", "/password"),
    ("GET", "/events"),
    *CHECKED_BY_THE_HANDLER,
}


def expected_declarations() -> dict[Key, frozenset[str] | str]:
    """From test_security_access.py's table: the permissions any one of which admits, or
    NOTHING for the routes listed above."""
    table: dict[Key, frozenset[str] | str] = {}
    for route in ROUTES:
        key = (route.method, route.path)
        if key in DECLARE_NOTHING:
            assert key in CHECKED_BY_THE_HANDLER or route.needs in (PUBLIC, SIGNED_IN), key
            table[key] = NOTHING
        elif route.needs == SIGNED_IN:  # a page of one's own: `Requires()`, no permission
            table[key] = frozenset({SIGNED_IN})
        else:
            assert isinstance(route.needs, frozenset), f"{key}: list it in DECLARE_NOTHING"
            table[key] = route.needs
    return table


def required(dependencies: Iterable[Any]) -> set[str]:
    """The permissions of every `Requires` among `dependencies` (FastAPI's `Dependant`s),
    followed down to the dependencies' own; SIGNED_IN for a `Requires` of none."""
    found: set[str] = set()
    for dependant in dependencies:
        if isinstance(dependant.call, Requires):
            found.update(str(p) for p in dependant.call.permissions or (SIGNED_IN,))
        found |= required(dependant.dependencies)
    return found


def declarations(app: FastAPI) -> dict[Key, frozenset[str] | str]:
    """(method, path template) of every route the app serves -> what it declares."""
    found: dict[Key, frozenset[str] | str] = {}
    for route in iter_route_contexts(app.routes):
        if isinstance(route.original_route, Mount):
            found[("GET", f"{route.path}/{{path:path}}")] = NOTHING
            continue
        dependant = getattr(route, "dependant", None)
        permissions = required([dependant]) if dependant is not None else set()
        for method in set(route.methods or ()) - {"HEAD"}:
            found[(method, str(route.path))] = frozenset(permissions) or NOTHING
    return found


def made(api_docs: bool = False) -> FastAPI:
    """The app as `sp serve` makes it; no station behind it (no request is sent)."""
    return create_app(
        cast(Server, SimpleNamespace(secure_cookies=False, api_docs=api_docs)), "s" * 32
    )


@pytest.fixture(scope="module")
def app() -> FastAPI:
    return made()


def test_each_route_declares_exactly_the_permission_of_the_table(app: FastAPI) -> None:
    served = declarations(app)
    expected = expected_declarations()
    assert sorted(served.keys() - expected.keys()) == [], "routes the table does not list"
    assert sorted(expected.keys() - served.keys()) == [], "rows for routes not served"
    wrong = {k: (v, expected[k]) for k, v in served.items() if v != expected[k]}
    assert wrong == {}, "route: (declared, expected)"


def test_api_docs_adds_only_the_public_documentation() -> None:
    """`sp serve --api-docs`: the page and its schema, for anyone (they show no station data)."""
    added = declarations(made(api_docs=True)).items() - expected_declarations().items()
    assert sorted(added) == [(("GET", "/docs"), NOTHING), (("GET", "/openapi.json"), NOTHING)]
