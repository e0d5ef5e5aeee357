"""Seed 000's experiments E1-E9 through the real protocols: `sp run --devices` plays each
scenario in real time on emulated UR controllers (ur_rtde) and Modbus devices (pymodbus),
and each must end as its simulated run does, with the paper's recovery types and the
operator's work (the same checks as tests/planner/runner/test_runner.py).

Each experiment runs in its own `sp run` process on its own block of loopback addresses
(127.0.N.x, the demo device file moved there), three at a time: about half a minute each.
"""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from app.station.recovery_types import as_the_paper, label, operator_work, recovery
from app.station.scenario import load_scenario
from hw.ur.emulator.launch import free_block, on_block
from planner.reading import load_station
from tests.support.one_at_a_time import one_at_a_time
from tests.support.paths import REPOSITORY

# the module's plays may wait for the other group of device plays (one_at_a_time)
pytestmark = pytest.mark.timeout(1800)
ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
DEVICES = ROOT / "models" / "demo_station.devices.yaml"
SCENARIOS = ROOT / "models" / "scenarios"
EXPERIMENTS = sorted(p.stem for p in SCENARIOS.glob("e[1-9]_*.yaml"))
PARALLEL = 3
# a play takes half a minute on a quiet machine; on a shared, busy one E7 once took over 240 s
TIME_LIMIT = 420.0


@dataclass
class Event:
    """An event of `sp run --json`, in the shape tests/planner/runner/test_runner.py's checks
    read."""

    kind: str
    subject: str
    detail: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_json(cls, line: str) -> Event:
        data = json.loads(line)
        return cls(data.pop("kind"), data.pop("subject"), data)


def play(name: str, block: int, directory: Path) -> tuple[list[Event], str]:
    devices = directory / f"{name}.devices.yaml"
    devices.write_text(on_block(DEVICES.read_text(), block))
    command = [sys.executable, "-m", "app.cli.main", "run", str(MODEL), "--json"]
    command += ["--scenario", str(SCENARIOS / f"{name}.yaml"), "--devices", str(devices)]
    try:
        done = subprocess.run(
            command, capture_output=True, text=True, timeout=TIME_LIMIT, cwd=ROOT, check=False
        )
        out, errors = done.stdout, done.stderr
    except subprocess.TimeoutExpired as late:  # the test shows how far it got, and why
        out, errors = _text(late.stdout), _text(late.stderr) + f"\n{name}: {late}"
        out = out[: out.rfind("\n") + 1]  # a line cut off by the kill is not an event
    return [Event.from_json(line) for line in out.splitlines() if line], errors


def _text(captured: bytes | str | None) -> str:
    return captured.decode(errors="replace") if isinstance(captured, bytes) else captured or ""


@pytest.fixture(scope="module")
def played(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[list[Event], str]]:
    directory = tmp_path_factory.mktemp("devices")
    taken: set[int] = set()
    # blocks 40-89: tests/app/cli/test_serve_devices.py takes 90-119, test_station_devices 120-199
    blocks = {name: free_block(range(40, 90), taken) for name in EXPERIMENTS}
    with one_at_a_time("device-plays"), ThreadPoolExecutor(PARALLEL) as pool:
        runs = {name: pool.submit(play, name, blocks[name], directory) for name in EXPERIMENTS}
        return {name: run.result() for name, run in runs.items()}


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_the_experiment_recovers_on_emulated_devices_as_in_the_paper(
    played: dict[str, tuple[list[Event], str]], name: str
) -> None:
    events, errors = played[name]
    station = load_station(MODEL.read_text(), str(MODEL))
    path = SCENARIOS / f"{name}.yaml"
    scenario = load_scenario(path.read_text(), str(path), station)
    shown = [f"{e.detail.get('time')} {e.kind} {e.subject}" for e in events[-25:]]
    assert events and events[-1].kind == "done", (shown, errors[-2000:])
    ours = [label(e) for e in recovery(events)]
    paper = list(scenario.expect["recovery"])
    assert ours, "the fault caused no replanning"
    assert as_the_paper(paper, ours), ours
    assert operator_work(events) == list(scenario.expect["operator"])
    # the robots really moved: every arrival the runner took came from joint readings
    arrivals = [e for e in events if e.kind == "effect" and e.subject.endswith("goto.arrive")]
    assert len(arrivals) >= 4
