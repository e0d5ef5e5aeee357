"""Planning beside the station loop: a child process answers the runner's queries.

A planning query can take seconds, and inside the tick nothing else happens meanwhile: no
automatics, no time-outs, no heartbeats, no person's tap.  A thread would not help, since
the BDD library holds the GIL while it works.  So the live station's runner hands its queries
to this worker (`planner.runner.answers`): a process with planners of its own, built from the
model's text (the supervisor from the cache, as the station's own).  The tick asks; until the
answer is there the phase that asked waits and the rest of the tick goes on.

Each query has a time budget.  One that runs past it is answered `over_budget` (no plan
within the budget; the runner escalates as for an unreachable goal), and the worker is
replaced: a process stuck in C code cannot be interrupted, only ended.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import queue
import time
from collections import OrderedDict
from collections.abc import Callable
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from app.station import model_cache, supervisor_cache
from planner.planning.operation_planner import OperationPlanner
from planner.planning.query import PlanQuery, PlanResult, PlanStatus
from planner.runner import PlanLevel
from planner.runner.answers import Answer

log = logging.getLogger(__name__)

Key = tuple[PlanLevel, PlanQuery]
KEEP = 64  # answers kept: a phase retried in the same state asks the same queries again
WAITING = 8  # queries waiting for the worker; older ones are dropped (their phase moved on)


def serve(text: str, file: str, cache: Path | None, delay: float, jobs: Any, replies: Any) -> None:
    """The child process: build the planners, then answer jobs until told to stop."""
    station = model_cache.load(text, file, cache)
    transition = supervisor_cache.planner(station.model, text, "bdd", cache)
    transition.prepare()
    planners: dict[PlanLevel, Callable[[PlanQuery], PlanResult]] = {
        PlanLevel.TRANSITIONS: transition.plan,
        PlanLevel.OPERATIONS: OperationPlanner(station).plan,
    }
    replies.put(("ready", None, None))
    parent = os.getppid()
    while True:
        try:
            job = jobs.get(timeout=1.0)
        except queue.Empty:
            if os.getppid() != parent:
                return  # the station is gone (killed, even with -9): so is its worker
            continue
        if job is None:
            return
        number, level, query = job
        started = time.perf_counter()
        if delay:
            time.sleep(delay)  # tests: a query made slow on purpose
        result = planners[level](query)
        replies.put((number, result, (time.perf_counter() - started) * 1000))


class PlanningWorker:
    """Answers planning queries in a child process, each within `budget` seconds."""

    asynchronous = True

    def __init__(
        self,
        text: str,
        file: str,
        cache: Path | None,
        *,
        budget: float = 10.0,
        delay: float = 0.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.text, self.file, self.cache = text, file, cache
        self.budget, self.delay, self.clock = budget, delay, clock
        self.context = multiprocessing.get_context("spawn")
        self.answers: OrderedDict[Key, Answer] = OrderedDict()
        self.waiting: OrderedDict[Key, None] = OrderedDict()
        self.running: tuple[int, Key, float] | None = None
        self.numbers = 0
        self.replaced = 0  # workers ended for running past the budget
        self.start()

    def start(self) -> None:
        self.jobs: Any = self.context.Queue()
        self.replies: Any = self.context.Queue()
        self.ready = False
        self.process: BaseProcess = self.context.Process(
            target=serve,
            args=(self.text, self.file, self.cache, self.delay, self.jobs, self.replies),
            name="planning-worker",
            daemon=True,
        )
        self.process.start()

    def answer(self, level: PlanLevel, query: PlanQuery) -> Answer | None:
        key = (level, query)
        self.collect()
        if key in self.answers:
            self.answers.move_to_end(key)
            return self.answers[key]
        if self.running is None or self.running[1] != key:
            self.waiting[key] = None
            self.waiting.move_to_end(key)
            while len(self.waiting) > WAITING:
                self.waiting.popitem(last=False)
        self.dispatch()
        return None

    def collect(self) -> None:
        """Take the replies that came; end a worker whose query ran past the budget."""
        while True:
            try:
                number, result, millis = self.replies.get_nowait()
            except queue.Empty:
                break
            if number == "ready":
                self.ready = True
            elif self.running is not None and self.running[0] == number:
                self.remember(self.running[1], Answer(result, millis))
                self.running = None
        if self.running is not None and self.clock() - self.running[2] > self.budget:
            _, (level, query), _ = self.running
            log.warning("a %s query ran past its budget of %s s", level.value, self.budget)
            over = PlanResult(PlanStatus.OVER_BUDGET, max_steps=query.max_steps, engine="worker")
            self.remember((level, query), Answer(over, self.budget * 1000))
            self.running = None
            self.replaced += 1
            self.process.kill()
            self.start()
        self.dispatch()

    def dispatch(self) -> None:
        if self.running is not None or not self.ready or not self.waiting:
            return
        key, _ = self.waiting.popitem(last=True)  # the newest: its phase still asks
        self.numbers += 1
        self.jobs.put((self.numbers, key[0], key[1]))
        self.running = (self.numbers, key, self.clock())

    def remember(self, key: Key, answer: Answer) -> None:
        self.answers[key] = answer
        while len(self.answers) > KEEP:
            self.answers.popitem(last=False)

    def close(self) -> None:
        try:
            self.jobs.put(None)
            self.process.join(timeout=2)
        finally:
            if self.process.is_alive():
                self.process.kill()
