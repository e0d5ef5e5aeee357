"""Device-level faults played on emulated devices (issue 28): `sp run --devices` plays each
scenario of models/scenarios/devices/ in real time through ur_rtde and pymodbus, three at a
time, each on its own block of loopback addresses.

Each must end as its `expect` says: done, or stopped with `waiting_for` naming the device, the
cause and the person to act.  Whatever the fault, a forbidden state comes only from the
world (within a second of a fault), never later from what the station did, and a stop never
waits on an effect that timed out."""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
import yaml

from hw.faults import DEVICE_FAULTS
from hw.ur.emulator.launch import free_block, on_block
from tests.support.one_at_a_time import one_at_a_time
from tests.support.paths import REPOSITORY

# the module's plays may wait for the other group of device plays (one_at_a_time)
pytestmark = pytest.mark.timeout(900)
ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
DEVICES = ROOT / "models" / "demo_station.devices.yaml"
SCENARIOS = sorted((ROOT / "models" / "scenarios" / "devices").glob("*.yaml"))
PARALLEL = 3
TIME_LIMIT = 300.0


def play(path: Path, block: int, directory: Path) -> tuple[list[dict[str, Any]], str]:
    devices = directory / f"{path.stem}.devices.yaml"
    devices.write_text(on_block(DEVICES.read_text(), block))
    command = [sys.executable, "-m", "app.cli.main", "run", str(MODEL), "--json"]
    command += ["--scenario", str(path), "--devices", str(devices)]
    done = subprocess.run(
        command, capture_output=True, text=True, timeout=TIME_LIMIT, cwd=ROOT, check=False
    )
    return [json.loads(line) for line in done.stdout.splitlines() if line], done.stderr


@pytest.fixture(scope="module")
def played(
    tmp_path_factory: pytest.TempPathFactory,
) -> dict[str, tuple[list[dict[str, Any]], str]]:
    directory = tmp_path_factory.mktemp("device-faults")
    taken: set[int] = set()
    # blocks 200-239: the experiments take 40-89, serve-devices 90-119, station devices 120-199
    blocks = {p.stem: free_block(range(200, 240), taken) for p in SCENARIOS}
    with one_at_a_time("device-plays"), ThreadPoolExecutor(PARALLEL) as pool:
        runs = {p.stem: pool.submit(play, p, blocks[p.stem], directory) for p in SCENARIOS}
        return {name: run.result() for name, run in runs.items()}


def test_there_is_a_play_for_each_kind_the_issue_names() -> None:
    kinds = {
        fault["kind"]
        for path in SCENARIOS
        for fault in yaml.safe_load(path.read_text()).get("faults", [])
    }
    assert {kind.value for kind in DEVICE_FAULTS} <= kinds, kinds


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_a_device_fault_ends_as_a_good_station_would(
    played: dict[str, tuple[list[dict[str, Any]], str]], path: Path
) -> None:
    events, errors = played[path.stem]
    assert events, errors[-2000:]
    expect = yaml.safe_load(path.read_text())["expect"]
    last = events[-1]
    assert last["kind"] == expect["ends"], (last, errors[-2000:])
    if last["kind"] == "stopped":
        waiting = last["waiting_for"]
        wanted = expect["waiting_for"]
        assert [(w["who"], w["subject"]) for w in waiting] == [
            (w["who"], w["subject"]) for w in wanted
        ], waiting
        for item, want in zip(waiting, wanted, strict=True):
            assert want["says"] in item["what"], item["what"]
        late = {w["subject"] for w in waiting if "did not happen in time" in w["what"]}
        assert not [w for w in waiting if w["who"] != "engineer" and w["subject"] in late]
    faults = [e["time"] for e in events if e["kind"] == "fault"]
    for forbidden in (e for e in events if e["kind"] == "forbidden"):
        assert any(0 <= forbidden["time"] - t <= 1.0 for t in faults), forbidden


def test_a_robot_that_cannot_move_is_named_with_what_a_person_does_not_as_silent(
    played: dict[str, tuple[list[dict[str, Any]], str]],
) -> None:
    for name, says in (
        ("r1_protective_stop_on_the_way", "r1 is in a protective stop: release it"),
        ("r1_power_lost_on_the_way", "r1 has no power: power it on"),
    ):
        events, _ = played[name]
        # said as a fact of a robot that answers, not as silence after a heartbeat time-out
        # (later in the play a loaded machine may still make a driver miss its heartbeat)
        first = next(e for e in events if e["kind"] == "unavailable" and e["subject"] == "r1")
        assert says in first.get("why", "") and "silent_for" not in first, first
        assert [e for e in events if e["kind"] == "available" and e["subject"] == "r1"]


def test_a_frozen_robot_stream_finishes_no_bolt_pair_on_the_stale_pose(
    played: dict[str, tuple[list[dict[str, Any]], str]],
) -> None:
    """r1's data froze on its way from bolt pair 1 to pair 2, and the nut bit on pair 2 meanwhile:
    r1 is unavailable as soon as its driver says the data are stale, no pair is finished while
    it is, and the pair finished when it answers again is pair 2."""
    events, _ = played["r1_stream_frozen_going_down_on_bolts"]
    kinds = [(e["kind"], e["subject"]) for e in events]
    lost = kinds.index(("unavailable", "r1"))
    assert "silent_for" not in events[lost] and "does not answer" in events[lost]["why"]
    back = kinds.index(("available", "r1"), lost)
    finished = [s for k, s in kinds[lost:back] if s.startswith("nr.run_nut.finish_")]
    assert finished == []
    after = [s for k, s in kinds[back:] if s.startswith("nr.run_nut.finish_")]
    assert after[0] == "nr.run_nut.finish_bp2", after
    assert not [e for e in events if e["kind"] == "forbidden"]


def test_the_simulation_panel_offers_the_device_plays_on_emulated_devices_only() -> None:
    from app.station.experiments import experiments
    from tests.support import plays as shared

    station, _ = shared.demo()
    simulated = experiments(station)
    emulated = experiments(station, emulated=True)
    device_plays = {p.stem for p in SCENARIOS}
    assert len(simulated) == 30 and not device_plays & simulated.keys()  # E1-E9 and faults
    assert device_plays <= emulated.keys() and simulated.keys() <= emulated.keys()
    title, scenario = emulated["r1_protective_stop_on_the_way"]
    assert title == "devices: r1 protective stop on the way"
    assert [f.fault.kind.value for f in scenario.faults] == ["protective_stop"] * 2
