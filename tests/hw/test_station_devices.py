"""The station on emulated devices: the runner never trusts a device it cannot hear.

The demo's device file, its emulators on a free block of loopback addresses, and the runner
stepped in real time on them (`StationCycle`, as the live station does).  Each resource's
devices are cut in turn (the scenario fault `disconnect`, acted out on the emulator); the
runner must mark the resource unavailable within the devices' heartbeat time-out plus its
own, and available again once it answers.  A device that answers nonsense (malformed
frames) counts as not answering.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

from app.station.cycle import StationCycle
from app.station.emulated import EmulatedStation, emulate, start_values
from hw.device_file import load_devices
from hw.device_file.spec import DeviceFile
from hw.faults import Fault, FaultKind
from hw.ur.emulator.launch import free_block, on_block
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import EventKind, Runner, RunnerConfig
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
DEVICES = ROOT / "models" / "demo_station.devices.yaml"
# the runner's heartbeat time-out above the drivers' own 1 s: which of them speaks first is then
# the design's order, not the scheduler's (test_a_robot_its_driver_calls_silent_...)
CONFIG = RunnerConfig(heartbeat_timeout=3.0, auto_intentions=frozenset())
PERIOD = 0.1


@dataclass
class Running:
    station: Station
    devices: DeviceFile
    emulated: EmulatedStation
    cycle: StationCycle

    def run_until(self, holds: object, limit: float) -> float:
        """Steps the station every period until `holds()`; the seconds it took."""
        started = time.monotonic()
        while time.monotonic() - started < limit:
            self.cycle.step(time.monotonic())
            if holds():  # type: ignore[operator]
                return time.monotonic() - started
            time.sleep(PERIOD)
        raise AssertionError(f"not within {limit} s")


@pytest.fixture(scope="module")
def running() -> Iterator[Running]:
    station = load_station(MODEL.read_text(), str(MODEL))
    text = on_block(DEVICES.read_text(), free_block(range(120, 200)))  # bench/devices.py: 200+
    devices = load_devices(text, "demo.devices.yaml", station)
    start = start_values(station, {})
    with emulate(station, devices, start) as emulated:
        assert emulated.devices.wait_until_ready(30.0) == []
        runner = Runner(
            station, TransitionPlanner(station.model), OperationPlanner(station), CONFIG
        )
        cycle = StationCycle(runner, emulated.devices, runner.initial(time.monotonic()))
        yield Running(station, devices, emulated, cycle)


CUT = ["r1", "r2", "r1_tc", "r2_tc", "r1_cam", "r2_cam", "nr"]


@pytest.mark.parametrize("resource", CUT)
def test_a_cut_device_is_unavailable_and_back_when_it_answers(
    running: Running, resource: str
) -> None:
    """How soon a cut is noticed, against each device's time-out, is in bench/devices.py."""
    state = lambda: running.cycle.state  # noqa: E731
    running.run_until(lambda: not state().unavailable, 30.0)
    running.emulated.devices.inject(Fault(FaultKind.DISCONNECT, resource=resource))
    try:
        running.run_until(lambda: resource in state().unavailable, 30.0)
        # the others carry on: on a busy machine one may miss a 1 s heartbeat and be back
        # a tick later, so what is asserted is that only the cut one stays unavailable
        running.run_until(lambda: state().unavailable == {resource}, 30.0)
        link = running.emulated.devices.links()[resource]
        assert not link.connected and link.error
    finally:  # the next test starts from a whole station even when this one failed
        running.emulated.devices.inject(Fault(FaultKind.RECONNECT, resource=resource))
    running.run_until(lambda: resource not in state().unavailable, 30.0)
    assert running.emulated.devices.links()[resource].connected


@pytest.mark.parametrize("kind", ["short", "other_unit"])
def test_a_device_that_talks_nonsense_is_not_trusted(running: Running, kind: str) -> None:
    """`other_unit`: the answers come from another unit behind the nutrunner's address."""
    state = lambda: running.cycle.state  # noqa: E731
    running.run_until(lambda: not state().unavailable, 30.0)
    running.emulated.world.request("nr", {"op": "garbage", "count": 1000, "kind": kind})
    try:
        running.run_until(lambda: "nr" in state().unavailable, 30.0)
        running.run_until(lambda: state().unavailable == {"nr"}, 30.0)  # the others carry on
        assert "nr" not in running.emulated.devices.read().heartbeats
        if kind == "other_unit":
            assert "an answer from unit 2, not 1" in running.emulated.devices.links()["nr"].error
    finally:
        running.emulated.world.request("nr", {"op": "reset"})
    running.run_until(lambda: "nr" not in state().unavailable, 30.0)


def test_people_s_changes_reach_the_runner_as_observed_product_states(running: Running) -> None:
    running.emulated.devices.inject(Fault(FaultKind.SET, values={"bp2.state": "placed"}))
    running.run_until(lambda: running.cycle.state.values["bp2.state"] == "placed", 30.0)
    running.emulated.devices.inject(Fault(FaultKind.SET, values={"mir.docked": False}))
    running.run_until(lambda: running.cycle.state.values["mir.docked"] is False, 30.0)


def test_a_silent_plc_makes_what_it_reports_stale_until_it_answers(running: Running) -> None:
    """The PLC serves no resource, so it has no heartbeat to miss: its driver's judgement
    makes its variables stale (said once, with why), and fresh again when it answers."""
    state = lambda: running.cycle.state  # noqa: E731
    running.run_until(lambda: not state().unavailable and not state().stale, 30.0)
    wired = {w.variable for d in running.devices.devices if d.name == "plc" for w in d.wires}
    running.emulated.world.request("plc", {"op": "network", "mode": "refuse"})
    try:
        running.run_until(lambda: set(state().stale) == wired and not state().unavailable, 30.0)
        assert all(why.startswith("plc does not answer: ") for why in state().stale.values())
    finally:
        running.emulated.world.request("plc", {"op": "network", "mode": "up"})
    running.run_until(lambda: not state().stale, 30.0)


def test_a_robot_its_driver_calls_silent_is_unavailable_at_once_with_why(
    running: Running,
) -> None:
    """A frozen RTDE stream: unavailable as soon as the driver judges it (its 1 s), not
    after the runner's heartbeat time-out as well; back when the data move again."""
    state = lambda: running.cycle.state  # noqa: E731
    running.run_until(lambda: not state().unavailable, 30.0)
    running.emulated.world.request("r1", {"op": "freeze", "on": True})
    try:
        said = []
        deadline = time.monotonic() + 30.0
        while not said and time.monotonic() < deadline:
            events = running.cycle.step(time.monotonic()).events
            said = [e for e in events if e.kind is EventKind.UNAVAILABLE and e.subject == "r1"]
            time.sleep(PERIOD)
        [event] = said
        assert str(event.detail["why"]).startswith("r1 does not answer: "), event
        assert "silent_for" not in event.detail  # not the runner's heartbeat time-out
    finally:
        running.emulated.world.request("r1", {"op": "freeze", "on": False})
    running.run_until(lambda: "r1" not in state().unavailable, 30.0)
