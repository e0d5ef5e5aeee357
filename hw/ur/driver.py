"""The station's driver for one UR robot: ur_rtde in a supervised child process.

The station's 100 ms tick calls the parent side, which never blocks and never raises: commands
are queued and return at once, readings are the newest the child sent.  A supervisor thread
starts the child (`hw.ur.driver_child`), forwards commands, checks what comes back and starts
the child again, after a short backoff, when the connection is lost, the controller's
timestamp stops advancing for `heartbeat_timeout`, the child dies or does not come up within
`startup_timeout`.  Meanwhile the robot is unavailable.

Life cycle: `URDriver(host)` → `start()` → (`latest()`, `available`, `status()`, `move_j`,
`set_tool`, `stop_j` from the station's tick) → `close()`.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import threading
import time
from collections import deque
from collections.abc import Sequence
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any

from hw.link import LinkStatus
from hw.pipelines import Nonsense
from hw.ur import driver_child
from hw.ur.sample import URReading, reading_from

BACKOFF_FIRST = 0.2
BACKOFF_MOST = 2.0
POLL = 0.02
STOP_WAIT = 1.0


class URDriver:
    """One UR robot (`host`: its controller's address) for the station."""

    def __init__(
        self,
        host: str,
        *,
        name: str = "",
        heartbeat_timeout: float = 1.0,
        startup_timeout: float = 15.0,
    ) -> None:
        self.host = host
        self.name = name or host
        self.heartbeat_timeout = heartbeat_timeout
        self.startup_timeout = startup_timeout
        self._lock = threading.Lock()
        self._commands: deque[tuple[Any, ...]] = deque(maxlen=32)
        self._tool: tuple[Any, ...] | None = None
        self._last_move: tuple[Any, ...] | None = None
        self._latest: URReading | None = None
        self._advanced_at = 0.0
        self._latency_ms: float | None = None
        self._ready = False
        self._program_pending = False
        self._trusted = False
        self._error = "not started"
        self._command_error = ""
        self._restarts = 0
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._child: BaseProcess | None = None
        self._conn: Connection | None = None
        self._started_at = 0.0

    def start(self) -> None:
        """Starts the supervisor thread (and through it the child); returns at once."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(
            target=self._supervise, name=f"ur-driver {self.name}", daemon=True
        )
        self._thread.start()

    def close(self) -> None:
        """Stops the child and the supervisor; no process is left behind."""
        self._closing.set()
        if self._thread is not None:
            self._thread.join(STOP_WAIT + 2.0)
        self._stop_child()

    def latest(self) -> URReading | None:
        """The newest trustworthy reading (None before the first); see `available`."""
        return self._latest

    @property
    def available(self) -> bool:
        """Connected, the data make sense and the controller's timestamp advanced lately."""
        return self._ready and self._trusted and self._fresh(time.monotonic())

    def status(self) -> LinkStatus:
        latest = self._latest
        connected = self.available
        error = self._command_error if connected else (self._error or "no fresh data")
        return LinkStatus(
            connected=connected,
            latency_ms=self._latency_ms,
            last_data=latest.received if latest else None,
            error=error,
            restarts=self._restarts,
        )

    def move_j(self, q: Sequence[float], speed: float, acceleration: float) -> None:
        """An asynchronous moveJ; sent only when it differs from the last one sent."""
        values = [float(x) for x in q]
        if len(values) != 6 or not all(math.isfinite(x) for x in (*values, speed, acceleration)):
            self._command_error = f"move_j refused: {list(q)} is not 6 finite joint values"
            return
        if not (speed > 0 and acceleration > 0):
            self._command_error = "move_j refused: speed and acceleration must be positive"
            return
        command = ("move_j", tuple(values), float(speed), float(acceleration))
        with self._lock:
            if command == self._last_move:
                return
            self._last_move = command
            self._commands.append(command)

    def set_tool(self, tcp: Sequence[float], payload_kg: float) -> None:
        """Sets the TCP (6 floats, m and rad) and payload; kept and set again after a restart."""
        values = tuple(float(x) for x in tcp)
        if len(values) != 6 or not all(math.isfinite(x) for x in (*values, payload_kg)):
            self._command_error = "set_tool refused: a TCP is 6 finite values"
            return
        command = ("set_tool", values, float(payload_kg))
        with self._lock:
            self._tool = command
            self._commands.append(command)

    def forget_move(self) -> None:
        """The next `move_j` is sent even when it is the last one sent (the robot stopped
        it: a protective stop, a power loss)."""
        with self._lock:
            self._last_move = None

    def stop_j(self) -> None:
        """Stops the arm (and forgets the last target, so that it can be sent again)."""
        with self._lock:
            self._last_move = None
            self._commands.append(("stop_j",))

    def _supervise(self) -> None:
        backoff = BACKOFF_FIRST
        next_start = 0.0
        while not self._closing.is_set():
            now = time.monotonic()
            if self._child is None:
                if now >= next_start:
                    self._spawn()
                else:
                    self._closing.wait(min(next_start - now, POLL))
                continue
            problem = self._watch()
            if problem:
                self._fail(problem)
                next_start = time.monotonic() + backoff
                backoff = min(backoff * 2, BACKOFF_MOST)
            elif self._ready and self._fresh(time.monotonic()):
                backoff = BACKOFF_FIRST
        self._stop_child()

    def _spawn(self) -> None:
        context = multiprocessing.get_context("spawn")
        parent, child = context.Pipe(duplex=True)
        process = context.Process(
            target=driver_child.main,
            args=(self.host, child, self.startup_timeout),
            name=f"ur-driver-child {self.name}",
            daemon=True,
        )
        process.start()
        child.close()
        with self._lock:
            self._child, self._conn = process, parent
            self._ready = self._program_pending = False
            self._last_move = None
            self._commands.clear()
            if self._tool is not None:
                self._commands.append(self._tool)
        self._started_at = time.monotonic()

    def _watch(self) -> str:
        """Handles what the child sent and sends it commands; returns a problem or ""."""
        conn, child = self._conn, self._child
        assert conn is not None and child is not None
        try:
            while conn.poll(POLL):
                problem = self._receive(conn.recv())
                if problem:
                    return problem
                if not conn.poll():
                    break
            if self._ready:
                self._send_commands(conn)
        except (EOFError, OSError):
            return f"the driver process ended (exit code {child.exitcode})"
        now = time.monotonic()
        if not child.is_alive():
            return f"the driver process ended (exit code {child.exitcode})"
        if not self._ready and now - self._started_at > self.startup_timeout:
            return f"the robot did not start within {self.startup_timeout:.0f} s ({self._error})"
        if self._ready and not self._fresh(now):
            return (
                f"no fresh data for {self.heartbeat_timeout:.1f} s "
                "(the controller's timestamp stopped advancing or the network is down)"
            )
        return ""

    def _receive(self, message: tuple[Any, ...]) -> str:
        kind = message[0]
        if kind == "reading":
            self._reading(message[1])
        elif kind == "ready":
            # Control is up, but a reading already in flight may still show the program
            # stopped: the robot is ready with the first reading that shows it running.
            self._program_pending = True
            self._error = "starting: waiting for the control program to run"
        elif kind == "phase":
            self._error = f"starting: {message[1]}"
        elif kind == "error":
            self._command_error = str(message[1])
        elif kind == "fatal":
            return str(message[1])
        return ""

    def _reading(self, raw: dict[str, Any]) -> None:
        now = time.monotonic()
        try:
            reading = reading_from(raw, now)
        except Nonsense as problem:
            self._trusted = False
            self._error = f"nonsense from the robot: {problem}"
            return
        previous = self._latest
        if previous is None or reading.stamp > previous.stamp:
            self._advanced_at = now
        self._latest = reading
        self._trusted = True
        if self._program_pending and (reading.running or reading.protective_stop):
            self._program_pending = False
            self._ready = True
            self._advanced_at = now
        if self._ready:
            self._error = ""
        sampled = raw.get("sampled")
        if isinstance(sampled, float):
            self._latency_ms = max(now - sampled, 0.0) * 1000.0

    def _send_commands(self, conn: Connection) -> None:
        while True:
            with self._lock:
                if not self._commands:
                    return
                command = self._commands.popleft()
            conn.send(command)

    def _fresh(self, now: float) -> bool:
        return now - self._advanced_at <= self.heartbeat_timeout

    def _fail(self, problem: str) -> None:
        self._error = problem
        self._stop_child()
        self._restarts += 1

    def _stop_child(self) -> None:
        with self._lock:
            child, conn = self._child, self._conn
            self._child, self._conn = None, None
            self._ready = self._program_pending = False
        if child is not None:
            child.terminate()
            child.join(STOP_WAIT)
            if child.is_alive():
                child.kill()
                child.join(STOP_WAIT)
        if conn is not None:
            with contextlib.suppress(OSError):
                conn.close()
