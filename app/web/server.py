"""What every request handler may reach: the store, the live station, templates, throttling."""

from __future__ import annotations

import ipaddress
import threading
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from fastapi.templating import Jinja2Templates

from app.people.failures import FailureLog, FailureWriter, Summary
from app.people.sessions import ApiTokens
from app.people.throttle import SignInThrottle
from app.station.live import LiveStation
from app.station.model_budget import ModelChecks
from app.station.scenario import Scenario
from app.store import audit
from app.store.audit import AuditEntry, AuditKind
from app.store.checkpoints import Checkpointer
from app.store.db import Store

ROOT = Path(__file__).resolve().parents[2]
TEMPLATES = ROOT / "templates"
STATIC = ROOT / "static"
PASSWORD_CHECKS = 4  # argon2 checks at once: each takes ~0.2 s of a core and 64 MiB

Network = ipaddress.IPv4Network | ipaddress.IPv6Network


def parse_networks(texts: Iterable[str]) -> tuple[Network, ...]:
    """Addresses or networks (`10.0.0.5`, `10.0.0.0/24`); ValueError names a bad one."""
    networks = []
    for text in texts:
        try:
            networks.append(ipaddress.ip_network(text.strip(), strict=False))
        except ValueError:
            raise ValueError(f"'{text}' is not an IP address or network") from None
    return tuple(networks)


@dataclass
class Server:
    store: Store
    live: LiveStation
    tokens: ApiTokens
    cache: Path | None
    throttle: SignInThrottle = field(default_factory=SignInThrottle)
    # failed sign-ins and bad tokens, counted per address block for the audit log
    failures: FailureLog = field(default_factory=FailureLog)
    # the simulation panel's experiments: id -> (title, scenario)
    experiments: dict[str, tuple[str, Scenario]] = field(default_factory=dict)
    templates: Jinja2Templates = field(
        default_factory=lambda: Jinja2Templates(directory=str(TEMPLATES))
    )
    secure_cookies: bool = False
    trusted_proxies: tuple[Network, ...] = ()
    api_docs: bool = False  # /docs and /openapi.json (`sp serve --api-docs`)
    checkpoints: Checkpointer | None = None
    password_checks: threading.BoundedSemaphore = field(
        default_factory=lambda: threading.BoundedSemaphore(PASSWORD_CHECKS)
    )
    tampered: set[str] = field(default_factory=set)  # users whose tampered row was said
    # held by the one model activation under way (each builds a runner and a planning worker)
    activation: threading.Lock = field(default_factory=threading.Lock)
    # models read and built in a child process within their budget (app.station.model_budget)
    models: ModelChecks = field(default_factory=ModelChecks)

    def __post_init__(self) -> None:
        self.failure_writer = FailureWriter(self.failures, self.write_failures)

    def start(self) -> None:
        """The station loop, the audit checkpoints and the failures' summaries (the web app
        is served by the caller)."""
        self.live.start()
        if self.checkpoints is not None:
            self.checkpoints.start()
        self.failure_writer.start()

    def stop(self) -> None:
        self.models.close()
        self.failure_writer.stop()
        self.live.stop()
        if self.checkpoints is not None:
            self.checkpoints.stop()

    def write_failures(self, found: list[Summary]) -> None:
        """Summaries of failed sign-ins and bad tokens into the audit log, one per block."""
        entries = [AuditEntry(AuditKind.LOGIN, s.subject, s.user, "", s.detail()) for s in found]
        audit.write(self.store, self.live.name, entries, self.live.wall())
