"""Users, roles, passwords (argon2), login throttling, CSRF tokens and API tokens."""

from __future__ import annotations

import hmac
import secrets
import time
from collections import defaultdict, deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError
from itsdangerous import BadSignature, SignatureExpired, URLSafeTimedSerializer
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.store.tables import Setting, User


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
API_TOKEN_HOURS = 12

_hasher = PasswordHasher()


def hash_password(password: str) -> str:
    return _hasher.hash(password)


def password_matches(stored: str, password: str) -> bool:
    try:
        return _hasher.verify(stored, password)
    except (VerificationError, InvalidHashError):
        return False


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


def secret_key(session: Session) -> str:
    """The key that signs session cookies and API tokens, made once per store."""
    row = session.get(Setting, "secret_key")
    if row is None:
        row = Setting(key="secret_key", value=secrets.token_urlsafe(48))
        session.add(row)
        session.flush()
    return row.value


def new_csrf_token() -> str:
    return secrets.token_urlsafe(32)


def same_token(expected: str | None, given: str | None) -> bool:
    return bool(expected) and bool(given) and hmac.compare_digest(str(expected), str(given))


@dataclass
class LoginThrottle:
    """At most `limit` failed logins per user name and per client address in `window` seconds."""

    limit: int = 5
    window: float = 300.0
    clock: Callable[[], float] = time.monotonic

    def __post_init__(self) -> None:
        self.failures: defaultdict[str, deque[float]] = defaultdict(deque)

    def _recent(self, key: str) -> deque[float]:
        times = self.failures[key]
        while times and times[0] <= self.clock() - self.window:
            times.popleft()
        return times

    def wait(self, name: str, address: str) -> float:
        """Seconds until another attempt is allowed (0 when it is)."""
        waits = []
        for key in (f"user:{name.lower()}", f"address:{address}"):
            times = self._recent(key)
            if len(times) >= self.limit:
                waits.append(times[0] + self.window - self.clock())
        return max(waits, default=0.0)

    def failed(self, name: str, address: str) -> None:
        for key in (f"user:{name.lower()}", f"address:{address}"):
            self._recent(key).append(self.clock())

    def succeeded(self, name: str) -> None:
        self.failures.pop(f"user:{name.lower()}", None)


class ApiTokens:
    """Bearer tokens for line systems (MES): signed, expiring, void after a password change."""

    def __init__(self, key: str) -> None:
        self.serializer = URLSafeTimedSerializer(key, salt="sequence-planner api token")

    def issue(self, user: User) -> str:
        return self.serializer.dumps({"user": user.id, "hash": user.password_hash[-16:]})

    def user(self, session: Session, token: str) -> User | None:
        try:
            data = self.serializer.loads(token, max_age=API_TOKEN_HOURS * 3600)
        except (BadSignature, SignatureExpired):
            return None
        if not isinstance(data, dict):
            return None
        user = session.get(User, data.get("user"))
        if user is None or user.disabled or user.password_hash[-16:] != data.get("hash"):
            return None
        return user
