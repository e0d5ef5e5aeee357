"""The station's keys: kept in a file outside the database, never in it.

Whoever can write the database file could otherwise recompute a plain hash chain, raise a
user's role or sign a session cookie with a key read from the same file.  One master key (32
random bytes, hex, in a file of mode 0600) gives, by HMAC with a label each, the keys that
sign session cookies and API tokens, seal audit records and user rows, and sign the audit
log's checkpoints.  The checkpoints file lies beside the key file (`KEY.checkpoints`).

Where the key file is: `--keys FILE` (or `$SP_KEY_FILE`); else beside a SQLite database
(`station.db.key`); else `~/.config/sequence-planner/station.key` (`$XDG_CONFIG_HOME`).
An in-memory database gets keys that live as long as the process.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import secrets
from dataclasses import dataclass
from pathlib import Path


class KeyFileError(RuntimeError):
    """The key file cannot be used (unreadable, malformed, or missing while data needs it)."""


@dataclass(frozen=True)
class StationKeys:
    """The keys derived from one master key; `path` is None for keys that are not saved."""

    master: bytes
    path: Path | None = None

    def derived(self, label: str) -> bytes:
        return hmac.new(self.master, label.encode(), hashlib.sha256).digest()

    def mac(self, label: str, text: str) -> str:
        """HMAC-SHA256 of `text` under the key for `label`, as hex."""
        return hmac.new(self.derived(label), text.encode(), hashlib.sha256).hexdigest()

    @property
    def cookie_secret(self) -> str:
        return self.derived("session cookies and API tokens").hex()

    @property
    def checkpoints(self) -> Path | None:
        return None if self.path is None else self.path.with_name(self.path.name + ".checkpoints")


def default_key_path(url: str) -> Path | None:
    """Where the key file of the store at `url` is by default (None: in memory)."""
    from sqlalchemy.engine import make_url  # here: `sp plan` reads the cache key, no store

    configured = os.environ.get("SP_KEY_FILE")
    if configured:
        return Path(configured)
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database or ""
        if database in ("", ":memory:") or database.startswith("file::memory:"):
            return None
        return Path(database).resolve().with_name(Path(database).name + ".key")
    base = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    return base / "sequence-planner" / "station.key"


def read_keys(path: Path) -> StationKeys:
    """The keys in an existing key file; `KeyFileError` when it is missing or malformed."""
    try:
        text = path.read_text(encoding="ascii").strip()
    except FileNotFoundError:
        raise KeyFileError(f"there is no key file at {path}") from None
    except (OSError, UnicodeDecodeError) as problem:
        raise KeyFileError(f"the key file {path} cannot be read: {problem}") from None
    try:
        master = bytes.fromhex(text)
    except ValueError:
        master = b""
    if len(master) != 32:
        raise KeyFileError(f"the key file {path} does not hold a key (64 hex digits)")
    return StationKeys(master, path)


def create_keys(path: Path) -> StationKeys:
    """A new key file (mode 0600); refuses to overwrite one."""
    master = secrets.token_bytes(32)
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    try:
        descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise KeyFileError(f"a key file exists already at {path}") from None
    except OSError as problem:
        raise KeyFileError(f"the key file {path} cannot be written: {problem}") from None
    with os.fdopen(descriptor, "w", encoding="ascii") as file:
        file.write(master.hex() + "\n")
        file.flush()
        os.fsync(file.fileno())
    return StationKeys(master, path)


def ephemeral_keys() -> StationKeys:
    return StationKeys(secrets.token_bytes(32))
