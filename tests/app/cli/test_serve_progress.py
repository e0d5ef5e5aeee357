"""A cold start says what it is doing (issue 16): `sp serve` prints each step as it begins
(the store, the model, the planners, the station, the web server), with the seconds since
start-up, and says where it listens once the port takes connections."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

from app.cli.station import progress_printer, say_when_listening
from tests.support.paths import REPOSITORY
from tests.support.stations import MODEL, free_port

ROOT = REPOSITORY
STEPS = (
    "opening the store",
    "loading the model demo_station.yaml",
    "preparing the planners of model version 1",
    "restoring the station's last state",
    "loading the experiments",
    "starting the station loop",
    "starting the web server on 127.0.0.1:",
    "listening on http://127.0.0.1:",
)


def test_sp_serve_prints_its_progress_until_it_listens(tmp_path: Path) -> None:
    port = free_port()
    command = [
        sys.executable,
        "-m",
        "app.cli.main",
        "serve",
        "--model",
        str(MODEL),
        "--port",
        str(port),
    ]
    command += ["--db", f"sqlite:///{tmp_path / 'station.db'}"]
    process = subprocess.Popen(
        command,
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    lines: list[str] = []
    try:
        assert process.stdout is not None
        deadline = time.monotonic() + 120
        for line in process.stdout:  # printed as each step begins, not at the end
            lines.append(line.rstrip())
            if "listening on" in line:
                answer = httpx.get(f"http://127.0.0.1:{port}/healthz", timeout=5)
                assert answer.status_code == 200
                break
            assert time.monotonic() < deadline, lines
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(timeout=30)
    steps = [line for line in lines if re.match(r"^\[ *\d+\.\d s\] ", line)]
    assert len(steps) == len(STEPS), lines
    for step, expected in zip(steps, STEPS, strict=True):
        assert expected in step, (step, expected)
    seconds = [float(re.findall(r"[\d.]+", step)[0]) for step in steps]
    assert seconds == sorted(seconds)


def test_the_progress_lines_carry_the_seconds_since_start(capsys: object) -> None:
    ticks = iter([10.0, 10.0, 12.25])
    say = progress_printer(lambda: next(ticks))
    say("opening the store")
    say("loading the model m.yaml")
    out = capsys.readouterr().out  # type: ignore[attr-defined]
    assert out == "[  0.0 s] opening the store\n[  2.2 s] loading the model m.yaml\n"


def test_listening_is_said_only_once_the_port_takes_connections() -> None:
    said: list[str] = []
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        port = listener.getsockname()[1]
        watcher = say_when_listening("127.0.0.1", port, said.append, seconds=5)
        time.sleep(0.3)
        assert said == []  # bound, not listening: connections are refused
        listener.listen()
        watcher.join(5)
    assert said == [f"listening on http://127.0.0.1:{port} (Ctrl-C to stop)"]
