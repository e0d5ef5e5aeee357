"""The station server under load: N clients for a while, and whether the station loop keeps
its period meanwhile (issue 15).

    python -m bench.web_load [--clients 50] [--seconds 60] [--think 2.0] [--nice 0]
                             [--output bench/results/web_load.md]

Starts `sp serve` on the demo station (its own process, a fresh SQLite file in a temporary
directory, a free port), changes the demo users' first-login passwords once, signs every
client in (before the load: sign-ins are argon2), then runs the clients concurrently for
`--seconds`.  Each client is one of, in this rotation of ten:

- operator (4): a browser on the task page or the alarms page, holding its event stream
  (`/events`) as htmx does, and re-fetching `/fragments/tasks` on `tasks` and
  `/fragments/alarms` on `alarm` (on the alarms page) as those pages do;
- engineer (3): the same on the station page (its three live parts re-fetched with the
  digest they show on every `station` event, answered 204 when unchanged), the task page or
  the alarms page;
- auditor (1): the audit log page and the alarms page;
- line system (1): a bearer token; `GET /api/station` and `/api/tasks`, and every third
  step an action: restart mode entered and left, `assemble_engine` started and cancelled;
- intruder (1): sign-ins with a wrong password, by form (`POST /login`) and for a token
  (`POST /api/token`).  They all come from 127.0.0.1, so after five the address is
  throttled: 429 is the expected answer, like 401.

A browser loads a page every `--think` seconds on average (uniformly 0.5-1.5 times that),
and opens a new event stream with each page, as a browser does; line systems and intruders
take a step every half `--think`.  Every answer is timed from sending the request to its
whole body (the event stream: to its first event).  An error is a 5xx, an answer other than
the ones expected for that kind of request, a broken connection or a request over 10 s; a
refusal is an expected 4xx (409 from the runner, 401 or 429 for the intruders).

The station loop is measured from inside (`GET /healthz`: `loop`, since the load began):
the gaps between round starts and each round's duration.  CPU is read from /proc for the
server process, its station loop thread, the planning worker and this benchmark's own
process.  The clients share the machine with the server; by default at the same priority,
as another busy process on a station PC would (the planning worker in a long plan, argon2
at a sign-in); `--nice 10` runs them below it, to see the server on its own.  Prints a
Markdown report and writes it to `--output` with the machine and the date.
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import os
import random
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Awaitable, Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import httpx

from bench.devices import TICKS, children, cpu_seconds, percentile
from bench.planning import machine
from bench.runner import revision

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results"
PERIOD_MS = 100.0  # the station's round (sp serve's default --period)
LATE_MS = 150.0  # issue 15: the loop's period p99 under this
TIMEOUT = 10.0  # a request that takes longer is an error
ROTATION = (
    "operator",
    "engineer",
    "operator",
    "line system",
    "engineer",
    "operator",
    "auditor",
    "engineer",
    "operator",
    "intruder",
)
PAGES = {
    "operator": ("/", "/alarms"),
    "engineer": ("/station", "/station", "/", "/alarms"),
    "auditor": ("/audit", "/alarms"),
}
USERS = {"operator": "operator", "engineer": "engineer", "auditor": "auditor"}
LIVE_PARTS = ("status", "plans", "variables")  # the station page's parts, re-fetched on `station`
ACTIONS = (
    ("POST /api/restart", "/api/restart", {"mode": "enter", "reason": "load benchmark"}),
    ("POST /api/restart", "/api/restart", {"mode": "leave"}),
    ("POST /api/intentions/{name}/start", "/api/intentions/assemble_engine/start", None),
    ("POST /api/intentions/{name}/cancel", "/api/intentions/assemble_engine/cancel", None),
)


def password_of(user: str) -> str:
    return f"{user}-load-bench"


# -- the server ----------------------------------------------------------------------------------


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


@contextmanager
def station_server(directory: Path) -> Iterator[tuple[str, subprocess.Popen[bytes]]]:
    """`sp serve` on a fresh store in `directory`; its URL and process, stopped after."""
    port = free_port()
    command = [sys.executable, "-m", "app.cli.main", "serve", "--db", f"sqlite:///{directory}/s.db"]
    command += ["--port", str(port)]
    log = (directory / "serve.log").open("wb")
    process = subprocess.Popen(command, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 180
        while True:
            try:
                if httpx.get(f"{url}/healthz", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if process.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"sp serve did not start: {server_log(directory)[-2000:]}")
            time.sleep(0.2)
        yield url, process
    finally:
        process.terminate()
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        log.close()


def server_log(directory: Path) -> str:
    path = directory / "serve.log"
    return path.read_text(errors="replace") if path.exists() else ""


def csrf_of(html: str) -> str:
    found = re.search(r'name="csrf_token"\s+value="([^"]+)"', html)
    if found is None:
        raise RuntimeError("no CSRF token on the page")
    return found.group(1)


def change_first_password(url: str, user: str) -> None:
    """The demo user's first sign-in: the printed password, then a new one (once per user)."""
    with httpx.Client(base_url=url, timeout=30) as http:
        form = {"name": user, "password": f"{user}-demo-1"}
        form["csrf_token"] = csrf_of(http.get("/login").text)
        answer = http.post("/login", data=form)
        if answer.headers.get("location") != "/password":
            raise RuntimeError(f"first sign-in of {user}: {answer.status_code} {answer.text[:200]}")
        new = password_of(user)
        form = {"current_password": f"{user}-demo-1", "new_password": new, "repeat": new}
        form["csrf_token"] = csrf_of(http.get("/password").text)
        answer = http.post("/password", data=form)
        if answer.status_code != 303:
            raise RuntimeError(f"password change of {user}: {answer.status_code}")


# -- what the clients measure ----------------------------------------------------------------------


@dataclass
class Kind:
    """One kind of request: its latencies (s), refusals and errors."""

    expected: frozenset[int]  # statuses that are a right answer
    refusals: frozenset[int] = frozenset()  # of those, the ones that refuse (409, 401, 429)
    seconds: list[float] = field(default_factory=list)
    refused: int = 0
    errors: int = 0
    statuses: Counter[str] = field(default_factory=Counter)


@dataclass
class Load:
    """Everything the clients record; `running` is cleared when the window ends."""

    kinds: dict[str, Kind]
    running: bool = True
    events: Counter[str] = field(default_factory=Counter)  # SSE events received, by name
    problems: list[str] = field(default_factory=list)  # the first few errors, as text
    loop: dict[str, Any] = field(default_factory=dict)  # /healthz's `loop` over the window

    def answered(self, kind: str, began: float, status: int) -> None:
        if not self.running:
            return
        found = self.kinds[kind]
        found.seconds.append(time.perf_counter() - began)
        found.statuses[str(status)] += 1
        if status not in found.expected:
            self.failed(kind, f"status {status}")
        elif status in found.refusals:
            found.refused += 1

    def failed(self, kind: str, why: str) -> None:
        if not self.running:
            return
        self.kinds[kind].errors += 1
        if why.startswith("status"):
            return  # counted with its status above
        self.kinds[kind].statuses[why] += 1
        if len(self.problems) < 20:
            self.problems.append(f"{kind}: {why}")


OK = frozenset({200})
FRAGMENT = frozenset({200, 204})  # 204: the part is unchanged (the digest it sent)
ACTED = frozenset({200, 409})  # 409: the runner refused the action now
WRONG = frozenset({401, 429})  # 429: the address is throttled


def kinds() -> dict[str, Kind]:
    return {
        "GET /events (to the first event)": Kind(OK),
        "GET / (task page)": Kind(OK),
        "GET /station": Kind(OK),
        "GET /alarms": Kind(OK),
        "GET /audit": Kind(OK),
        "GET /fragments/tasks (on `tasks`)": Kind(OK),
        "GET /fragments/alarms (on `alarm`)": Kind(OK),
        "GET /station/fragments/* (on `station`)": Kind(FRAGMENT),
        "GET /api/station": Kind(OK),
        "GET /api/tasks": Kind(OK),
        "POST /api/restart": Kind(ACTED, frozenset({409})),
        "POST /api/intentions/{name}/start": Kind(ACTED, frozenset({409})),
        "POST /api/intentions/{name}/cancel": Kind(ACTED, frozenset({409})),
        "POST /login, wrong password": Kind(WRONG, WRONG),
        "POST /api/token, wrong password": Kind(WRONG, WRONG),
    }


async def timed(load: Load, kind: str, request: Callable[[], Awaitable[httpx.Response]]) -> Any:
    """The answer to `request()`, timed and classified under `kind` (None on an error)."""
    began = time.perf_counter()
    try:
        answer = await request()
    except httpx.TimeoutException:
        load.failed(kind, f"timeout ({TIMEOUT:g} s)")
        return None
    except httpx.HTTPError as exc:
        load.failed(kind, f"{type(exc).__name__}: {exc}")
        return None
    load.answered(kind, began, answer.status_code)
    return answer


# -- the clients -----------------------------------------------------------------------------------


class Browser:
    """A signed-in browser: one page at a time, its event stream, and the fragments the page
    re-fetches on events (at most one in flight per fragment and one queued, as htmx's
    `hx-sync="this:queue last"`)."""

    def __init__(self, http: httpx.AsyncClient, load: Load, role: str) -> None:
        self.http, self.load, self.role = http, load, role
        self.page = PAGES[role][0]
        self.digests: dict[str, str] = {}
        self.busy: dict[str, bool] = {}  # fragment url -> a fetch in flight; queued when True
        self.queued: set[str] = set()
        self.tasks: set[asyncio.Task[None]] = set()

    async def run(self, think: float, rng: random.Random) -> None:
        stream: asyncio.Task[None] | None = None
        try:
            while self.load.running:
                self.page = rng.choice(PAGES[self.role])
                kind = {"/": "GET / (task page)"}.get(self.page, f"GET {self.page}")
                await timed(self.load, kind, functools.partial(self.http.get, self.page))
                if stream is not None:
                    stream.cancel()
                stream = asyncio.create_task(self.events(self.page))
                await asyncio.sleep(think * rng.uniform(0.5, 1.5))
        finally:
            for task in [stream, *self.tasks]:
                if task is not None:
                    task.cancel()

    async def events(self, page: str) -> None:
        """The page's event stream until the next page; each event re-fetches what listens."""
        kind = "GET /events (to the first event)"
        began = time.perf_counter()
        name, first = "", True
        try:
            timeout = httpx.Timeout(TIMEOUT, read=40.0)  # a keep-alive comes every 15 s
            async with self.http.stream("GET", "/events", timeout=timeout) as stream:
                if stream.status_code != 200:
                    self.load.answered(kind, began, stream.status_code)
                    return
                async for line in stream.aiter_lines():
                    if line.startswith("event:"):
                        name = line[6:].strip()
                    elif line == "" and name:
                        if first:
                            self.load.answered(kind, began, 200)
                            first = False
                        if self.load.running:
                            self.load.events[name] += 1
                        self.on_event(page, name)
                        name = ""
            self.load.failed(kind, "the server ended the stream")
        except httpx.TimeoutException:
            self.load.failed(kind, "no event or keep-alive for 40 s" if not first else "timeout")
        except httpx.HTTPError as exc:
            self.load.failed(kind, f"{type(exc).__name__}: {exc}")

    def on_event(self, page: str, name: str) -> None:
        if name == "tasks" and page == "/":
            self.fetch("/fragments/tasks", "GET /fragments/tasks (on `tasks`)")
        elif name == "alarm" and page == "/alarms":
            self.fetch("/fragments/alarms", "GET /fragments/alarms (on `alarm`)")
        elif name == "station" and page == "/station":
            for part in LIVE_PARTS:
                url = f"/station/fragments/{part}"
                self.fetch(url, "GET /station/fragments/* (on `station`)", live=True)

    def fetch(self, url: str, kind: str, live: bool = False) -> None:
        if self.busy.get(url):
            self.queued.add(url)
            return
        self.busy[url] = True
        task = asyncio.create_task(self._fetch(url, kind, live))
        self.tasks.add(task)
        task.add_done_callback(self.tasks.discard)

    async def _fetch(self, url: str, kind: str, live: bool) -> None:
        try:
            while True:
                params = {"seen": self.digests.get(url, "")} if live else None
                headers = {"HX-Request": "true"}
                get = functools.partial(self.http.get, url, params=params, headers=headers)
                answer = await timed(self.load, kind, get)
                if answer is not None and answer.status_code == 200 and live:
                    found = re.search(r'data-digest="([0-9a-f]+)"', answer.text)
                    self.digests[url] = found.group(1) if found else ""
                if url not in self.queued:
                    return
                self.queued.discard(url)
        finally:
            self.busy[url] = False


async def line_system(http: httpx.AsyncClient, load: Load, step: float, rng: random.Random) -> None:
    """An MES: reads the station and the tasks, and every third step acts."""
    n = rng.randrange(len(ACTIONS))
    for k in range(10**9):
        if not load.running:
            return
        await timed(load, "GET /api/station", functools.partial(http.get, "/api/station"))
        await timed(load, "GET /api/tasks", functools.partial(http.get, "/api/tasks"))
        if k % 3 == 2:
            kind, url, body = ACTIONS[n % len(ACTIONS)]
            n += 1
            await timed(load, kind, functools.partial(http.post, url, json=body))
        await asyncio.sleep(step * rng.uniform(0.5, 1.5))


async def intruder(http: httpx.AsyncClient, load: Load, step: float, rng: random.Random) -> None:
    """Wrong passwords for real names, by form and for a token, from the bench's address."""
    csrf = csrf_of((await http.get("/login")).text)
    for k in range(10**9):
        if not load.running:
            return
        name = ("engineer", "admin", "operator")[k % 3]
        if k % 2 == 0:
            form = {"name": name, "password": f"guess-{k}", "csrf_token": csrf}
            post = functools.partial(http.post, "/login", data=form)
            await timed(load, "POST /login, wrong password", post)
        else:
            body = {"name": name, "password": f"guess-{k}"}
            post = functools.partial(http.post, "/api/token", json=body)
            await timed(load, "POST /api/token, wrong password", post)
        await asyncio.sleep(step * rng.uniform(0.5, 1.5))


async def signed_in(url: str, role: str) -> httpx.AsyncClient:
    """A client with its own session (browsers) or bearer token (line systems)."""
    # idle connections closed before uvicorn's 5 s keep-alive ends them: a request sent on one
    # the server is closing fails, where a browser would quietly send it again
    limits = httpx.Limits(max_connections=8, max_keepalive_connections=4, keepalive_expiry=4.0)
    http = httpx.AsyncClient(base_url=url, timeout=TIMEOUT, limits=limits)
    if role == "intruder":
        return http
    user = USERS.get(role, "engineer")
    if role == "line system":
        answer = await http.post("/api/token", json={"name": user, "password": password_of(user)})
        answer.raise_for_status()
        http.headers["Authorization"] = f"Bearer {answer.json()['token']}"
        return http
    form = {"name": user, "password": password_of(user)}
    form["csrf_token"] = csrf_of((await http.get("/login")).text)
    answer = await http.post("/login", data=form)
    if answer.status_code != 303 or answer.headers.get("location") != "/":
        raise RuntimeError(f"sign-in of {user}: {answer.status_code} {answer.text[:200]}")
    return http


# -- one run ---------------------------------------------------------------------------------------


@dataclass
class Usage:
    """CPU seconds so far: the server process, its children (the planning worker), the
    station loop thread (from /healthz), this benchmark's process, and the whole machine."""

    server: float
    worker: float
    loop: float
    bench: float
    machine: float

    @staticmethod
    def now(pid: int, loop_cpu: float) -> Usage:
        worker = sum(cpu_seconds(f"/proc/{child}/stat") for child in children(pid))
        server = cpu_seconds(f"/proc/{pid}/stat")
        return Usage(server, worker, loop_cpu, time.process_time(), machine_busy())


def machine_busy() -> float:
    """CPU seconds all processes have used since boot (/proc/stat: all but idle and iowait)."""
    fields = [int(n) for n in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:9]]
    user, nice, system, _idle, _iowait, irq, softirq, steal = fields
    return (user + nice + system + irq + softirq + steal) / TICKS


@dataclass
class Result:
    clients: int
    seconds: float  # the load window as measured
    think: float
    roles: Counter[str]
    kinds: dict[str, Kind]
    events: Counter[str]
    problems: list[str]
    loop: dict[str, Any]  # /healthz's loop summary over the window
    cpu: dict[str, float]  # % of one core over the window
    server_errors: list[str]  # tracebacks and errors the server logged


def health(url: str, since: float | None = None) -> dict[str, Any]:
    params = {} if since is None else {"since": since}
    answer = httpx.get(f"{url}/healthz", params=params, timeout=TIMEOUT)
    answer.raise_for_status()
    loop: dict[str, Any] = answer.json()["loop"]
    return loop


@dataclass
class Window:
    """The load window: when it began and ended (monotonic), and /healthz and CPU then."""

    began: float = 0.0
    ended: float = 0.0
    since: float = 0.0  # the station time it began, for /healthz?since=
    cpu: list[Usage] = field(default_factory=list)


async def drive(
    url: str, pid: int, clients: int, seconds: float, think: float, load: Load
) -> tuple[Counter[str], Window]:
    """Signs the clients in, then lets them run for `seconds`: the window."""
    roles = [ROTATION[k % len(ROTATION)] for k in range(clients)]
    https = []
    for role in roles:  # one at a time: each sign-in is an argon2 hash on the server
        https.append(await signed_in(url, role))
    window = Window()
    loop = await asyncio.to_thread(health, url)
    window.since, window.began = loop["now"], time.monotonic()
    window.cpu.append(Usage.now(pid, loop["cpu_s"]))
    tasks = []
    for k, (role, http) in enumerate(zip(roles, https, strict=True)):
        rng = random.Random(k)
        if role == "line system":
            tasks.append(asyncio.create_task(line_system(http, load, think / 2, rng)))
        elif role == "intruder":
            tasks.append(asyncio.create_task(intruder(http, load, think / 2, rng)))
        else:
            tasks.append(asyncio.create_task(Browser(http, load, role).run(think, rng)))
    await asyncio.sleep(seconds)
    load.running = False
    window.ended = time.monotonic()
    loop = await asyncio.to_thread(health, url, window.since)
    window.cpu.append(Usage.now(pid, loop["cpu_s"]))
    load.loop = loop
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    for http in https:
        await http.aclose()
    return Counter(roles), window


T = TypeVar("T")


def niced(nice: int, work: Callable[[], T]) -> T:
    """`work()` on a thread of its own at niceness `nice` (on Linux niceness is per thread,
    and the threads it starts inherit it), so that the caller's thread keeps its own."""
    done: list[T] = []
    failed: list[BaseException] = []

    def run() -> None:
        try:
            if nice:
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
            done.append(work())
        except BaseException as exc:  # handed to the caller's thread
            failed.append(exc)

    thread = threading.Thread(target=run, name="load-clients")
    thread.start()
    thread.join()
    if failed:
        raise failed[0]
    return done[0]


def measure(clients: int, seconds: float, think: float = 2.0, nice: int = 0) -> Result:
    """One run; `nice` > 0 runs the clients at that niceness, so that they take only the CPU
    the server leaves (as browsers on other machines would)."""
    with (
        tempfile.TemporaryDirectory(prefix="web-load-") as name,
        station_server(Path(name)) as (url, server),
    ):
        for user in USERS.values():
            change_first_password(url, user)
        load = Load(kinds())
        roles, window = niced(
            nice, lambda: asyncio.run(drive(url, server.pid, clients, seconds, think, load))
        )
        text = server_log(Path(name))
    seconds = window.ended - window.began
    before, after = window.cpu
    cpu = {
        what: 100.0 * (getattr(after, what) - getattr(before, what)) / seconds
        for what in ("server", "loop", "worker", "bench", "machine")
    }
    errors = [line for line in text.splitlines() if "Traceback" in line or "ERROR" in line]
    return Result(
        clients,
        seconds,
        think,
        roles,
        load.kinds,
        load.events,
        load.problems,
        load.loop,
        cpu,
        errors,
    )


# -- the report ------------------------------------------------------------------------------------


def report(result: Result, command: str) -> str:
    total = sum(len(k.seconds) + k.errors for k in result.kinds.values())
    errors = sum(k.errors for k in result.kinds.values())
    lines = [
        "# Station server under load",
        "",
        f"`{command}`, {time.strftime('%Y-%m-%d')}, {revision()}. Machine: {machine()}",
        "",
        f"{result.clients} clients ("
        + ", ".join(f"{n} {role}" for role, n in sorted(result.roles.items()))
        + f") for {result.seconds:.0f} s, a page every {result.think:g} s per browser on "
        f"average: {total:,} requests ({total / result.seconds:.0f}/s), {errors} errors.",
        "",
        "| request | count | errors | refused (expected) | median ms | p99 ms | max ms |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, kind in result.kinds.items():
        ms = [s * 1000.0 for s in kind.seconds]
        cells = (
            [f"{percentile(ms, 0.5):.1f}", f"{percentile(ms, 0.99):.1f}", f"{max(ms):.1f}"]
            if ms
            else ["", "", ""]
        )
        lines.append(
            f"| {name} | {len(ms)} | {kind.errors} | {kind.refused} | " + " | ".join(cells) + " |"
        )
    loop = result.loop
    met = loop["period_ms_p99"] < LATE_MS
    lines += [
        "",
        f"## The station loop over the load window (a round every {PERIOD_MS:.0f} ms)",
        "",
        f"| what | rounds | median ms | p99 ms | max ms | over {LATE_MS:.0f} ms | target | met |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
        f"| period between round starts | {loop['rounds']} | {loop['period_ms_p50']:.1f} "
        f"| {loop['period_ms_p99']:.1f} | {loop['period_ms_max']:.1f} | {loop['late']} "
        f"({100.0 * loop['late'] / max(1, loop['rounds'] - 1):.1f} %) "
        f"| p99 < {LATE_MS:.0f} ms | {'yes' if met else '**no**'} |",
        f"| round (take requests, tick, commit, notify) | {loop['rounds']} "
        f"| {loop['round_ms_p50']:.1f} | {loop['round_ms_p99']:.1f} | {loop['round_ms_max']:.1f} "
        "|  |  |  |",
        "",
        "## CPU over the window (% of one core)",
        "",
        "| process or thread | CPU % |",
        "| --- | --- |",
        f"| `sp serve`, all threads | {result.cpu['server']:.1f} |",
        f"| of which the station loop thread | {result.cpu['loop']:.1f} |",
        f"| the planning worker (process) | {result.cpu['worker']:.1f} |",
        f"| this benchmark's clients (process) | {result.cpu['bench']:.1f} |",
        f"| the whole machine, all processes (of {os.cpu_count()} cores) "
        f"| {result.cpu['machine']:.1f} |",
        "",
        "SSE events received: "
        + (", ".join(f"{name} {n:,}" for name, n in sorted(result.events.items())) or "none")
        + ".  Statuses: "
        + "; ".join(
            f"{name.split(' (')[0]}: "
            + ", ".join(f"{status} x{n}" for status, n in sorted(kind.statuses.items()))
            for name, kind in result.kinds.items()
            if kind.statuses
        )
        + ".",
    ]
    if result.problems:
        lines += ["", "First errors:", "", *(f"- {p}" for p in result.problems)]
    if result.server_errors:
        lines += ["", f"The server logged {len(result.server_errors)} errors, the first:", ""]
        lines += [f"    {line}" for line in result.server_errors[:5]]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--clients", type=int, default=50, help="%(default)s")
    parser.add_argument("--seconds", type=float, default=60.0, help="%(default)s")
    parser.add_argument("--think", type=float, default=2.0, help="s between pages (%(default)s)")
    parser.add_argument("--nice", type=int, default=0, help="the clients' niceness (%(default)s)")
    parser.add_argument("--output", type=Path, default=RESULTS / "web_load.md", help="%(default)s")
    args = parser.parse_args()
    command = f"python -m bench.web_load --clients {args.clients} --seconds {args.seconds:g}"
    if args.think != 2.0:
        command += f" --think {args.think:g}"
    if args.nice:
        command += f" --nice {args.nice}"
    text = report(measure(args.clients, args.seconds, args.think, args.nice), command)
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)


if __name__ == "__main__":
    main()
