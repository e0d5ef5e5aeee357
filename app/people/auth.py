"""Users, roles, permissions, passwords (argon2) and CSRF tokens.

Sessions and API tokens are in app.people.sessions, sign-in throttling in app.people.throttle."""

from __future__ import annotations

import functools
import hmac
import secrets
import time
from enum import StrEnum

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.store.tables import User


class Role(StrEnum):
    OPERATOR = "operator"
    ENGINEER = "engineer"
    AUDITOR = "auditor"
    ADMIN = "admin"


class Permission(StrEnum):
    """What a page or API route needs; each role has a set of them."""

    TASKS = "tasks"  # task cards: confirm, maintenance done, approve or reject
    ALARMS = "alarms"  # see the alarms
    ACKNOWLEDGE = "acknowledge"  # acknowledge, shelve and unshelve alarms
    STATION = "station"  # the live station view
    CONTROL = "control"  # start and cancel intentions, restart mode, resets, estimates
    MODEL = "model"  # edit and save model versions
    ACTIVATE = "activate"  # run another model version
    SIMULATE = "simulate"  # the simulation panel: experiments and faults
    AUDIT = "audit"  # the audit log
    USERS = "users"  # add, disable and change users


ROLES = tuple(role.value for role in Role)
_OPERATOR = frozenset({Permission.TASKS, Permission.ALARMS, Permission.ACKNOWLEDGE})
_ENGINEER = _OPERATOR | {
    Permission.STATION,
    Permission.CONTROL,
    Permission.MODEL,
    Permission.ACTIVATE,
    Permission.SIMULATE,
    Permission.AUDIT,
}
PERMISSIONS: dict[Role, frozenset[Permission]] = {
    Role.OPERATOR: _OPERATOR,
    Role.ENGINEER: _ENGINEER,
    Role.AUDITOR: frozenset({Permission.ALARMS, Permission.AUDIT}),
    Role.ADMIN: _ENGINEER | {Permission.USERS},
}

# the demo station's users and their first-login passwords (printed on start, in the README)
DEMO_USERS = (
    ("operator", "operator", "operator-demo-1"),
    ("engineer", "engineer", "engineer-demo-1"),
    ("auditor", "auditor", "auditor-demo-1"),
    ("admin", "admin", "admin-demo-1"),
)
MIN_PASSWORD = 10

_hasher = PasswordHasher()


def hash_password(password: str) -> str:
    return _hasher.hash(password)


def password_matches(stored: str, password: str) -> bool:
    try:
        return _hasher.verify(stored, password)
    except (VerificationError, InvalidHashError):
        return False


@functools.cache
def dummy_hash() -> str:
    """A hash no password matches, checked for unknown user names: a sign-in takes as long
    for a name that does not exist as for one that does."""
    return hash_password(secrets.token_urlsafe(32))


def password_problem(name: str, password: str) -> str:
    """Why a new password is not acceptable ("" if it is)."""
    if len(password) < MIN_PASSWORD:
        return f"use at least {MIN_PASSWORD} characters"
    if password.lower() == name.lower():
        return "the password must differ from the user name"
    return ""


def add_user(session: Session, name: str, role: str, password: str, must_change: bool) -> User:
    if role not in ROLES:
        raise ValueError(f"unknown role '{role}'; use one of {', '.join(ROLES)}")
    user = User(
        name=name,
        role=role,
        password_hash=hash_password(password),
        must_change_password=must_change,
        disabled=False,
        created_at=time.time(),
    )
    session.add(user)
    session.flush()
    return user


def seed_demo_users(session: Session) -> list[tuple[str, str, str]]:
    """Create the demo users when there are no users at all; returns those created."""
    if session.scalars(select(User).limit(1)).first() is not None:
        return []
    for name, role, password in DEMO_USERS:
        add_user(session, name, role, password, must_change=True)
    return list(DEMO_USERS)


def user_named(session: Session, name: str) -> User | None:
    return session.scalars(select(User).where(User.name == name)).first()


def allowed(role: str, permission: Permission) -> bool:
    """May a user of `role` (as stored: a role's text) do what `permission` covers?"""
    known = role in ROLES
    return known and permission in PERMISSIONS[Role(role)]


def new_csrf_token() -> str:
    return secrets.token_urlsafe(32)


def same_token(expected: str | None, given: str | None) -> bool:
    return bool(expected) and bool(given) and hmac.compare_digest(str(expected), str(given))
