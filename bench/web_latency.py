"""How fast a state change reaches the pages: SSE latency with 1, 10 and 50 browsers.

    python -m bench.web_latency [--changes 40] [--clients 1 10 50]

Starts `sp serve` on the demo station (its own process, a fresh SQLite file), signs in, and
opens N event streams as the pages do (`/events`).  Each measurement toggles restart mode
through the API (the runner takes the action at its next tick, commits it, then announces
it) and times, for every client, from sending the request until the client has received the
`tasks` event *and* re-fetched the task fragment that now shows the change, which is what
htmx does on a page.  Prints a Markdown table of median and p99 per client count.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

from bench.planning import machine

ROOT = Path(__file__).resolve().parent.parent
PASSWORD = "engineer-bench-pw"


def start_server(directory: Path, port: int) -> subprocess.Popen[bytes]:
    command = [sys.executable, "-m", "app.cli.main", "serve", "--db", f"sqlite:///{directory}/b.db"]
    command += ["--port", str(port)]
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL, env=os.environ)
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=1).status_code == 200:
                return process
        except httpx.HTTPError:
            time.sleep(0.2)
    process.kill()
    raise SystemExit("sp serve did not start")


def sign_in(url: str) -> tuple[httpx.Cookies, str]:
    """The engineer's session cookie (first-login password changed) and an API token."""
    import re

    def token_of(html: str) -> str:
        found = re.search(r'name="csrf_token"\s+value="([^"]+)"', html)
        assert found
        return found.group(1)

    with httpx.Client(base_url=url) as client:
        page = client.get("/login")
        form = {
            "name": "engineer",
            "password": "engineer-demo-1",
            "csrf_token": token_of(page.text),
        }
        client.post("/login", data=form)
        page = client.get("/password")
        form = {"current_password": "engineer-demo-1", "new_password": PASSWORD, "repeat": PASSWORD}
        form["csrf_token"] = token_of(page.text)
        client.post("/password", data=form)
        answer = client.post("/api/token", json={"name": "engineer", "password": PASSWORD})
        answer.raise_for_status()
        return client.cookies, str(answer.json()["token"])


async def client_task(
    url: str,
    cookies: httpx.Cookies,
    ready: asyncio.Event,
    results: list[float],
    expected: list[tuple[float, bool]],
) -> None:
    """One browser: listen to /events; on each `tasks` event fetch the fragment and, when it
    shows the restart mode expected by the latest change, record the latency."""
    async with (
        httpx.AsyncClient(base_url=url, cookies=cookies, timeout=None) as http,
        http.stream("GET", "/events") as stream,
    ):
        ready.set()
        seen = 0
        event = ""
        async for line in stream.aiter_lines():
            if line.startswith("event:"):
                event = line[6:].strip()
            elif line == "" and event == "tasks":
                fragment = await http.get("/fragments/tasks")
                if seen < len(expected):
                    sent, restart = expected[seen]
                    if ("in restart mode" in fragment.text) == restart:
                        results.append(time.perf_counter() - sent)
                        seen += 1
                event = ""


async def measure(
    url: str, cookies: httpx.Cookies, token: str, clients: int, changes: int
) -> list[float]:
    results: list[float] = []
    expected: list[tuple[float, bool]] = []
    readies = [asyncio.Event() for _ in range(clients)]
    tasks = [
        asyncio.create_task(client_task(url, cookies, ready, results, expected))
        for ready in readies
    ]
    for ready in readies:
        await ready.wait()
    await asyncio.sleep(1.0)
    headers = {"Authorization": f"Bearer {token}"}
    async with httpx.AsyncClient(base_url=url, headers=headers, timeout=30) as api:
        restart = False
        for _ in range(changes):
            restart = not restart
            body = {"mode": "enter" if restart else "leave", "reason": "latency benchmark"}
            target = len(results) + clients
            expected.append((time.perf_counter(), restart))
            (await api.post("/api/restart", json=body)).raise_for_status()
            deadline = time.monotonic() + 10
            while len(results) < target and time.monotonic() < deadline:
                await asyncio.sleep(0.005)
            await asyncio.sleep(0.2)
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--changes", type=int, default=40)
    parser.add_argument("--clients", type=int, nargs="+", default=[1, 10, 50])
    parser.add_argument("--port", type=int, default=8765)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as directory:
        server = start_server(Path(directory), args.port)
        try:
            url = f"http://127.0.0.1:{args.port}"
            cookies, token = sign_in(url)
            print(f"State change to page, SSE + fragment fetch (tick period 0.1 s); {machine()}\n")
            print("| browsers | changes | median ms | p99 ms | max ms |")
            print("| --- | --- | --- | --- | --- |")
            for clients in args.clients:
                times = asyncio.run(measure(url, cookies, token, clients, args.changes))
                times.sort()
                expected = clients * args.changes
                if len(times) < expected:
                    print(f"(only {len(times)} of {expected} updates arrived)", file=sys.stderr)
                p99 = times[min(len(times) - 1, int(len(times) * 0.99))]
                print(
                    f"| {clients} | {args.changes} | {statistics.median(times) * 1000:.0f} "
                    f"| {p99 * 1000:.0f} | {times[-1] * 1000:.0f} |"
                )
        finally:
            server.terminate()
            server.wait(timeout=10)


if __name__ == "__main__":
    main()
