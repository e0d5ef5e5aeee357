"""One whole child process, timed: wall seconds, CPU seconds and peak memory, with a timeout.

Every number in the planning benchmark is of a whole process (`sp plan`, `sp check`, the Fast
Downward and SymK drivers), started from a small stdlib-only launcher: Linux carries a
parent's peak RSS into a vfork()ed child at exec, so children of the (large) benchmark process
would report its size.  The launcher waits for the child with ``wait4``, whose usage covers the
child and every descendant it waited for (the planners' drivers run their translator and
search as such children), and on timeout kills the child's whole process group, so no
translator or search binary is left running.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

_LAUNCHER = """
import json, os, signal, subprocess, sys, threading, time
spec = json.loads(sys.argv[1])
timed_out = []
def kill():
    timed_out.append(True)
    try:
        os.killpg(child.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
with open(spec["stdout"], "wb") as out, open(spec["stderr"], "wb") as err:
    started = time.perf_counter()
    child = subprocess.Popen(spec["command"], stdout=out, stderr=err, stdin=subprocess.DEVNULL,
                             cwd=spec["cwd"], start_new_session=True)
    timer = threading.Timer(spec["timeout"], kill)
    timer.start()
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - started
    timer.cancel()
try:
    os.killpg(child.pid, signal.SIGKILL)  # anything the child left behind in its group
except ProcessLookupError:
    pass
print(json.dumps({"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
                  "peak_kb": usage.ru_maxrss, "returncode": os.waitstatus_to_exitcode(status),
                  "timed_out": bool(timed_out)}))
"""


@dataclass(frozen=True)
class ProcessRun:
    """How one process ended; ``returncode`` is negative for a signal (-9 after a timeout)."""

    stdout: str
    stderr: str
    returncode: int
    wall: float  # seconds, from start to exit
    cpu: float  # user + system seconds of the process and the children it waited for
    peak_mb: float  # maximum resident set size of the process or any such child
    timed_out: bool


def run(
    command: Sequence[str],
    timeout: float,
    *,
    cwd: Path | None = None,
    env: Mapping[str, str] | None = None,
) -> ProcessRun:
    """Run `command` to its end or for at most `timeout` seconds."""
    with tempfile.TemporaryDirectory(prefix="bench-process-") as tmp:
        out, err = Path(tmp) / "stdout", Path(tmp) / "stderr"
        spec = {
            "command": [str(c) for c in command],
            "timeout": timeout,
            "cwd": str(cwd) if cwd is not None else None,
            "stdout": str(out),
            "stderr": str(err),
        }
        launched = subprocess.run(
            [sys.executable, "-c", _LAUNCHER, json.dumps(spec)],
            capture_output=True,
            text=True,
            check=True,
            env={**os.environ, **(env or {})},
        )
        report = json.loads(launched.stdout)
        return ProcessRun(
            stdout=out.read_text(errors="replace"),
            stderr=err.read_text(errors="replace"),
            returncode=report["returncode"],
            wall=report["wall"],
            cpu=report["cpu"],
            peak_mb=report["peak_kb"] / 1024,
            timed_out=report["timed_out"],
        )
