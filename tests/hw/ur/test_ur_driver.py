"""The station's UR driver against the emulator: readings, moves, faults, restarts, clean close.

One emulator and one driver serve the whole module (starting them costs about a second); each
fault test ends its fault and waits until the driver has recovered, so the next one starts
from a healthy robot.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from hw.emulator_kit.control import control
from hw.ur import driver_child
from hw.ur.driver import URDriver
from hw.ur.emulator.launch import emulate, free_host, host_range
from hw.ur.robot_state import cannot_move

HOSTS = host_range(121, 250)
JOINTS = [0.1, -1.5, 1.4, -1.2, -1.5, 0.2]
HEARTBEAT = 0.5


def until(condition: Callable[[], bool], timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


class Station:
    def __init__(self, host: str, control_port: int, driver: URDriver) -> None:
        self.host, self.control_port, self.driver = host, control_port, driver

    def op(self, **request: Any) -> dict[str, Any]:
        return control(self.host, self.control_port, request)

    def q(self) -> list[float]:
        reading = self.driver.latest()
        assert reading is not None
        return list(reading.q)

    def recovered(self, timeout: float = 10.0) -> bool:
        return until(lambda: self.driver.available, timeout)


@pytest.fixture(scope="module")
def station() -> Iterator[Station]:
    host = free_host(HOSTS)
    with emulate(host, "--joints", ",".join(map(str, JOINTS))) as emulator:
        driver = URDriver(host, name="r1", heartbeat_timeout=HEARTBEAT, startup_timeout=8.0)
        driver.start()
        try:
            yield Station(host, emulator.ports["control"], driver)
        finally:
            driver.close()


@pytest.fixture
def healthy(station: Station) -> Station:
    assert station.recovered(), station.driver.status()
    return station


def test_start_up_powers_the_robot_and_reads(healthy: Station) -> None:
    reading = healthy.driver.latest()
    assert reading is not None
    assert reading.q == pytest.approx(JOINTS)
    assert reading.robot_mode == 7 and reading.runtime_state == 2 and reading.running
    assert not reading.protective_stop and reading.steady
    status = healthy.driver.status()
    assert status.connected and status.error == ""
    assert status.last_data is not None and status.last_data <= time.monotonic()
    assert until(lambda: (healthy.driver.status().last_data or 0.0) > status.last_data)  # fresh


def test_move_j_reaches_the_target_at_limited_speed(healthy: Station) -> None:
    target = list(JOINTS)
    target[0] += 0.3
    started = time.monotonic()
    healthy.driver.move_j(target, 1.0, 4.0)
    assert until(lambda: healthy.q() != pytest.approx(JOINTS))
    assert until(lambda: healthy.q() == pytest.approx(target) and healthy.driver.latest().steady)
    took = time.monotonic() - started  # command to motion is measured in bench/devices.py
    assert took >= 0.3 / 1.0 + 1.0 / 4.0 - 0.05  # no faster than the speed limit allows
    healthy.driver.move_j(JOINTS, 1.0, 4.0)
    assert until(lambda: healthy.q() == pytest.approx(JOINTS))


def test_stop_j_and_set_tool(healthy: Station) -> None:
    healthy.driver.set_tool([0.0, 0.0, 0.2, 0.0, 0.0, 0.0], 2.5)
    assert until(lambda: healthy.op(op="state")["payload"] == 2.5)
    assert healthy.op(op="state")["tcp"] == [0.0, 0.0, 0.2, 0.0, 0.0, 0.0]
    target = list(JOINTS)
    target[2] -= 1.0
    healthy.driver.move_j(target, 0.1, 2.0)  # ten seconds on the way: stopped long before
    assert until(lambda: healthy.q()[2] < JOINTS[2] - 0.01)
    healthy.driver.stop_j()
    assert until(lambda: healthy.driver.latest().steady)
    assert target[2] < healthy.q()[2] < JOINTS[2]  # where the stop found it
    healthy.driver.move_j(JOINTS, 1.0, 4.0)
    assert until(lambda: healthy.q() == pytest.approx(JOINTS))


@pytest.mark.parametrize(
    ("fault", "end"),
    [
        ({"op": "network", "down": True, "mode": "silent"}, {"op": "network", "down": False}),
        ({"op": "network", "down": True, "mode": "refuse"}, {"op": "network", "down": False}),
        ({"op": "freeze", "on": True}, {"op": "freeze", "on": False}),
    ],
    ids=["silent", "refuse", "freeze"],
)
def test_lost_data_makes_the_robot_unavailable_and_restarts(
    healthy: Station, fault: dict[str, Any], end: dict[str, Any]
) -> None:
    restarts = healthy.driver.status().restarts
    healthy.op(**fault)
    assert until(lambda: not healthy.driver.available)  # how soon: bench/devices.py
    assert not healthy.driver.status().connected
    assert healthy.driver.status().error
    assert until(lambda: healthy.driver.status().restarts > restarts)
    healthy.op(**end)
    assert healthy.recovered(), healthy.driver.status()


def test_protective_stop_shows_and_commands_fail_until_unlocked(healthy: Station) -> None:
    healthy.op(op="protective_stop")
    assert until(lambda: healthy.driver.latest().protective_stop)
    target = list(JOINTS)
    target[0] += 0.2
    healthy.driver.move_j(target, 1.0, 4.0)
    assert until(lambda: "refused" in healthy.driver.status().error)
    healthy.op(op="protective_stop", on=False)
    # the driver resumes the paused control script by itself once the stop is cleared
    assert until(lambda: healthy.driver.latest().running)
    healthy.driver.stop_j()
    healthy.driver.move_j(JOINTS, 1.0, 4.0)
    assert until(lambda: healthy.q() == pytest.approx(JOINTS) and healthy.driver.latest().steady)


def test_a_robot_that_cannot_move_says_why_from_its_rtde_fields(healthy: Station) -> None:
    """Protective stop, power off, brakes on: facts of a robot that still answers (issue
    28), each with what a person does; none once it runs again."""

    def why() -> str:
        reading = healthy.driver.latest()
        assert reading is not None
        return cannot_move("r1", reading)

    assert why() == ""
    healthy.op(op="protective_stop")
    assert until(lambda: "protective stop: release it on r1's teach pendant" in why()), why()
    assert healthy.driver.available  # it answers: a fact, not silence
    healthy.op(op="protective_stop", on=False)
    assert until(lambda: why() == ""), why()
    healthy.op(op="power", on=False)
    assert until(lambda: "r1 has no power: power it on" in why()), why()
    healthy.op(op="power", on=True)
    assert until(lambda: "brakes are on" in why()), why()
    healthy.op(op="power", on=True, brake_release=True)
    assert until(lambda: why() == "", timeout=15.0), why()
    assert healthy.recovered()


def test_a_stalled_move_never_finishes(healthy: Station) -> None:
    healthy.op(op="stall", on=True)
    target = list(JOINTS)
    target[0] += 0.4
    healthy.driver.move_j(target, 1.0, 4.0)
    assert until(lambda: healthy.op(op="state")["goal"] == pytest.approx(target))
    time.sleep(0.6)  # a move it would have finished by now
    assert healthy.driver.latest().steady
    assert healthy.q()[0] < target[0] - 0.1
    healthy.op(op="stall", on=False)
    assert until(lambda: healthy.q() == pytest.approx(target))
    healthy.driver.move_j(JOINTS, 1.0, 4.0)
    assert until(lambda: healthy.q() == pytest.approx(JOINTS))


def test_a_push_shows_and_nonsense_is_not_trusted(healthy: Station) -> None:
    assert until(lambda: healthy.op(op="state")["goal"] is None)  # no move left to finish
    healthy.op(op="push", offset=[0.05, 0, 0, 0, 0, 0])
    assert until(lambda: healthy.q()[0] == pytest.approx(JOINTS[0] + 0.05))
    healthy.op(op="push", offset=[100.0, 0, 0, 0, 0, 0])  # no UR joint turns that far
    assert until(lambda: not healthy.driver.available)
    assert "nonsense" in healthy.driver.status().error
    assert healthy.q()[0] == pytest.approx(JOINTS[0] + 0.05)  # the last trusted reading
    healthy.op(op="jog", joints=JOINTS)
    assert healthy.recovered()
    assert healthy.q() == pytest.approx(JOINTS)


def test_a_killed_child_is_restarted(healthy: Station) -> None:
    restarts = healthy.driver.status().restarts
    child = healthy.driver._child
    assert child is not None and child.pid is not None
    os.kill(child.pid, signal.SIGKILL)
    assert until(lambda: not healthy.driver.available)
    assert healthy.recovered(), healthy.driver.status()
    assert healthy.driver.status().restarts == restarts + 1


def timer_slacks(pid: int) -> dict[int, int]:
    """Each thread of a process: its timer slack in ns (Linux's /proc/TID/timerslack_ns)."""
    return {
        int(task.name): int(Path(f"/proc/{task.name}/timerslack_ns").read_text())
        for task in Path(f"/proc/{pid}/task").iterdir()
    }


def test_ur_rtdes_polling_threads_run_with_relaxed_timers_and_commands_without(
    healthy: Station,
) -> None:
    child = healthy.driver._child
    assert child is not None and child.pid is not None
    slacks = timer_slacks(child.pid)
    relaxed = round(driver_child.TIMER_SLACK * 1e9)
    # ur_rtde's receive threads, one per RTDE connection (receive and control interfaces)
    assert sum(1 for ns in slacks.values() if ns == relaxed) >= 2, slacks
    assert slacks[child.pid] == timer_slacks(os.getpid())[os.getpid()] != relaxed


def test_relaxed_timers_reach_threads_started_inside_and_give_the_caller_its_own_back() -> None:
    def own_slack() -> int:
        return int(Path(f"/proc/{threading.get_native_id()}/timerslack_ns").read_text())

    before, seen = own_slack(), []
    with driver_child.relaxed_timers(0.003):
        thread = threading.Thread(target=lambda: seen.append(own_slack()))
        thread.start()
        thread.join()
    assert seen == [3_000_000]
    assert own_slack() == before


def test_no_robot_is_unavailable_and_close_leaves_no_process() -> None:
    driver = URDriver(
        free_host(HOSTS), name="nobody", heartbeat_timeout=HEARTBEAT, startup_timeout=3.0
    )
    driver.start()
    try:
        assert until(lambda: driver.status().restarts >= 1, 20.0)
        assert not driver.available and driver.latest() is None
        assert driver.status().error
        child = driver._child
    finally:
        driver.close()
    assert not [p for p in multiprocessing.active_children() if p.name.endswith("nobody")]
    if child is not None:
        assert not child.is_alive()
