"""The FastAPI application: middleware, error pages, and every router, per area (STYLE.md):
the pages (app.web.routes) and the JSON API (app.web.api)."""

from __future__ import annotations

import logging
from html import escape

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.middleware.sessions import SessionMiddleware

from app.station.live import StationError
from app.web.actions import RunnerRefused
from app.web.api import alarms as api_alarms
from app.web.api import audit as api_audit
from app.web.api import control as api_control
from app.web.api import experiments as api_experiments
from app.web.api import models as api_models
from app.web.api import operator as api_operator
from app.web.api import station as api_station
from app.web.api import token as api_token
from app.web.deps import (
    LoginRequired,
    PasswordChangeRequired,
    current_caller,
    is_api,
    templates,
)
from app.web.headers import SecurityHeaders
from app.web.limits import BODY_BYTES
from app.web.outcomes import AuditedRefusal, after_refusal
from app.web.pages import values_for
from app.web.routes import (
    account,
    alarms,
    api_docs,
    assets,
    audit,
    auth,
    control,
    events,
    model,
    operator,
    simulation,
    station,
    timeline,
    users,
)
from app.web.server import STATIC, Server

log = logging.getLogger(__name__)

# every router, by area: the pages, then the JSON API (its paths in this order in /docs)
PAGES = (
    auth.router,
    events.router,
    operator.router,
    station.router,
    control.router,
    simulation.router,
    model.router,
    audit.router,
    users.router,
    account.router,
    alarms.router,
    assets.router,
    timeline.router,
)
API = (
    api_token.router,
    api_station.router,
    api_operator.router,
    api_control.router,
    api_alarms.router,
    api_models.router,
    api_experiments.router,
    api_audit.router,
)


def create_app(srv: Server, secret: str) -> FastAPI:
    app = FastAPI(
        title="Sequence Planner station",
        description="Operator, engineer and auditor HMI of one assembly station, and its JSON API.",
        version="0.1.0",
        # FastAPI's own pages load an unpinned CDN copy with an inline script: never served;
        # with `sp serve --api-docs`, /docs is the vendored one (app.web.routes.api_docs)
        docs_url=None,
        redoc_url=None,
        openapi_url="/openapi.json" if srv.api_docs else None,
        max_body_size=BODY_BYTES,  # the model routes allow more (app.web.limits)
    )
    app.state.server = srv
    app.add_middleware(
        SessionMiddleware,
        secret_key=secret,
        session_cookie="sp_session",
        max_age=12 * 3600,
        same_site="strict",
        https_only=srv.secure_cookies,
    )
    # outermost: on every answer, errors included
    app.add_middleware(SecurityHeaders, docs=srv.api_docs)
    app.mount("/static", StaticFiles(directory=str(STATIC)), name="static")
    for router in (*PAGES, *API, *((api_docs.router,) if srv.api_docs else ())):
        app.include_router(router)

    @app.get("/healthz", include_in_schema=False)
    def healthz(since: float | None = None) -> dict[str, object]:
        """`loop`: how the station loop keeps its period (over rounds since station time
        `since`, the `now` of an earlier answer; by default the last few thousand)."""
        view = srv.live.view
        loop = srv.live.loop_summary(since)
        return {"ok": True, "version": view.serial, "model": view.model.number, "loop": loop}

    app.add_exception_handler(LoginRequired, _login_required)
    app.add_exception_handler(PasswordChangeRequired, _password_change)
    # Starlette's own (an unknown address, a wrong method) too: a person gets the error
    # page (its <title> and lang), not raw JSON; the API keeps its JSON
    app.add_exception_handler(StarletteHTTPException, _http_error)  # type: ignore[arg-type]
    app.add_exception_handler(RequestValidationError, _invalid)  # type: ignore[arg-type]
    app.add_exception_handler(StationError, _station_error)  # type: ignore[arg-type]
    return app


async def _login_required(request: Request, _exc: Exception) -> Response:
    if request.headers.get("hx-request"):
        return Response(status_code=401, headers={"HX-Redirect": "/login"})
    return RedirectResponse(f"/login?next={request.url.path}", status_code=303)


async def _password_change(request: Request, _exc: Exception) -> Response:
    if is_api(request):
        return JSONResponse({"detail": "change the first-login password at /password"}, 403)
    return RedirectResponse("/password", status_code=303)


def error_response(request: Request, status: int, message: str) -> Response:
    """An error as the asker reads it: JSON for the API, the flash for htmx, else a page."""
    if is_api(request) or request.headers.get("hx-request"):
        if request.headers.get("hx-request") and not is_api(request):
            return HTMLResponse(
                f'<p class="flash flash--error" role="alert">{escape(message)}</p>',
                status_code=status,
                headers={"HX-Retarget": "#flash", "HX-Reswap": "innerHTML"},
            )
        return JSONResponse({"detail": message}, status_code=status)
    context = values_for(request, None, "error", error=message, status=status)
    try:
        context["user"] = current_caller(request)
    except Exception:  # a broken session must not hide the error itself
        context["user"] = None
    response: Response = templates(request).TemplateResponse(
        request, "error.html", context, status_code=status
    )
    return response


async def _http_error(request: Request, exc: StarletteHTTPException) -> Response:
    audited = isinstance(exc, AuditedRefusal)
    detail = str(exc.detail)
    if type(exc) is StarletteHTTPException and exc.status_code == 404 and not is_api(request):
        detail = "There is no page at this address."  # no route: Starlette's "Not Found"
    back = await after_refusal(request, exc.status_code, detail, audited)
    return back or error_response(request, exc.status_code, detail)


async def _invalid(request: Request, exc: RequestValidationError) -> Response:
    problems = []
    for error in exc.errors():
        where = ".".join(str(p) for p in error.get("loc", ()) if p not in ("body", "query"))
        problems.append(f"{where}: {error.get('msg', 'invalid')}" if where else error["msg"])
    message = "; ".join(problems) or "the request is not valid"
    back = await after_refusal(request, 422, message, audited=False)
    if back is not None:
        return back
    if is_api(request):
        errors = [
            {"loc": list(e.get("loc", ())), "msg": str(e.get("msg", ""))} for e in exc.errors()
        ]
        return JSONResponse({"detail": message, "errors": errors}, status_code=422)
    return error_response(request, 422, message)


async def _station_error(request: Request, exc: StationError) -> Response:
    # the runner's own refusals are in the log already, as its `refused` events
    back = await after_refusal(request, 409, str(exc), isinstance(exc, RunnerRefused))
    return back or error_response(request, 409, str(exc))
