"""Budgets for models: reading and building a supervisor in a child process, within limits.

An engineer's model can stand for far more than its text: predicates built on predicates, a
specification whose supervisor takes exponential time to synthesise (issue 26: a valid 8 KB
model took 52 s, with the station loop stalled for seconds meanwhile, since the BDD library
holds the GIL).  So the server never reads or synthesises a model it has not yet seen within
bounds: a child process does, under a memory limit (`RLIMIT_AS`) and at a lower priority,
and is ended once it runs past its time.  The server then builds the version from the
supervisor cache the child filled (`app.station.supervisor_cache`), which takes a moment.

The life of one check: the child is spawned and says it is ready (imports are not counted
against the budget); the parent then waits at most the budget's seconds for the answer; a
child that runs past them is killed, and one that died (out of memory: CUDD aborts, Python
raises MemoryError) is said so.  At most `at_once` children run at a time; others wait.
"""

from __future__ import annotations

import multiprocessing
import os
import resource
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

READY_WITHIN = 60.0  # seconds a child may take to start (imports, on a busy machine)


@dataclass(frozen=True)
class ModelBudget:
    """What one model may cost the station: `seconds` to build its supervisor, `read_seconds`
    to read it (validation), `memory` bytes of address space for either, `at_once` checks."""

    seconds: float = 60.0
    read_seconds: float = 60.0
    memory: int = 2 * 2**30
    at_once: int = 2


class OverBudget(Exception):
    """A model that cannot be read or built within the budget: `message` says which, in
    words for the engineer."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


Found = list[tuple[int, int, str]]  # (line, column, message) of each problem


@dataclass
class ModelChecks:
    """Runs the budgeted checks of models (module docstring); shared by the whole server."""

    budget: ModelBudget = field(default_factory=ModelBudget)
    slots: threading.BoundedSemaphore = field(init=False)

    def __post_init__(self) -> None:
        self.slots = threading.BoundedSemaphore(self.budget.at_once)

    def problems(self, text: str, file: str) -> Found:
        """Every problem reading `text` finds (empty when valid); OverBudget past the budget."""
        seconds = self.budget.read_seconds
        found: Found = self._run("read", text, file, None, seconds, "to read")
        return found

    def build(self, text: str, file: str, cache: Path | None) -> Found:
        """Read `text` and synthesise its supervisor into `cache`; the problems reading
        found, or OverBudget: "the supervisor is too large to build within N s"."""
        seconds = self.budget.seconds
        found: Found = self._run("build", text, file, cache, seconds, "to build")
        return found

    def _run(
        self, kind: str, text: str, file: str, cache: Path | None, seconds: float, doing: str
    ) -> Any:
        what = "the supervisor is too large" if kind == "build" else "the model is too large"
        if not self.slots.acquire(timeout=READY_WITHIN):
            raise OverBudget("other models are being checked; try again in a moment")
        context = multiprocessing.get_context("spawn")
        receive, send = context.Pipe(duplex=False)
        args = (kind, text, file, cache, self.budget.memory, seconds, send)
        process = context.Process(target=_work, args=args, name=f"model-{kind}", daemon=True)
        try:
            process.start()
            send.close()
            if not receive.poll(READY_WITHIN):
                raise OverBudget("the model could not be checked: its process did not start")
            receive.recv()  # "ready"
            if not receive.poll(seconds):
                raise OverBudget(f"{what} {doing} within {seconds:g} s")
            outcome, found = receive.recv()
        except (EOFError, OSError):  # the child died: out of memory, as a rule
            megabytes = self.budget.memory // 2**20
            raise OverBudget(f"{what} {doing} within {megabytes} MB of memory") from None
        finally:
            if process.is_alive():
                process.kill()
            process.join(timeout=10)
            receive.close()
            self.slots.release()
        if outcome == "memory":
            raise OverBudget(f"{what} {doing} within {self.budget.memory // 2**20} MB of memory")
        return found


def _limit(which: int, most: int) -> None:
    """Lower the soft and hard limit `which` to `most` (never raise it)."""
    _, hard = resource.getrlimit(which)
    limit = most if hard == resource.RLIM_INFINITY else min(most, hard)
    resource.setrlimit(which, (limit, limit))


def _work(
    kind: str, text: str, file: str, cache: Path | None, memory: int, seconds: float, send: Any
) -> None:
    """The child: limit itself, say it is ready, read (and build), answer.  Its CPU time is
    limited too, so that it ends even when its parent was killed (with -9) meanwhile."""
    _limit(resource.RLIMIT_AS, memory)
    _limit(resource.RLIMIT_CPU, int(seconds + READY_WITHIN) + 1)
    os.nice(10)  # the station loop's process comes first
    from app.station import supervisor_cache
    from planner.reading import load_station
    from planner.reading.yaml_reader import ModelError

    send.send("ready")
    try:
        station = load_station(text, file)
        if kind == "build":
            planner = supervisor_cache.planner(station.model, text, "bdd", cache)
            planner.prepare()
            supervisor_cache.remember_order(planner, text, cache)
    except ModelError as exc:
        found = [(d.location.line, d.location.column, d.message) for d in exc.diagnostics]
        send.send(("problems", found))
        return
    except MemoryError:
        send.send(("memory", []))
        return
    except Exception as exc:  # a fault of ours, said to the engineer (the server goes on)
        send.send(("problems", [(1, 1, f"the model could not be checked: {exc}")]))
        return
    send.send(("ok", []))
