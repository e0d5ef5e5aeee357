"""A bearer token for the API (`POST /api/token`): the sign-in of line systems (MES) and
scripts, checked and throttled as the sign-in form is (app.web.sign_in); and the caller's
own tokens, listed (`GET /api/tokens`) and revoked one by one (`DELETE /api/tokens/{id}`),
as on their account page (app.web.tokens)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, HTTPException, Path, Request
from pydantic import BaseModel, Field

from app.people.sessions import HANDLE_CHARS, SessionKind
from app.web import tokens
from app.web.api.common import PREFIX, bearer, errors
from app.web.api.schemas import Invalid, Message
from app.web.deps import ServerDep, SignedIn, client_address
from app.web.limits import PASSWORD_CHARS, USER_CHARS
from app.web.sign_in import check_password, open_session

router = APIRouter(prefix=PREFIX, tags=["auth"])


class TokenRequest(BaseModel):
    name: str = Field(min_length=1, max_length=USER_CHARS)
    password: str = Field(min_length=1, max_length=PASSWORD_CHARS)


class TokenAnswer(BaseModel):
    token: str
    token_type: str = "bearer"
    role: str


@router.post(
    "/token",
    responses={
        400: {"model": Message, "description": "the body is not JSON"},
        401: {"model": Message, "description": "wrong user name or password"},
        403: {"model": Message, "description": "the first-login password is not changed yet"},
        422: {"model": Invalid, "description": "a field is missing or too long"},
        429: {"model": Message, "description": "too many failed sign-ins"},
        503: {"model": Message, "description": "too many sign-ins being checked at once"},
    },
)
def api_token(request: Request, srv: ServerDep, body: TokenRequest) -> TokenAnswer:
    """A bearer token for line systems (MES): valid 12 hours; void when the password changes
    or the user is disabled."""
    user = check_password(srv, client_address(request), body.name.strip(), body.password)
    if user.must_change_password:
        raise HTTPException(403, "change the first-login password in the browser first")
    secret = open_session(srv, user, SessionKind.API, client_address(request))
    return TokenAnswer(token=srv.tokens.issue(user, secret), role=user.role)


class TokenShown(BaseModel):
    """A live API token of the caller's (never its secret)."""

    id: str = Field(description="the token's id, to revoke it by")
    issued_at: float = Field(description="seconds since the epoch (UTC)")
    expires_at: float
    address: str = Field(description="the address it was issued to")
    from_session: str = Field(
        description="'this session', 'another session' (a browser session it ends with), "
        "or '' (issued for a password)"
    )


TokenId = Annotated[
    str, Path(min_length=HANDLE_CHARS, max_length=HANDLE_CHARS, description="a token's id")
]


@router.get("/tokens", dependencies=[Depends(bearer)], responses=errors(401))
def list_tokens(request: Request, caller: SignedIn, srv: ServerDep) -> list[TokenShown]:
    """The caller's live API tokens, newest first."""
    current = "" if caller.bearer else str(request.session.get("sid", ""))
    return [
        TokenShown(
            id=t.handle,
            issued_at=t.issued_at,
            expires_at=t.expires_at,
            address=t.address,
            from_session=t.from_session,
        )
        for t in tokens.listed(srv, caller, current)
    ]


@router.delete(
    "/tokens/{token_id}", dependencies=[Depends(bearer)], responses=errors(401, 404, 422)
)
def revoke_token(caller: SignedIn, srv: ServerDep, token_id: TokenId) -> Message:
    """End one of the caller's own tokens (the one this request carries, too)."""
    tokens.revoke(srv, caller, token_id)
    return Message(detail="revoked")
