"""`sp run --devices FILE --running-emulators` plays on emulators `sp emulate FILE` already
serves (issue 28): each run puts them back to its start first, so runs can follow one
another; without the flag a serving block gets a hint, with it and nothing serving a clear
error."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from hw.ur.emulator.launch import free_block, on_block
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
DEVICES = ROOT / "models" / "demo_station.devices.yaml"
SHORT = """
intentions: [tighten_bolts]
start: {frame.state: on_engine, lift_ee.at: hanging}
until: 8
"""


def sp(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "app.cli.main", *args]
    return subprocess.run(
        command, capture_output=True, text=True, timeout=timeout, cwd=ROOT, check=False
    )


@pytest.fixture
def device_file(tmp_path: Path) -> Path:
    path = tmp_path / "devices.yaml"
    path.write_text(on_block(DEVICES.read_text(), free_block(range(90, 120))))
    return path


@pytest.fixture
def emulating(device_file: Path) -> Iterator[Path]:
    command = [sys.executable, "-m", "app.cli.main", "emulate", str(device_file)]
    command += ["--model", str(MODEL)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert process.stdout is not None
        for line in process.stdout:
            if line.startswith("emulating"):
                break
        else:
            raise AssertionError("sp emulate ended before it served")
        yield device_file
    finally:
        process.terminate()
        process.wait(30)


def test_runs_one_after_another_on_emulators_already_serving(
    emulating: Path, tmp_path: Path
) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT)
    args = ["run", str(MODEL), "--json", "--scenario", str(scenario), "--devices", str(emulating)]
    for _ in range(2):  # the second starts where the scenario says, not where the first ended
        done = sp(*args, "--running-emulators")
        events = [json.loads(line) for line in done.stdout.splitlines() if line]
        assert done.returncode == 1 and events[-1]["kind"] == "stopped", done.stderr[-2000:]
        seen = [(e["kind"], e["subject"]) for e in events]
        assert ("taken", "r1.goto_scan") in seen and ("effect", "r1.goto.arrive") in seen, seen
        assert ("unexpected", "r1.pos") not in seen  # r1 stood at home, as the start says
    # without the flag the emulators cannot start where they already serve: said with a hint
    done = sp(*args)
    assert done.returncode == 2 and "--running-emulators" in done.stderr, done.stderr


def test_running_emulators_that_do_not_serve_are_a_clear_error(device_file: Path) -> None:
    done = sp("run", str(MODEL), "--devices", str(device_file), "--running-emulators")
    assert done.returncode == 2
    assert "no running emulators to use" in done.stderr and "sp emulate" in done.stderr
    done = sp("run", str(MODEL), "--running-emulators")
    assert done.returncode == 2 and "needs --devices" in done.stderr
