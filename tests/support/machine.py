"""Programs run beside a station under test, each in a process of its own.

`stalls`: a bystander that sleeps 2 ms at a time, until its input ends, and reports every gap
over 30 ms.  A virtual machine whose host throttles it stops every process for some 100 ms
now and then; a gap the bystander saw too is the machine's, not something the station did (a
nice-0 process is not starved that long by threads of equal priority, nor by the station's
nice-10 children).  Every 10 ms it also reads how much time the host took from each virtual
CPU so far ("steal"; a throttled host may stop one CPU while the bystander runs on the
other), and, given the station's process id, how long each of that process's threads has
waited for a CPU so far (Linux's run-queue time): a thread that holds the interpreter lock
while the machine runs other work keeps the loop waiting too, and that wait is the machine's.

`bombs`: engineers' clients saving model bombs through the API from their own threads until a
deadline, as they would from other machines: not sharing the station's interpreter lock, as
they would if they ran in the test's process.

    python -m tests.support.machine stalls [PID]
    python -m tests.support.machine bombs URL TOKEN SECONDS
Each prints, when done, one JSON object: `began` (when it started sampling or saving, on the
monotonic clock) and its `found`.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import httpx

from tests.support.bombs import alias_bomb, predicate_bomb
from tests.support.paths import REPOSITORY

SAMPLE = 0.002
STALL = 0.030


def stalls(done: threading.Event, pid: int | None) -> dict[str, list[Any]]:
    """`stalls`: (start, length) on the monotonic clock (shared by every process) of each
    gap; `queued`: (when, {thread id: seconds waited for a CPU so far} of process `pid`,
    [seconds stolen from each CPU so far])."""
    found: list[tuple[float, float]] = []
    queued: list[tuple[float, dict[int, float], list[float]]] = []
    last = time.monotonic()
    for count in itertools.count():
        if done.is_set():
            break
        if count % 5 == 0:
            queued.append((time.monotonic(), {} if pid is None else waited(pid), stolen()))
        time.sleep(SAMPLE)
        now = time.monotonic()
        if now - last > STALL:
            found.append((last, now - last))
        last = now
    return {"stalls": found, "queued": queued}


def stolen() -> list[float]:
    """Seconds the host took from each CPU of this machine so far (/proc/stat, in ticks)."""
    tick = os.sysconf("SC_CLK_TCK")
    with open("/proc/stat", encoding="ascii") as stat:
        rows = [line.split() for line in stat if line.startswith("cpu") and line[3].isdigit()]
    return [int(row[8]) / tick if len(row) > 8 else 0.0 for row in rows]


def waited(pid: int) -> dict[int, float]:
    """Each thread of `pid` with its seconds spent runnable but not running."""
    found = {}
    for task in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{task}/schedstat", "rb") as stat:
                found[int(task)] = int(stat.read().split()[1]) / 1e9
        except (OSError, IndexError, ValueError):  # the thread ended meanwhile
            continue
    return found


def bombs(url: str, token: str, seconds: float) -> list[tuple[int, str]]:
    """Every (status, detail) the station answered to four clients saving bombs meanwhile."""
    texts = [predicate_bomb(30), predicate_bomb(60, "->"), alias_bomb(), alias_bomb(12, 7)]
    deadline = time.monotonic() + seconds
    headers = {"Authorization": f"Bearer {token}"}

    def save(text: str) -> list[tuple[int, str]]:
        answers: list[tuple[int, str]] = []
        with httpx.Client(base_url=url, timeout=120, headers=headers) as client:
            while not answers or time.monotonic() < deadline:
                answer = client.post("/api/models", json={"text": text, "note": "bomb"})
                answers.append((answer.status_code, str(answer.json().get("detail", ""))))
        return answers

    with ThreadPoolExecutor(max_workers=len(texts)) as pool:
        return [answer for answers in pool.map(save, texts) for answer in answers]


@dataclass
class Beside:
    """One of this module's programs running beside the test; `result()` waits for it."""

    process: subprocess.Popen[str]

    @classmethod
    def start(cls, *arguments: str) -> Beside:
        command = [sys.executable, "-m", "tests.support.machine", *arguments]
        return cls(
            subprocess.Popen(
                command, cwd=REPOSITORY, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
            )
        )

    def result(self, timeout: float = 300) -> tuple[float, Any]:
        """(began, found) as the program printed them; a program reading its input is told
        to end."""
        out, _ = self.process.communicate(timeout=timeout)
        assert self.process.returncode == 0, out
        printed = json.loads(out)
        return float(printed["began"]), printed["found"]


def main() -> None:
    program, *arguments = sys.argv[1:]
    if program == "stalls":
        done = threading.Event()
        threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
        began = time.monotonic()
        pid = int(arguments[0]) if arguments else None
        print(json.dumps({"began": began, "found": stalls(done, pid)}))
    elif program == "bombs":
        url, token, seconds = arguments
        began = time.monotonic()
        print(json.dumps({"began": began, "found": bombs(url, token, float(seconds))}))
    else:
        raise SystemExit(f"no program {program!r}: stalls or bombs")


if __name__ == "__main__":
    main()
