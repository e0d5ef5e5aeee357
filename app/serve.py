"""Starting a station process: store, active model, live station, web application.

`sp serve` calls `build`, prints the seeded users, and runs uvicorn; tests do the same
through a real subprocess.  `build` says each step as it starts (`progress`): a cold start
takes some seconds, most of them synthesising the supervisor, and a silent terminal looks
like a hung one.
"""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from fastapi import FastAPI

from app.pages.cards import station_activity, task_cards
from app.people.auth import seed_demo_users
from app.people.sessions import ApiTokens
from app.people.throttle import SignInThrottle
from app.station import supervisor_cache, tampering
from app.station.experiments import experiments
from app.station.live import LiveStation
from app.station.running import DeviceSetup, PlanningSetup, simulated_devices
from app.station.view import ActiveModel, build_model
from app.store import audit, versions
from app.store.audit import AuditEntry, AuditKind
from app.store.checkpoints import Checkpointer
from app.store.db import Store, open_store
from app.store.keys import default_key_path
from app.store.sealing import check_before_start, seal_store
from app.web.app import create_app
from app.web.server import Server, parse_networks
from hw.device_file.spec import DeviceFile
from hw.devices import Devices
from hw.emulation.world import EmulatedWorld
from hw.station_devices import StationDevices
from planner.model.expressions import Value
from planner.model.station import Station
from planner.runner import RunnerConfig

log = logging.getLogger(__name__)


@dataclass
class Built:
    app: FastAPI
    server: Server
    seeded: list[tuple[str, str, str]]


def build(
    model_path: Path,
    url: str,
    *,
    station_name: str | None = None,
    cache: Path | None = None,
    period: float = 0.1,
    speed: float = 1.0,
    secure_cookies: bool = False,
    seed_users: bool = True,
    planning: PlanningSetup | None = None,
    devices: DeviceSetup | None = None,
    keys: Path | None = None,
    trusted_proxies: tuple[str, ...] = (),
    api_docs: bool = False,
    checkpoint_period: float = 60.0,
    sequential: bool = False,
    progress: Callable[[str], None] | None = None,
) -> Built:
    """Open (and migrate) the store, load the active model, restore the station, make the app.

    `planning`: in a worker process (by default), its budget, a delay for tests.
    `devices`: the station's devices (`on_devices`); by default the simulated world (the
    simulation panel and its experiments are there on all but real devices).
    `keys`: the key file (app.store.keys; by default beside a SQLite file).
    `trusted_proxies`: addresses (or networks) of reverse proxies whose X-Forwarded-For is
    believed; none by default.
    `api_docs`: serve /docs and /openapi.json (app.web.routes.api_docs); off by default.
    `sequential`: one operation at a time instead of the operation plan's partial order.
    `progress`: told each step as it starts, in words (`sp serve` prints them).
    """
    say = progress or (lambda _line: None)
    say("opening the store")
    store = _open_store(url)
    text = model_path.read_text(encoding="utf-8")
    name = station_name or _station_name(text, model_path)
    station_keys = seal_store(store, keys or default_key_path(url), name, time.time())
    check = check_before_start(store, name)
    if check.steering:
        raise tampering.refuse_start(store, name, check, time.time())
    seeded = _seed_users(store, name) if seed_users else []
    model = _active_model(store, name, text, model_path.name, cache, say)
    say("restoring the station's last state")
    config = RunnerConfig(auto_intentions=frozenset(), sequential=sequential)
    clock, devices = _scaled_clock(speed), devices or simulated_devices
    live = LiveStation(store, name, model, config=config, period=period, clock=clock,
                       planning=planning, devices=devices)  # fmt: skip
    _watch_the_task_page(live)
    if check.findings:
        live.running.notices[tampering.FOUND_KEY] = tampering.found_at_start(
            store, name, check, time.time()
        )  # before the loop starts: the alarm is there in its first round
    if live.simulated:
        say("loading the experiments E1-E9")
    server = _server(store, live, model, station_keys.cookie_secret, cache,
                     secure_cookies=secure_cookies, trusted_proxies=trusted_proxies,
                     api_docs=api_docs)  # fmt: skip
    if station_keys.checkpoints is not None:
        server.checkpoints = Checkpointer(store, name, period=checkpoint_period)
    return Built(create_app(server, station_keys.cookie_secret), server, seeded)


def _server(
    store: Store,
    live: LiveStation,
    model: ActiveModel,
    secret: str,
    cache: Path | None,
    *,
    secure_cookies: bool,
    trusted_proxies: tuple[str, ...],
    api_docs: bool,
) -> Server:
    """What every request handler may reach (`build`'s arguments of the same names)."""
    return Server(
        store,
        live,
        ApiTokens(secret),
        cache,
        throttle=SignInThrottle(),
        experiments=experiments(model.station, live.emulated) if live.simulated else {},
        secure_cookies=secure_cookies,
        trusted_proxies=parse_networks(trusted_proxies),
        api_docs=api_docs,
    )


def _open_store(url: str) -> Store:
    """The store at `url`, migrated to this version's tables."""
    store = open_store(url)
    store.upgrade()
    return store


def _watch_the_task_page(live: LiveStation) -> None:
    """The task page shows the cards, and restart mode when there are none: its area is
    announced only when one of those changes."""
    live.watch_area(
        "tasks",
        lambda view: (task_cards(view), view.state.restart_mode, station_activity(view)),
    )


def _seed_users(store: Store, name: str) -> list[tuple[str, str, str]]:
    """The demo's users on a store that has none, audited: (name, role, first password)."""

    def added(users: list[tuple[str, str, str]]) -> list[AuditEntry]:
        return [
            AuditEntry(AuditKind.USER, "added", "sp serve", "", {"name": n, "role": r})
            for n, r, _ in users
        ]

    return audit.write(store, name, added, time.time(), also=seed_demo_users) or []


def _active_model(
    store: Store, name: str, text: str, file: str, cache: Path | None, say: Callable[[str], None]
) -> ActiveModel:
    """The station's active model version (the file's text on a new store), made ready."""
    say(f"loading the model {file}")
    with store.sessions.begin() as session:
        version = versions.ensure_active(session, name, text, "sp serve")
    say(
        f"preparing the planners of model version {version.number}: its supervisor is"
        " synthesised on its first start (some seconds), later read from the cache"
    )
    return build_model(version, cache)


def on_devices(devices: DeviceFile, world: EmulatedWorld | None = None) -> DeviceSetup:
    """The station's devices from a device file: drivers for each device, with the emulated
    world behind them when the devices are emulated (faults from the simulation panel)."""

    def setup(station: Station, start: Mapping[str, Value]) -> Devices:
        return StationDevices(devices, station, start, world=world)

    return setup


def _scaled_clock(speed: float) -> Callable[[], float]:
    """The runner's clock: real time, or faster for demos and tests of simulated stations."""
    if speed == 1.0:
        return time.monotonic
    return lambda: time.monotonic() * speed


def _station_name(text: str, path: Path) -> str:
    found = re.search(r"^station:\s*([A-Za-z_][A-Za-z0-9_]*)", text, re.MULTILINE)
    return found.group(1) if found else path.stem


def default_cache() -> Path:
    return supervisor_cache.default_directory()
