"""A bearer token for the API (`POST /api/token`): the sign-in of line systems (MES) and
scripts, checked and throttled as the sign-in form is (app.web.sign_in)."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Request
from pydantic import BaseModel, Field

from app.people.sessions import SessionKind
from app.web.api.common import PREFIX
from app.web.api.schemas import Invalid, Message
from app.web.deps import ServerDep, client_address
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
