"""The station loop's thread: a round every `period` seconds, and how well it keeps time.

The loop calls the station's round (`LiveStation.round`, `app.station.rounds`) and sleeps
until the next one is due; a round that fails is logged and reported (`failed`), and the
loop goes on.  A late round is not made up: the next one starts a period after it.  The
loop keeps each round's start and duration for `summary`, which the caller's thread
computes (`/healthz`, the benchmarks): the loop itself only appends three numbers.

The third is how long the loop's thread has waited for a CPU so far (Linux's run-queue
time, `/proc/thread-self/schedstat`, one 2 us read of a kept file): a round that started
late while the thread sat runnable on a busy machine is the machine's lateness, one that
started late while the thread waited on a lock or the interpreter is the station's.
"""

from __future__ import annotations

import itertools
import logging
import math
import os
import threading
import time
from collections import deque
from collections.abc import Callable

log = logging.getLogger(__name__)

HISTORY = 5000  # rounds kept for `summary`: 500 s at 0.1 s
LATE = 1.5  # a round that starts more than this many periods after the one before is late


class StationLoop:
    """Runs `step` (one round) on a thread of its own (module docstring); `clock` gives
    seconds, and station time is counted from the loop's making (`now`)."""

    def __init__(
        self,
        name: str,
        step: Callable[[], None],
        failed: Callable[[], None],
        *,
        period: float = 0.1,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.name, self.step, self.failed = name, step, failed
        self.period, self.clock = period, clock
        self.started_at = clock()
        self.thread: threading.Thread | None = None
        self.stopping = threading.Event()
        # (start, duration, seconds waited for a CPU so far): the module docstring
        self.rounds: deque[tuple[float, float, float]] = deque(maxlen=HISTORY)

    def now(self) -> float:
        """Station time: seconds since the loop was made."""
        return self.clock() - self.started_at

    @property
    def running(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    def start(self) -> None:
        self.thread = threading.Thread(target=self._run, name=f"station-{self.name}", daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.stopping.set()
        if self.thread is not None:
            self.thread.join(timeout=10)

    def _run(self) -> None:
        queued = _RunQueue()
        next_round = self.clock()
        while not self.stopping.is_set():
            started, waited = self.clock(), queued.seconds()
            try:
                self.step()
            except Exception:  # the loop must go on; the cause is logged and audited
                log.exception("station round failed")
                self.failed()
            self.rounds.append((started, self.clock() - started, waited))
            next_round += self.period
            delay = next_round - self.clock()
            if delay < 0:
                next_round = self.clock()
            self.stopping.wait(max(0.0, delay))
        queued.close()

    def summary(self, since: float | None = None) -> dict[str, float | int]:
        """How well the loop keeps its period, over the rounds kept (the last `HISTORY`) or
        those that started at or after station time `since` (`now()`'s seconds).

        On the loop's clock: `period_ms` are the gaps between successive round starts,
        `late` how many exceed `LATE` periods, `round_ms` the rounds' own durations (take,
        tick, commit, notify); `now` is the station time of this summary, to pass as `since`
        to a later one; `cpu_s` the loop thread's CPU seconds so far, `queued_s` the seconds it
        waited for a CPU over these rounds (high: the machine, not the station, was late).
        """
        rounds = tuple(self.rounds)  # one copy, under the GIL: no lock in the loop
        if since is not None:
            rounds = tuple(r for r in rounds if r[0] >= self.started_at + since)
        starts = [start for start, _, _ in rounds]
        gaps = sorted(b - a for a, b in itertools.pairwise(starts))
        took = sorted(duration for _, duration, _ in rounds)
        return {
            "now": round(self.now(), 3),
            "rounds": len(starts),
            "period_ms_p50": _ms(_percentile(gaps, 0.50)),
            "period_ms_p99": _ms(_percentile(gaps, 0.99)),
            "period_ms_max": _ms(gaps[-1] if gaps else 0.0),
            "late": sum(1 for gap in gaps if gap > LATE * self.period),
            "round_ms_p50": _ms(_percentile(took, 0.50)),
            "round_ms_p99": _ms(_percentile(took, 0.99)),
            "round_ms_max": _ms(took[-1] if took else 0.0),
            "cpu_s": round(self._cpu(), 3),
            "queued_s": round(rounds[-1][2] - rounds[0][2], 3) if rounds else 0.0,
        }

    def _cpu(self) -> float:
        """The loop thread's CPU seconds (0 when it is not running or the OS cannot say)."""
        thread = self.thread
        if thread is None or thread.ident is None or not thread.is_alive():
            return 0.0
        try:
            return time.clock_gettime(time.pthread_getcpuclockid(thread.ident))
        except (AttributeError, OSError):  # not on Linux, or the thread just ended
            return 0.0


class _RunQueue:
    """The calling thread's seconds spent runnable but not running (0 where the OS cannot
    say); made on the thread it measures."""

    def __init__(self) -> None:
        try:
            self.file: int | None = os.open("/proc/thread-self/schedstat", os.O_RDONLY)
        except OSError:
            self.file = None

    def seconds(self) -> float:
        if self.file is None:
            return 0.0
        try:  # "<on cpu ns> <waiting for a cpu ns> <time slices>"
            return int(os.pread(self.file, 64, 0).split()[1]) / 1e9
        except (OSError, IndexError, ValueError):
            return 0.0

    def close(self) -> None:
        if self.file is not None:
            os.close(self.file)


def _percentile(ordered: list[float], share: float) -> float:
    """The nearest-rank percentile of sorted values (0 when there are none)."""
    if not ordered:
        return 0.0
    return ordered[max(0, math.ceil(share * len(ordered)) - 1)]


def _ms(seconds: float) -> float:
    return round(seconds * 1000.0, 2)
