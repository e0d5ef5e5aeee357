"""A user's own API tokens, for their account page (app.web.routes.account) and the API
(app.web.api.token): issued from their browser session (ending with it), listed, and
revoked one by one; each issue and revocation audited.  The tokens themselves are sessions
of the store (app.people.sessions); their secrets are shown once, when issued, and never
kept."""

from __future__ import annotations

from fastapi import HTTPException
from sqlalchemy.orm import Session

from app.people import sessions as user_sessions
from app.people.sessions import SessionKind, Token
from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.web.deps import Caller
from app.web.server import Server


def listed(srv: Server, caller: Caller, current: str = "") -> list[Token]:
    """The caller's live tokens; `current`: the secret of the browser session asking."""
    with srv.store.sessions() as session:
        return user_sessions.tokens_of(session, caller.id, srv.live.wall(), current)


def issue(srv: Server, found: user_sessions.Found, address: str) -> str:
    """A new token for the user of the browser session `found`, ending with that session;
    audited.  The token itself (shown once)."""
    user, row = found.user, found.row

    def opened(session: Session) -> str:
        return user_sessions.open_session(
            session, user, SessionKind.API, address, srv.live.wall(), issued_by=row
        )

    detail = {"role": user.role, "address": address, "from": "a browser session"}
    entry = AuditEntry(AuditKind.LOGIN, "api token", user.name, "", detail)
    secret = audit.write(srv.store, srv.live.name, [entry], srv.live.wall(), also=opened)
    return srv.tokens.issue(user, secret or "")


def revoke(srv: Server, caller: Caller, handle: str) -> None:
    """End the caller's own token `handle` (404 for none of theirs live); audited."""

    def end(session: Session) -> bool:
        return user_sessions.revoke_token(session, caller.id, handle, "revoked", srv.live.wall())

    def entries(ended: bool | None) -> list[AuditEntry]:
        return (
            [AuditEntry(AuditKind.LOGIN, "api token revoked", caller.name, "", {"token": handle})]
            if ended
            else []
        )

    if not audit.write(srv.store, srv.live.name, entries, srv.live.wall(), also=end):
        raise HTTPException(404, "you have no live API token with that id")
