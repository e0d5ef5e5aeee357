"""Running stations for the web tests: a real SQLite file, the live runner loop, and either
an in-process client or a real uvicorn server on 127.0.0.1 (for the browser)."""

from __future__ import annotations

import json
import re
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import uvicorn
from fastapi.testclient import TestClient

from app.serve import Built, build, default_cache
from app.station.model_budget import ModelBudget, ModelChecks
from app.station.running import PlanningSetup
from app.store.db import sqlite_url
from app.web import http_server
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
PASSWORDS = {"operator": "operator-demo-1", "engineer": "engineer-demo-1",
             "auditor": "auditor-demo-1", "admin": "admin-demo-1"}  # fmt: skip


def new_password(name: str) -> str:
    return f"{name}-changed-pw"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def form_token(html: str) -> str:
    found = re.search(r'name="csrf_token"\s+value="([^"]+)"', html) or re.search(
        r'name="csrf-token"\s+content="([^"]+)"', html
    )
    assert found, "no CSRF token on the page"
    return found.group(1)


def sign_in_with_forms(client: httpx.Client, name: str, first: bool) -> None:
    """Sign in through the login form; the first time, change the first-login password
    (to `new_password(name)`) as the station demands."""
    page = client.get("/login")
    password = PASSWORDS[name] if first else new_password(name)
    form = {"name": name, "password": password, "csrf_token": form_token(page.text)}
    response = client.post("/login", data=form, follow_redirects=False)
    assert response.status_code == 303, response.text
    assert (response.headers["location"] == "/password") == first
    if first:
        page = client.get("/password")
        form = {"current_password": PASSWORDS[name], "new_password": new_password(name)}
        form["repeat"] = new_password(name)
        form["csrf_token"] = form_token(page.text)
        response = client.post("/password", data=form, follow_redirects=False)
        assert response.status_code == 303, response.text


@dataclass
class RunningStation:
    built: Built
    db: Path
    url: str = ""
    uvicorn_server: uvicorn.Server | None = None
    thread: threading.Thread | None = None
    changed: set[str] = field(default_factory=set)

    @property
    def live(self) -> Any:
        return self.built.server.live

    def client(self) -> TestClient:
        return TestClient(self.built.app, base_url="http://127.0.0.1")

    def login(self, client: TestClient, name: str) -> str:
        """Sign `name` in through the forms (changing the first-login password once);
        returns the session's CSRF token."""
        sign_in_with_forms(client, name, first=name not in self.changed)
        self.changed.add(name)
        return form_token(client.get("/alarms").text)

    def token(self, client: TestClient, name: str) -> str:
        """A bearer token for the API (signs in through the forms first, for the password)."""
        if name not in self.changed:
            self.login(client, name)
        answer = client.post("/api/token", json={"name": name, "password": new_password(name)})
        assert answer.status_code == 200, answer.text
        token: str = answer.json()["token"]
        return token

    def audit_records(self, kind: str, subject: str) -> list[dict[str, Any]]:
        """The audit records of `kind` and `subject`, oldest first: who and the detail."""
        with self.built.server.store.engine.connect() as connection:
            rows = connection.exec_driver_sql(
                "SELECT user, detail FROM audit WHERE kind = ? AND subject = ? ORDER BY id",
                (kind, subject),
            ).all()
        return [{"user": user, **json.loads(detail)} for user, detail in rows]

    def wait(self, condition: Callable[[], bool], seconds: float = 30.0) -> None:
        deadline = time.monotonic() + seconds
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f"not reached within {seconds} s")
            time.sleep(0.05)

    def serve(
        self,
        head_timeout: float = http_server.HEAD_TIMEOUT,
        body_timeout: float = http_server.BODY_TIMEOUT,
    ) -> str:
        """Serve the app as `sp serve` does (app.web.http_server) on an ephemeral port of
        127.0.0.1."""
        port = free_port()
        config = http_server.config(
            self.built.app, "127.0.0.1", port, head_timeout=head_timeout, body_timeout=body_timeout
        )
        self.uvicorn_server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.uvicorn_server.run, daemon=True)
        self.thread.start()
        self.url = f"http://127.0.0.1:{port}"
        self.wait(lambda: self.uvicorn_server is not None and self.uvicorn_server.started, 20)
        return self.url

    def stop(self) -> None:
        if self.uvicorn_server is not None:
            self.uvicorn_server.should_exit = True
            if self.thread is not None:
                self.thread.join(timeout=10)
        self.built.server.stop()
        self.built.server.store.close()


# The planning budget for stations whose tests take the reject path (E2 with the removal of
# the oil filters rejected): its relaxed recovery is a search of some 30 steps that takes
# 6-14 s with operations in parallel, past the station's usual 10 s (issue 27 is to make such
# queries fast); those pages and cards are checked with time for it.
REJECT_BUDGET = 60.0


def start_station(
    directory: Path,
    period: float = 0.05,
    speed: float = 4.0,
    planning_delay: float = 0.0,
    planning_budget: float = 10.0,
    api_docs: bool = False,
    model_budget: ModelBudget | None = None,
) -> RunningStation:
    """A demo station whose simulated devices run `speed` times faster than real time (and,
    with `planning_delay`, whose every planning query takes that many seconds more, within
    `planning_budget`); `api_docs` as `sp serve --api-docs`."""
    db = directory / "station.db"
    built = build(
        MODEL,
        sqlite_url(db),
        cache=default_cache(),
        period=period,
        speed=speed,
        planning=PlanningSetup(delay=planning_delay, budget=planning_budget),
        api_docs=api_docs,
    )
    if model_budget is not None:
        built.server.models = ModelChecks(model_budget)
    station = RunningStation(built, db)
    built.server.start()
    return station
