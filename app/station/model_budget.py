"""Budgets for models: reading and building a supervisor in a child process, within limits.

An engineer's model can stand for far more than its text: predicates built on predicates, a
specification whose supervisor takes exponential time to synthesise (issue 26: a valid 8 KB
model took 52 s, with the station loop stalled for seconds meanwhile, since the BDD library
holds the GIL).  So the server never reads or synthesises a model it has not yet seen within
bounds: a child process does, under a memory limit (`RLIMIT_AS`) and at a lower priority,
and is ended once it runs past its time.  The server then builds the version from the
supervisor cache the child filled (`app.station.supervisor_cache`), which takes a moment.

The life of one check: the child (`python -m app.station.model_budget`) is started and says
it is ready (imports are not counted against the budget); the parent then waits at most the
budget's seconds for the answer; a child that runs past them is killed, and one that died
(out of memory: CUDD aborts, Python raises MemoryError) is said so.  At most `at_once`
children run at a time; others wait.  By default one core is left for the station's own
process: a lower priority keeps the children behind the loop on a machine of its own, but
on a virtual machine whose host caps its CPU time, children busy on every core get the whole
machine stopped for ~100 ms at a time, the loop with it (measured: p99 of the loop's period
during model bombs 185-200 ms with two children on two cores, 104 ms with one).

Reading (validation) is asked for far more often than building, often as someone types: so
a reading child is kept for the next one (`Reader`), and only started anew after it ran
past its time or died.  A child of its own limits each job's time with an alarm (its
default action ends the process, even inside C code), so it ends even when its parent was
killed meanwhile; and it ends when its parent closes the pipe.  Building always gets a
fresh child: what synthesis leaves in CUDD's memory is not the next model's business.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import resource
import select
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

ROOT = Path(__file__).resolve().parents[2]  # where `app` and `planner` are imported from
READY_WITHIN = 60.0  # seconds a child may take to start (imports, on a busy machine)


def spare_cores() -> int:
    """The cores this process may run on, but one (and at least one)."""
    return max(1, len(os.sched_getaffinity(0)) - 1)


@dataclass(frozen=True)
class ModelBudget:
    """What one model may cost the station: `seconds` to build its supervisor, `read_seconds`
    to read it (validation), `memory` bytes of address space for either, `at_once` checks."""

    seconds: float = 60.0
    read_seconds: float = 60.0
    memory: int = 2 * 2**30
    at_once: int = field(default_factory=spare_cores)


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
    idle: list[Reader] = field(init=False, default_factory=list)  # kept for the next read
    lock: threading.Lock = field(init=False, default_factory=threading.Lock)

    def __post_init__(self) -> None:
        self.slots = threading.BoundedSemaphore(self.budget.at_once)

    def problems(self, text: str, file: str) -> Found:
        """Every problem reading `text` finds (empty when valid); OverBudget past the budget."""
        seconds = self.budget.read_seconds
        with self._slot():
            with self.lock:
                reader = self.idle.pop() if self.idle else None
            if reader is None:
                reader = Reader(self.budget.memory)
            job = {"kind": "read", "text": text, "file": file, "cache": None}
            answer = reader.ask(job | {"seconds": seconds})
            if answer and answer["outcome"] != "memory":
                with self.lock:
                    self.idle.append(reader)
            else:
                reader.close()
        if answer is None:
            raise OverBudget(f"the model is too large to read within {seconds:g} s")
        return _found(answer, self.budget.memory, "the model is too large", "to read")

    @contextlib.contextmanager
    def _slot(self) -> Iterator[None]:
        """One of the `at_once` places for a child, held while it runs; OverBudget when none
        frees up in time."""
        if not self.slots.acquire(timeout=READY_WITHIN):
            raise OverBudget("other models are being checked; try again in a moment")
        try:
            yield
        finally:
            self.slots.release()

    def close(self) -> None:
        """End the reading children kept (the server stops)."""
        with self.lock:
            idle, self.idle = self.idle, []
        for reader in idle:
            reader.close()

    def build(self, text: str, file: str, cache: Path | None) -> Found:
        """Read `text` and synthesise its supervisor into `cache`; the problems reading
        found, or OverBudget: "the supervisor is too large to build within N s"."""
        seconds = self.budget.seconds
        found: Found = self._run("build", text, file, cache, seconds, "to build")
        return found

    def _run(
        self, kind: str, text: str, file: str, cache: Path | None, seconds: float, doing: str
    ) -> Found:
        what = "the supervisor is too large" if kind == "build" else "the model is too large"
        where = None if cache is None else str(cache)
        job: dict[str, Any] = {"kind": kind, "text": text, "file": file, "cache": where}
        job |= {"memory": self.budget.memory, "seconds": seconds}
        # a program of its own, not multiprocessing's spawn: that would import the server's
        # whole `__main__` (FastAPI and all) in each child, at the station's priority
        command = [sys.executable, "-m", "app.station.model_budget"]
        with self._slot():
            pipe = subprocess.PIPE
            child = subprocess.Popen(
                command, stdin=pipe, stdout=pipe, bufsize=0, env=_environment()
            )
            try:
                assert child.stdin is not None and child.stdout is not None
                with contextlib.suppress(BrokenPipeError):
                    child.stdin.write(json.dumps(job).encode())
                    child.stdin.close()
                if _line(child.stdout, READY_WITHIN) is None:
                    raise OverBudget("the model could not be checked: its process did not start")
                answer = _line(child.stdout, seconds)
                if answer is None:
                    raise OverBudget(f"{what} {doing} within {seconds:g} s")
            finally:
                if child.poll() is None:
                    child.kill()
                child.wait(timeout=10)
                if child.stdout is not None:
                    child.stdout.close()
        return _found(answer, self.budget.memory, what, doing)


def _found(answer: dict[str, Any], memory: int, what: str, doing: str) -> Found:
    if not answer or answer["outcome"] == "memory":  # died (CUDD aborts) or MemoryError
        raise OverBudget(f"{what} {doing} within {memory // 2**20} MB of memory")
    return [(line, column, message) for line, column, message in answer["found"]]


class Reader:
    """A reading child kept between jobs (module docstring): one job at a time."""

    def __init__(self, memory: int) -> None:
        command = [sys.executable, "-m", "app.station.model_budget", "--reader", str(memory)]
        self.child = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0, env=_environment()
        )
        self.ready = False

    def ask(self, job: dict[str, Any]) -> dict[str, Any] | None:
        """The child's answer to `job`; None past its seconds, {} when it died (it is then
        of no further use: close it)."""
        assert self.child.stdin is not None and self.child.stdout is not None
        try:
            self.child.stdin.write(json.dumps(job).encode() + b"\n")
        except (BrokenPipeError, ValueError):
            return {}
        if not self.ready:
            if _line(self.child.stdout, READY_WITHIN) is None:
                raise OverBudget("the model could not be checked: its process did not start")
            self.ready = True
        return _line(self.child.stdout, float(job["seconds"]))

    def close(self) -> None:
        if self.child.poll() is None:
            self.child.kill()
        self.child.wait(timeout=10)
        for pipe in (self.child.stdin, self.child.stdout):
            if pipe is not None:
                pipe.close()


def _environment() -> dict[str, str]:
    """The server's environment, with this repository first on the child's import path."""
    paths = [str(ROOT), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}


def _line(stream: IO[bytes], seconds: float) -> dict[str, Any] | None:
    """The child's next line (JSON) within `seconds`: None past them, {} at its end."""
    ready, _, _ = select.select([stream], [], [], seconds)
    if not ready:
        return None
    line = stream.readline()
    if not line:
        return {}
    found: dict[str, Any] = json.loads(line)
    return found


def _limit(which: int, most: int) -> None:
    """Lower the soft and hard limit `which` to `most` (never raise it)."""
    _, hard = resource.getrlimit(which)
    limit = most if hard == resource.RLIM_INFINITY else min(most, hard)
    resource.setrlimit(which, (limit, limit))


def reader(memory: int) -> None:
    """A reading child kept between jobs: one job (JSON) per line in, one answer per line out,
    each job within its seconds by an alarm; it ends when its parent closes the pipe."""
    os.nice(10)
    _limit(resource.RLIMIT_AS, memory)
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    from planner.reading import load_station

    print(json.dumps({"ready": True}), file=out, flush=True)
    for line in sys.stdin.buffer:
        job = json.loads(line)
        signal.alarm(int(job["seconds"]) + 1)  # its default action ends the process
        answer = _answer(functools.partial(load_station, job["text"], job["file"]))
        signal.alarm(0)
        print(json.dumps(answer), file=out, flush=True)


def _answer(work: Callable[[], object]) -> dict[str, Any]:
    """What `work` (reading, or reading and building) says to the parent: ok, the model's
    problems where they are, or out of memory."""
    from planner.reading.yaml_reader import ModelError

    try:
        work()
    except ModelError as exc:
        found = [(d.location.line, d.location.column, d.message) for d in exc.diagnostics]
        return {"outcome": "problems", "found": found}
    except MemoryError:
        return {"outcome": "memory", "found": []}
    except Exception as exc:  # a fault of ours, said to the engineer (the server goes on)
        return {"outcome": "problems", "found": [(1, 1, f"the model could not be checked: {exc}")]}
    return {"outcome": "ok", "found": []}


def main() -> None:
    """The child (`python -m app.station.model_budget`): lower its priority and limit itself,
    say it is ready, read (and build), answer; a job (JSON) on stdin, lines of JSON out.  Its
    CPU time is limited too, so that it ends even when its parent was killed meanwhile."""
    os.nice(10)  # the station loop's process comes first, imports included
    job = json.loads(sys.stdin.buffer.read())
    _limit(resource.RLIMIT_AS, job["memory"])
    _limit(resource.RLIMIT_CPU, int(job["seconds"] + READY_WITHIN) + 1)
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)  # what libraries print goes to stderr, not into the answer

    from app.station import model_cache, supervisor_cache
    from planner.reading import load_station

    print(json.dumps({"ready": True}), file=out, flush=True)
    text, file = job["text"], job["file"]
    cache = None if job["cache"] is None else Path(job["cache"])

    def check() -> None:
        station = load_station(text, file) if cache is None else model_cache.load(text, file, cache)
        if job["kind"] == "build":
            planner = supervisor_cache.planner(station.model, text, "bdd", cache)
            planner.prepare()
            supervisor_cache.remember_order(planner, text, cache)

    print(json.dumps(_answer(check)), file=out, flush=True)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--reader"]:
        reader(int(sys.argv[2]))
    else:
        main()
