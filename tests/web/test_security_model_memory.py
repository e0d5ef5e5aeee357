"""Issue 26: on a memory-limited server a model bomb was a 500 (the loader's doubling ran
out of memory in the server itself).  A real `sp serve` under a 1 GiB address-space limit
(its model children inherit it, and take 300 MB each) answers each bomb with a 4xx in words
and goes on serving."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import httpx

from tests.support.bombs import alias_bomb, predicate_bomb, synthesis_bomb
from tests.support.paths import REPOSITORY
from tests.support.stations import MODEL, free_port, new_password, sign_in_with_forms

LIMIT = 2**30  # bytes of address space: `sp serve` peaks at some 400 MB


def _capped() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def test_a_memory_capped_server_answers_model_bombs_with_4xx(tmp_path: Path) -> None:
    port = free_port()
    command = [sys.executable, "-m", "app.cli.main", "serve", "--model", str(MODEL),
               "--port", str(port), "--db", f"sqlite:///{tmp_path / 'station.db'}",
               "--model-seconds", "3", "--model-memory", "300"]  # fmt: skip
    log = (tmp_path / "serve.log").open("w")
    env = {**os.environ, "SP_CACHE_DIR": str(tmp_path / "cache")}
    server = subprocess.Popen(
        command, cwd=REPOSITORY, stdout=log, stderr=subprocess.STDOUT, env=env,
        preexec_fn=_capped,  # the cap, set in the child between fork and exec
    )  # fmt: skip
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90
        while True:
            try:
                if httpx.get(f"{url}/healthz", timeout=2).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            assert time.monotonic() < deadline, (tmp_path / "serve.log").read_text()
            time.sleep(0.5)
        with httpx.Client(base_url=url, timeout=60) as http:
            sign_in_with_forms(http, "engineer", first=True)
            answer = http.post(
                "/api/token", json={"name": "engineer", "password": new_password("engineer")}
            )
            http.headers["Authorization"] = f"Bearer {answer.json()['token']}"
            for bomb in (predicate_bomb(28), predicate_bomb(40, "||"), alias_bomb()):
                refused = http.post("/api/models", json={"text": bomb})
                assert refused.status_code == 422, refused.text[:300]
                assert "line" in refused.json()["detail"]
            saved = http.post("/api/models", json={"text": synthesis_bomb()})
            assert saved.status_code == 201, saved.text
            activated = http.post(f"/api/models/{saved.json()['number']}/activate")
            assert activated.status_code == 422, activated.text
            assert "the supervisor is too large to build within" in activated.json()["detail"]
            health = http.get("/healthz")
            assert health.status_code == 200 and health.json()["model"] == 1
            assert http.get("/api/station").status_code == 200
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(timeout=30)
        finally:
            if server.poll() is None:
                server.kill()
            log.close()
    assert server.returncode is not None
