"""FastAPI dependencies: the server, the current user and their permissions, CSRF checks,
and the aliases handlers declare them by: the services they touch (`LiveDep`, `StoreDep`,
`ServerDep`) and what the caller may do (`TasksCaller`, `Controller`, `ModelEditor`, ...).

Pages and API routes share them: a browser session (signed cookie) or, for line systems, a
bearer token, each looked up in the store on every request (app.people.sessions: revoked at
once on logout, password change or disable), for a user whose row is sealed (app.store.seals:
a row changed outside the station is refused).  Unsafe methods from a browser session must
carry the session's CSRF token, as a form field `csrf_token` or an `X-CSRF-Token` header;
bearer requests need none (no cookie a third-party page could ride on).
"""

from __future__ import annotations

import ipaddress
import logging
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import Depends, HTTPException, Request
from fastapi.templating import Jinja2Templates
from starlette.concurrency import run_in_threadpool

from app.pages.cards import task_cards
from app.people import sessions as user_sessions
from app.people.auth import Permission, allowed, new_csrf_token, same_token
from app.people.sessions import SessionKind
from app.station.live import LiveStation
from app.station.view import StationView
from app.store import audit, row_seals
from app.store.audit import AuditEntry, AuditKind
from app.store.db import Store
from app.store.tables import User, UserSession
from app.web.audit_log import Criteria, filter_dependency
from app.web.server import Network, Server

log = logging.getLogger(__name__)

SAFE_METHODS = ("GET", "HEAD", "OPTIONS")


class LoginRequired(Exception):
    """A page needs a signed-in user: redirect to /login (the API answers 401 instead)."""


class PasswordChangeRequired(Exception):
    """A first-login password must be changed before anything else."""


def server(request: Request) -> Server:
    """What the app was made with (app.web.app.create_app).  Handlers declare the part they
    use (`ServerDep`, `LiveDep`, `StoreDep`); this is for the functions here and for
    exception handlers, which get no dependencies."""
    found: Server = request.app.state.server
    return found


def templates(request: Request) -> Jinja2Templates:
    """The page templates (for app.web.pages' helpers, which render for a handler)."""
    return server(request).templates


# cheap, so on the event loop (a plain `def` dependency would take a worker thread)
async def _server(request: Request) -> Server:
    return server(request)


async def _live(request: Request) -> LiveStation:
    return server(request).live


async def _store(request: Request) -> Store:
    return server(request).store


ServerDep = Annotated[Server, Depends(_server)]
LiveDep = Annotated[LiveStation, Depends(_live)]
StoreDep = Annotated[Store, Depends(_store)]


@dataclass(frozen=True)
class Caller:
    """The signed-in user, as handlers see them (no ORM object escapes the session)."""

    id: int
    name: str
    role: str
    bearer: bool = False


def csrf_token(request: Request) -> str:
    token = request.session.get("csrf")
    if not token:
        token = new_csrf_token()
        request.session["csrf"] = token
    return str(token)


def is_api(request: Request) -> bool:
    return request.url.path.startswith("/api")


def client_address(request: Request) -> str:
    """The client's address: the peer's, unless the peer is a trusted proxy (none by
    default), then the nearest address in X-Forwarded-For that is not one."""
    srv = server(request)
    peer = request.client.host if request.client else "unknown"
    if not srv.trusted_proxies or not _within(peer, srv.trusted_proxies):
        return peer
    hops = [h.strip() for h in request.headers.get("x-forwarded-for", "").split(",")]
    for hop in reversed([h for h in hops if h]):
        if not _within(hop, srv.trusted_proxies):
            try:
                return str(ipaddress.ip_address(hop))
            except ValueError:
                return peer  # not an address: the proxy's word is worth nothing here
    return peer


def _within(address: str, networks: tuple[Network, ...]) -> bool:
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return False
    return any(ip in network for network in networks)


def trusted_user(srv: Server, user: User) -> bool:
    """An enabled user whose row the station wrote (a tampered one is said once, audited)."""
    if user.disabled:
        return False
    return _trusted_row(srv, user, f"user '{user.name}'", {"name": user.name}, AuditKind.USER)


def trusted_session(srv: Server, found: user_sessions.Found) -> bool:
    """A session (or token) row the station wrote, of a trusted user."""
    row = found.row
    what = f"a session of '{found.user.name}'"
    detail = {"name": found.user.name, "session": row.id[:12]}
    return _trusted_row(srv, row, what, detail, AuditKind.LOGIN) and trusted_user(srv, found.user)


def _trusted_row(
    srv: Server, row: User | UserSession, what: str, detail: dict[str, str], kind: AuditKind
) -> bool:
    """Sealed by the station and not older than it last wrote it (app.store.row_seals); a row
    that is not is refused, said once and audited."""
    keys, freshness = srv.store.keys, srv.store.freshness
    if keys is None or freshness is None or row_seals.trusted(keys, freshness, row):
        return True
    if what not in srv.tampered:
        srv.tampered.add(what)
        log.warning("%s: the row does not match its seal or is older than written; refused", what)
        entry = AuditEntry(kind, "row changed outside the station", "", "", detail)
        audit.write(srv.store, srv.live.name, [entry], srv.live.wall())
    return False


def browser_session(request: Request) -> user_sessions.Found | None:
    """The signed-in browser session and its user (first-login password change or not)."""
    srv = server(request)
    secret, uid = request.session.get("sid"), request.session.get("uid")
    if not isinstance(secret, str) or not isinstance(uid, int):
        return None
    with srv.store.sessions() as session:
        found = user_sessions.find(session, secret, uid, srv.live.wall())
        if found is not None:
            session.expunge_all()
    if found is None or found.row.kind != SessionKind.BROWSER or not trusted_session(srv, found):
        request.session.clear()
        return None
    return found


def current_caller(request: Request) -> Caller | None:
    srv = server(request)
    header = request.headers.get("authorization", "")
    if header.lower().startswith("bearer "):
        carried = srv.tokens.read(header[7:].strip())
        found = None
        if carried is not None:
            with srv.store.sessions() as session:
                found = user_sessions.find(session, carried[1], carried[0], srv.live.wall())
                if found is not None:
                    session.expunge_all()
        if found is None or found.row.kind != SessionKind.API or not trusted_session(srv, found):
            # counted for the audit log per address block (app.people.failures), not written
            srv.failures.note("bad token", client_address(request), srv.live.wall())
            raise HTTPException(
                401, "the bearer token is invalid, expired or revoked; get a new one"
            )
        return Caller(found.user.id, found.user.name, found.user.role, bearer=True)
    found = browser_session(request)
    if found is None:
        return None
    if found.user.must_change_password:
        raise PasswordChangeRequired()
    return Caller(found.user.id, found.user.name, found.user.role)


async def check_csrf(request: Request, caller: Caller) -> None:
    if request.method in SAFE_METHODS or caller.bearer:
        return
    expected = request.session.get("csrf")
    given = request.headers.get("x-csrf-token")
    if not given and "form" in request.headers.get("content-type", ""):
        form = await request.form()
        value = form.get("csrf_token")
        given = value if isinstance(value, str) else None
    if not same_token(expected, given):
        raise HTTPException(403, "the form has expired or did not come from this station; reload")


class Requires:
    """A dependency: the caller, who must be signed in and hold one of `permissions` (with
    none, any signed-in caller: their own account's pages).

    Routes depend on instances of it (the aliases below), so what each route requires can be
    read from the app's routes (each route's dependencies), not only tried by sending
    requests (tests/web/test_security_declared.py)."""

    def __init__(self, *permissions: Permission) -> None:
        self.permissions = permissions

    def __repr__(self) -> str:
        return f"Requires({', '.join(str(p) for p in self.permissions)})"

    async def __call__(self, request: Request) -> Caller:
        return await admitted(request, self.permissions or None)


async def admitted(request: Request, permissions: tuple[Permission, ...] | None) -> Caller:
    """The caller, signed in, holding one of `permissions` (None: any signed-in caller),
    with the CSRF token on an unsafe request; kept in `request.state.caller` for the
    handler's refusals (app.web.outcomes: only those past this gate are audited)."""
    # its session and user are read from the store: not on the event loop's thread,
    # which serves every page's event stream meanwhile
    caller = await run_in_threadpool(current_caller, request)
    if caller is None:
        if is_api(request):
            raise HTTPException(401, "sign in first: POST /api/token, then send a bearer token")
        raise LoginRequired()
    if permissions is not None and not any(allowed(caller.role, p) for p in permissions):
        raise HTTPException(403, refusal(request, caller.role, permissions))
    await check_csrf(request, caller)
    request.state.caller = caller
    return caller


def optional_caller(request: Request) -> Caller | None:
    """The caller, or None for nobody signed in: for pages that send nobody somewhere of
    their own (read from the store, so in a worker thread)."""
    return current_caller(request)


OptionalCaller = Annotated[Caller | None, Depends(optional_caller)]
# the caller, signed in and holding the permission (or a 401, a sign-in redirect or a 403
# before the handler runs), named after what the permission lets them do
TasksCaller = Annotated[Caller, Depends(Requires(Permission.TASKS))]
AlarmViewer = Annotated[Caller, Depends(Requires(Permission.ALARMS))]
Acknowledger = Annotated[Caller, Depends(Requires(Permission.ACKNOWLEDGE))]
StationViewer = Annotated[Caller, Depends(Requires(Permission.STATION))]
StationOrTasksCaller = Annotated[Caller, Depends(Requires(Permission.STATION, Permission.TASKS))]
Controller = Annotated[Caller, Depends(Requires(Permission.CONTROL))]
ModelEditor = Annotated[Caller, Depends(Requires(Permission.MODEL))]
Activator = Annotated[Caller, Depends(Requires(Permission.ACTIVATE))]
Simulator = Annotated[Caller, Depends(Requires(Permission.SIMULATE))]
AuditReader = Annotated[Caller, Depends(Requires(Permission.AUDIT))]
UserAdmin = Annotated[Caller, Depends(Requires(Permission.USERS))]
SignedIn = Annotated[Caller, Depends(Requires())]  # anyone signed in: their own account
# the audit log's filter from the query string, or a 422 that says what to fix
AuditCriteria = Annotated[Criteria, Depends(filter_dependency)]


def refusal(request: Request, role: str, permissions: tuple[Permission, ...]) -> str:
    """Why a role is refused, in plain words for a page ("Your role (auditor) cannot see
    this page."); a line system's API client is also told the permissions it lacks."""
    if is_api(request):
        needs = " or ".join(f"'{p}'" for p in permissions)
        return f"your role ({role}) cannot do this (it needs the {needs} permission)"
    if request.method in SAFE_METHODS:
        return f"Your role ({role}) cannot see this page."
    return f"Your role ({role}) cannot do this."


@dataclass(frozen=True, slots=True)
class Place:
    """A page a person may open, for links on the pages that refuse them."""

    href: str
    words: str


# every page of the HMI and what it needs to be opened, in the top bar's order
PLACES = (
    (Place("/", "Tasks"), Permission.TASKS),
    (Place("/alarms", "Alarms"), Permission.ALARMS),
    (Place("/station", "Station"), Permission.STATION),
    (Place("/model", "Model"), Permission.MODEL),
    (Place("/audit", "Audit log"), Permission.AUDIT),
    (Place("/users", "Users"), Permission.USERS),
)


def places_for(caller: Caller | None) -> list[Place]:
    """The pages `caller` may open (only the sign-in page for nobody)."""
    if caller is None:
        return [Place("/login", "Log in")]
    return [place for place, needs in PLACES if allowed(caller.role, needs)]


def alarm_badge(view: StationView) -> tuple[int, str]:
    """Alarms waiting for a person's acknowledgement (active or returned; shelved ones are
    not shown), and the highest priority among them ("" if none).  The page, its alarm
    list's answers and the SSE `alarm` event all count from the same committed view."""
    waiting = [a for a in view.alarms if a.waiting]
    if not waiting:
        return 0, ""
    return len(waiting), str(min(waiting, key=lambda a: a.priority.rank).priority)


def task_count(view: StationView, caller: Caller | None) -> int | None:
    """The task cards waiting, for the Tasks tab and the title of every page (None for a
    caller who sees no tasks: nobody signed in, an auditor).  The page, the task card's
    fragment and the SSE `tasks` and `badge` events all count from the same view."""
    if caller is None or not allowed(caller.role, Permission.TASKS):
        return None
    return len(task_cards(view))


def page_context(
    request: Request, caller: Caller | None, page: str, **extra: Any
) -> dict[str, Any]:
    """What every template gets (see templates/base.html)."""
    srv = server(request)
    view = srv.live.view
    alarm_count, alarm_priority = alarm_badge(view)
    return {
        "request": request,
        "user": caller,
        "csrf_token": csrf_token(request),
        "station_name": view.model.words.station(),  # words for people, not its model name
        "alarm_count": alarm_count,
        "alarm_priority": alarm_priority,
        "task_count": task_count(view, caller),
        "simulated": view.simulated,
        "on_emulators": srv.live.on_emulators,
        "page": page,
        "view": view,
        "places_for": places_for,
        **extra,
    }
