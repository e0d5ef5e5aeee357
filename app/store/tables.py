"""Tables of the station store (SQLAlchemy 2, portable between SQLite and PostgreSQL).

Times are seconds since the epoch (UTC) as floats: portable, sortable, and what the audit
chain hashes.  JSON payloads are text, so that the hash of a record does not depend on how a
database renders JSON.
"""

from __future__ import annotations

from sqlalchemy import Boolean, Float, ForeignKey, Index, Integer, String, Text
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column


class Base(DeclarativeBase):
    pass


class User(Base):
    __tablename__ = "users"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    role: Mapped[str] = mapped_column(String(16))  # operator, engineer, auditor, admin
    password_hash: Mapped[str] = mapped_column(String(256))
    must_change_password: Mapped[bool] = mapped_column(Boolean, default=True)
    disabled: Mapped[bool] = mapped_column(Boolean, default=False)
    created_at: Mapped[float] = mapped_column(Float)
    # HMAC of the row under the station's key (app.store.seals): a row changed outside the
    # station no longer matches and is refused
    mac: Mapped[str] = mapped_column(String(64), default="")
    seq: Mapped[int] = mapped_column(Integer, default=0)  # bound into the seal: freshness


class UserSession(Base):
    """A signed-in browser or API token, kept so that it can be revoked (logout, password
    change, disable).  `id` is the SHA-256 of the secret the cookie or token carries."""

    __tablename__ = "user_sessions"

    id: Mapped[str] = mapped_column(String(64), primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    kind: Mapped[str] = mapped_column(String(16))  # browser | api
    created_at: Mapped[float] = mapped_column(Float)
    expires_at: Mapped[float] = mapped_column(Float)
    revoked_at: Mapped[float | None] = mapped_column(Float, default=None)
    revoked_why: Mapped[str] = mapped_column(String(64), default="")
    address: Mapped[str] = mapped_column(String(64), default="")
    # an API token issued from a browser session: that session's id ("" for one issued for a
    # password, POST /api/token); the token ends when the session signs out
    issued_by: Mapped[str] = mapped_column(String(64), default="")
    # the row's version counter and seal under the station's key (app.store.row_seals)
    seq: Mapped[int] = mapped_column(Integer, default=0)
    mac: Mapped[str] = mapped_column(String(64), default="")

    __table_args__ = (
        Index("ix_user_sessions_user", "user_id"),
        Index("ix_user_sessions_issued_by", "issued_by"),
    )


class ModelVersion(Base):
    """A saved text of a station model; versions are never changed, only added."""

    __tablename__ = "model_versions"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    station: Mapped[str] = mapped_column(String(64))
    number: Mapped[int] = mapped_column(Integer)  # 1, 2, ... per station
    text: Mapped[str] = mapped_column(Text)
    sha256: Mapped[str] = mapped_column(String(64))
    author: Mapped[str] = mapped_column(String(64))
    note: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[float] = mapped_column(Float)
    # the row's version counter and seal under the station's key (app.store.row_seals)
    seq: Mapped[int] = mapped_column(Integer, default=0)
    mac: Mapped[str] = mapped_column(String(64), default="")

    __table_args__ = (Index("ix_model_versions_station_number", "station", "number", unique=True),)


class StationRecord(Base):
    """One row per station: its active model version and the runner's last durable state."""

    __tablename__ = "stations"

    name: Mapped[str] = mapped_column(String(64), primary_key=True)
    active_version_id: Mapped[int | None] = mapped_column(ForeignKey("model_versions.id"))
    snapshot: Mapped[str] = mapped_column(Text, default="")  # planner.runner.snapshot.dump as JSON
    world: Mapped[str] = mapped_column(Text, default="")  # the simulated devices' state, if any
    updated_at: Mapped[float] = mapped_column(Float)
    # the audit record the snapshot follows: the newest its round wrote (or found)
    audit_id: Mapped[int] = mapped_column(Integer, default=0)
    audit_hash: Mapped[str] = mapped_column(String(64), default="")
    # the row's version counter and seal under the station's key (app.store.row_seals)
    seq: Mapped[int] = mapped_column(Integer, default=0)
    mac: Mapped[str] = mapped_column(String(64), default="")


class AlarmRecord(Base):
    """The alarm book's rows (app.station.alarms.Alarm), kept so that alarm states survive a
    restart."""

    __tablename__ = "alarms"

    station: Mapped[str] = mapped_column(String(64), primary_key=True)
    key: Mapped[str] = mapped_column(String(200), primary_key=True)
    data: Mapped[str] = mapped_column(Text)  # the Alarm's fields as JSON
    updated_at: Mapped[float] = mapped_column(Float)
    # the row's version counter and seal under the station's key (app.store.row_seals)
    seq: Mapped[int] = mapped_column(Integer, default=0)
    mac: Mapped[str] = mapped_column(String(64), default="")


class AuditRecord(Base):
    """One audit event.  Append-only: the code has no update or delete path, the migration
    adds triggers that refuse both, and each record carries the hash of the one before."""

    __tablename__ = "audit"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    time: Mapped[float] = mapped_column(Float)
    station: Mapped[str] = mapped_column(String(64))
    user: Mapped[str] = mapped_column(String(64), default="")  # "" for the station itself
    kind: Mapped[str] = mapped_column(String(32))
    subject: Mapped[str] = mapped_column(String(200), default="")
    resource: Mapped[str] = mapped_column(String(64), default="")
    detail: Mapped[str] = mapped_column(Text, default="{}")  # JSON
    previous: Mapped[str] = mapped_column(String(64))  # hash of the record before ("0"*64 first)
    hash: Mapped[str] = mapped_column(String(64))
    # HMAC of `hash` under the station's key: "" only for records from before the key existed
    mac: Mapped[str] = mapped_column(String(64), default="")

    __table_args__ = (
        Index("ix_audit_time", "time"),
        Index("ix_audit_kind", "kind"),
        Index("ix_audit_user", "user"),
        Index("ix_audit_resource", "resource"),
    )


class Setting(Base):
    """Station-wide settings.  (Its old `secret_key` row is no longer used: the keys are in
    the key file, app.store.keys.)"""

    __tablename__ = "settings"

    key: Mapped[str] = mapped_column(String(64), primary_key=True)
    value: Mapped[str] = mapped_column(Text)
    # the row's version counter and seal under the station's key (app.store.row_seals)
    seq: Mapped[int] = mapped_column(Integer, default=0)
    mac: Mapped[str] = mapped_column(String(64), default="")
