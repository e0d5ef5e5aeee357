"""Starting an emulator as its own process and knowing when it listens.

An emulator's entry point prints one JSON line on stdout once every server listens:
`{"ready": true, "ports": {NAME: PORT, ...}}` (the ports it really bound, which matters when
it was asked for port 0).  `start` waits for that line; `stop` ends the process and its
children, also after a failed test, so that no emulator outlives its user.  And should the
user itself be killed (`kill -9`, a CI time-out), the emulator notices that its stdin, a
pipe from the user, has closed, and ends too (`exit_with_parent`).
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

PARENT = "SP_EMULATOR_PARENT"  # set for an emulator whose stdin is its user's pipe


def exit_with_parent() -> None:
    """In an emulator started by `start`: end this process (SIGTERM, so that it shuts down
    as usual) once the user's end of the stdin pipe closes.  Run by hand, it does nothing."""
    if os.environ.get(PARENT) != "1":
        return

    def watch() -> None:
        # the raw descriptor, not sys.stdin: a daemon thread holding sys.stdin's lock would
        # abort the interpreter's shutdown
        while os.read(0, 4096):
            pass
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


class EmulatorFailed(RuntimeError):
    """The emulator process did not come up."""


@dataclass
class EmulatorProcess:
    """A running emulator: its process and the ports it listens on."""

    process: subprocess.Popen[bytes]
    ports: dict[str, int] = field(default_factory=dict)

    def stop(self, timeout: float = 5.0) -> None:
        if self.process.poll() is not None:
            return
        try:
            os.killpg(self.process.pid, signal.SIGTERM)
            self.process.wait(timeout)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait(timeout)

    @property
    def alive(self) -> bool:
        return self.process.poll() is None


def start(module: str, *args: str, timeout: float = 15.0) -> EmulatorProcess:
    """Runs `python -m module args...` in its own process group; returns once it is ready."""
    process = subprocess.Popen(
        [sys.executable, "-m", module, *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        start_new_session=True,
        env={**os.environ, PARENT: "1"},
    )
    emulator = EmulatorProcess(process)
    try:
        ready = _ready_line(process, timeout)
    except EmulatorFailed:
        emulator.stop()
        raise
    emulator.ports = {str(k): int(v) for k, v in ready.get("ports", {}).items()}
    return emulator


def _ready_line(process: subprocess.Popen[bytes], timeout: float) -> dict[str, Any]:
    assert process.stdout is not None
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise EmulatorFailed(f"emulator exited with code {process.returncode}")
        readable, _, _ = select.select([process.stdout], [], [], 0.1)
        if not readable:
            continue
        line = process.stdout.readline()
        if not line:
            continue
        try:
            message = json.loads(line)
        except ValueError:
            continue
        if isinstance(message, dict) and message.get("ready"):
            return message
    raise EmulatorFailed(f"emulator not ready within {timeout:.0f} s")
