"""What every request handler may reach: the store, the live station, templates, throttling."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fastapi.templating import Jinja2Templates

from app.auth import ApiTokens, LoginThrottle
from app.live_station import LiveStation
from app.scenario import Scenario
from app.store.db import Store

ROOT = Path(__file__).resolve().parents[2]
TEMPLATES = ROOT / "templates"
STATIC = ROOT / "static"


@dataclass
class Server:
    store: Store
    live: LiveStation
    tokens: ApiTokens
    cache: Path | None
    throttle: LoginThrottle = field(default_factory=LoginThrottle)
    # the simulation panel's experiments: id -> (title, scenario)
    experiments: dict[str, tuple[str, Scenario]] = field(default_factory=dict)
    templates: Jinja2Templates = field(
        default_factory=lambda: Jinja2Templates(directory=str(TEMPLATES))
    )
    secure_cookies: bool = False
