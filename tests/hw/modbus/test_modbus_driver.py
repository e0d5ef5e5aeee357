"""The station's Modbus driver against emulator processes: reading and writing, level
commands written again after a reconnect, every network and data fault making the device
unavailable within its time-out and available again by itself, and nothing left behind."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from hw.emulator_kit.control import control
from hw.emulator_kit.process import EmulatorProcess, start
from hw.modbus import loop
from hw.modbus.driver import ModbusDriver
from hw.modbus.emulator.camera import CAMERA
from hw.modbus.emulator.connector import CONNECTOR
from hw.modbus.emulator.nutrunner import NUTRUNNER
from hw.modbus.emulator.tracker import TRACKER
from hw.modbus.registers import Point, RegisterMap, Table

HOST = "127.0.2.20"
DEVICES = {"nr": NUTRUNNER, "tc": CONNECTOR, "cam": CAMERA, "plc": TRACKER}
TIMEOUT = 0.3
HEARTBEAT_TIMEOUT = 0.6


@pytest.fixture(scope="module")
def emulator() -> Iterator[EmulatorProcess]:
    args = [
        a
        for name, registers in DEVICES.items()
        for a in ("--device", f"{registers.kind}:{name}:{HOST}:0")
    ]
    process = start("hw.modbus.emulator.server", *args, "--delay-scale", "0.1")
    try:
        yield process
    finally:
        process.stop()


@pytest.fixture
def ask(emulator: EmulatorProcess) -> Callable[..., dict[str, Any]]:
    def ask(op: str, device: str, **fields: Any) -> dict[str, Any]:
        return control(HOST, emulator.ports["control"], {"op": op, "device": device, **fields})

    for name in DEVICES:
        ask("network", name, mode="up")
        ask("restart", name)
    return ask


@pytest.fixture
def driver(emulator: EmulatorProcess) -> Iterator[Callable[..., ModbusDriver]]:
    """Makes started drivers of the emulated devices; closes them after the test."""
    made: list[ModbusDriver] = []

    def make(name: str, points: list[Point] | None = None, **options: Any) -> ModbusDriver:
        registers = DEVICES[name]
        options.setdefault("timeout", TIMEOUT)
        options.setdefault("heartbeat_timeout", HEARTBEAT_TIMEOUT)
        options.setdefault("heartbeat", registers.point("heartbeat"))
        polled = [r.point for r in registers] if points is None else points
        made.append(ModbusDriver(name, HOST, emulator.ports[name], 1, polled, **options))
        made[-1].start()
        return made[-1]

    yield make
    for each in made:
        each.close()


def until(condition: Callable[[], bool], timeout: float = 10.0) -> float:
    """Waits for `condition`; returns how long it took."""
    began = time.monotonic()
    while not condition():
        if time.monotonic() - began > timeout:
            raise AssertionError("condition not reached in time")
        time.sleep(0.005)
    return time.monotonic() - began


def received(driver: ModbusDriver) -> float:
    reading = driver.latest()
    return -1.0 if reading is None else reading.received


def named(registers: RegisterMap, driver: ModbusDriver) -> dict[str, int | bool]:
    reading = driver.latest()
    assert reading is not None
    return {registers.by_point[p].name: v for p, v in reading.values.items()}


def test_reads_every_point_with_one_request_per_table(
    ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    ask("set", "plc", values={"bp3.state": "tightened", "mir.docked": False})
    plc = driver("plc")
    assert [r.table for r in plc.reads] == [Table.DISCRETE_INPUT, Table.INPUT_REGISTER]
    until(lambda: plc.available)
    values = named(TRACKER, plc)
    assert values["bp3.state"] == 2 and values["mir.docked"] is False
    assert values["agv.engine"] is True and values["frame.state"] == 0
    status = plc.status()
    assert status.connected and status.error == "" and status.restarts == 0
    # an answer later than the time-out would have been a time-out; how fast: bench/devices.py
    assert status.latency_ms is not None and 0 < status.latency_ms <= TIMEOUT * 1000
    reading = plc.latest()
    assert reading is not None and reading.received == status.last_data


def test_writes_drive_the_device_and_readings_follow(
    ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    nr = driver("nr")
    nr.write(NUTRUNNER.point("target_torque"), 200)
    nr.write(NUTRUNNER.point("set_idle"), False)
    nr.write(NUTRUNNER.point("run_forward"), True)
    until(lambda: nr.latest() is not None and named(NUTRUNNER, nr)["torque_reached"] is True)
    values = named(NUTRUNNER, nr)
    assert values["torque"] == 200 and values["is_running"] is True
    assert values["set_idle"] is False and values["run_forward"] is True
    state = ask("state", "nr")["values"]
    assert state["target_torque"] == 20.0 and state["run_forward"] is True


def test_newest_level_per_point_wins(
    ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    cam = driver("cam")
    until(lambda: cam.available)
    for value in (True, False, True, False, True):
        cam.write(CAMERA.point("trigger"), value)
    until(lambda: named(CAMERA, cam)["located"] is True)
    assert ask("state", "cam")["values"]["trigger"] is True


def test_levels_are_written_again_after_a_reconnect(
    ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    tc = driver("tc")
    tc.write(CONNECTOR.point("unlock"), False)
    tc.write(CONNECTOR.point("lock"), True)
    until(lambda: tc.available and named(CONNECTOR, tc)["connected"] is True)
    ask("network", "tc", mode="refuse")
    until(lambda: not tc.available)
    ask("restart", "tc")  # a power cycle meanwhile: the commands are back at their initial values
    assert ask("state", "tc")["values"]["lock"] is False
    ask("network", "tc", mode="up")
    until(lambda: tc.available and named(CONNECTOR, tc)["connected"] is True)
    assert ask("state", "tc")["values"]["lock"] is True
    assert tc.status().restarts >= 1


@pytest.mark.parametrize("beat", [True, False], ids=["heartbeat", "read-back"])
def test_a_device_that_restarts_behind_an_open_connection_gets_its_commands_again(
    ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver], beat: bool
) -> None:
    """A power cycle of the tool while the link stays up (issue 28): the commands are back at
    their power-on values; the driver sees it (its heartbeat counted back, or a command reads
    another value) and writes every command again, without a reconnect."""
    options = {} if beat else {"heartbeat": None}
    tc = driver("tc", **options)
    tc.write(CONNECTOR.point("unlock"), False)
    tc.write(CONNECTOR.point("lock"), True)
    until(lambda: tc.available and named(CONNECTOR, tc)["connected"] is True)
    time.sleep(0.3)  # a few heartbeats, so that counting back is counting back
    ask("restart", "tc")
    until(lambda: ask("state", "tc")["values"]["lock"] is True, timeout=5.0)
    until(lambda: named(CONNECTOR, tc)["connected"] is True)
    status = tc.status()
    assert status.device_restarts >= 1 and status.restarts == 0, status
    said = "heartbeat counted back" if beat else "was written"
    assert said in status.device_restart, status.device_restart


def test_a_heartbeat_that_wraps_is_counting_on_not_a_restart() -> None:
    """The counter wraps from 65535 to 0: modulo 2^16 that is a step forward."""
    heartbeat = CONNECTOR.point("heartbeat")
    tc = ModbusDriver("tc", HOST, 1, 1, [heartbeat], heartbeat=heartbeat)
    tc._beat = (65534, 0.0)
    assert tc._restarted({heartbeat: 3}) == ""
    tc._beat = (812, 0.0)
    assert "counted back from 812 to 3" in tc._restarted({heartbeat: 3})


def test_write_refuses_read_only_points_and_wrong_values_at_once(
    driver: Callable[..., ModbusDriver],
) -> None:
    tc = driver("tc")
    with pytest.raises(ValueError, match="read-only"):
        tc.write(CONNECTOR.point("connected"), True)
    with pytest.raises(ValueError, match="true or false"):
        tc.write(CONNECTOR.point("lock"), 1)
    with pytest.raises(ValueError, match=r"0\.\.65535"):
        tc.write(Point(Table.HOLDING_REGISTER, 0), 70000)


@pytest.mark.parametrize("mode", ["silent", "refuse"])
def test_network_down_makes_the_device_unavailable_and_it_recovers(
    mode: str, ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    nr = driver("nr")
    until(lambda: nr.available)
    ask("network", "nr", mode=mode)
    until(lambda: not nr.available)  # how soon: bench/devices.py
    status = nr.status()
    assert not status.connected
    expected = "no answer within" if mode == "silent" else "closed|no connection"
    assert any(words in status.error for words in expected.split("|")), status.error
    time.sleep(0.3)  # it stays down while the network is
    assert not nr.available
    restarts = nr.status().restarts
    ask("network", "nr", mode="up")
    until(lambda: nr.available)
    if mode == "refuse":  # one reconnection, once the device takes connections again
        assert nr.status().restarts == restarts + 1
    else:  # reconnects while the device keeps silent; at least one
        assert nr.status().restarts >= 1


def test_freeze_stops_the_heartbeat_in_the_reading_and_makes_the_device_unavailable(
    ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    nr = driver("nr")
    unwatched = driver("nr", heartbeat=None)
    until(lambda: nr.available and unwatched.available)
    ask("freeze", "nr")
    frozen = time.monotonic()
    # one request in flight at a time: the second answer after the freeze was asked for after it
    until(lambda: received(nr) > frozen)
    first = received(nr)
    until(lambda: received(nr) > first)
    reading = nr.latest()
    assert reading is not None and reading.heartbeat_changed is not None
    until(lambda: not nr.available)
    assert "heartbeat counter stuck" in nr.status().error
    # not before the counter stood still for the heartbeat's time-out
    assert time.monotonic() - reading.heartbeat_changed >= HEARTBEAT_TIMEOUT
    later = nr.latest()
    assert later is not None and later.received > reading.received  # it still answers
    assert later.heartbeat_changed == reading.heartbeat_changed
    assert unwatched.available  # without a heartbeat point the freeze goes unseen
    ask("freeze", "nr", frozen=False)
    until(lambda: nr.available)


@pytest.mark.parametrize("kind", ["noise", "function", "short", "wrong_id", "other_unit"])
def test_malformed_answers_make_the_device_unavailable_and_it_recovers(
    kind: str, ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    plc = driver("plc")
    until(lambda: plc.available)
    ask("garbage", "plc", kind=kind, count=1)
    until(lambda: not plc.available, timeout=TIMEOUT + 0.3)
    assert "malformed answer" in plc.status().error
    until(lambda: plc.available)
    assert plc.status().restarts == 1


def test_an_answer_from_another_unit_is_refused_and_its_values_never_used(
    ask: Callable[..., dict[str, Any]], driver: Callable[..., ModbusDriver]
) -> None:
    """The right transaction's answer from unit 2 (another device behind a gateway's
    address) when the driver asked unit 1: never taken as this device's values."""
    plc = driver("plc")
    until(lambda: plc.available)
    ask("garbage", "plc", kind="other_unit", count=1000)
    until(lambda: not plc.available, timeout=TIMEOUT + 0.3)
    assert plc.status().error == "malformed answer: an answer from unit 2, not 1"
    last = plc.latest()
    time.sleep(3 * TIMEOUT)  # several more answers, each from unit 2
    assert plc.latest() is last and not plc.available
    ask("garbage", "plc", kind="other_unit", count=0)
    until(lambda: plc.available)


def test_a_modbus_exception_makes_the_device_unavailable_without_raising(
    driver: Callable[..., ModbusDriver],
) -> None:
    plc = driver("plc", points=[Point(Table.INPUT_REGISTER, 40)], heartbeat=None)
    until(lambda: plc.status().error.startswith("the device refused"))
    assert "illegal data address (Modbus exception 2)" in plc.status().error
    assert plc.latest() is None and not plc.available


def test_no_device_at_the_address_is_unavailable_and_says_so() -> None:
    lonely = ModbusDriver("ghost", "127.0.2.21", 1, 1, [Point(Table.COIL, 0)], timeout=TIMEOUT)
    lonely.start()
    try:
        until(lambda: "no connection" in lonely.status().error)
        assert lonely.latest() is None and not lonely.available
    finally:
        lonely.close()


def socket_count() -> int:
    count = 0
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):
            count += os.readlink(f"/proc/self/fd/{fd}").startswith("socket:")
    return count


def test_drivers_share_one_loop_thread_and_close_leaves_nothing(
    emulator: EmulatorProcess, ask: Callable[..., dict[str, Any]]
) -> None:
    assert not loop.running()
    before = socket_count()
    drivers = [
        ModbusDriver(name, HOST, emulator.ports[name], 1, [r.point for r in registers])
        for name, registers in DEVICES.items()
    ]
    for each in drivers:
        each.start()
    until(lambda: all(d.available for d in drivers))
    names = [t.name for t in threading.enumerate()]
    assert names.count("modbus-drivers") == 1
    assert socket_count() > before
    for each in drivers:
        each.close()
    assert not loop.running()
    assert "modbus-drivers" not in [t.name for t in threading.enumerate()]
    assert socket_count() == before
    assert drivers[0].status().error == "closed"


async def swallows_cancellations(times: int, started: threading.Event) -> None:
    """A task that goes on after its first `times` cancellations, as a coroutine does when
    `asyncio.wait_for` swallows one (Python 3.11)."""
    started.set()
    for _ in range(times):
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.sleep(3600)
    await asyncio.sleep(3600)


def test_the_last_release_ends_a_task_that_swallowed_a_cancellation() -> None:
    started = threading.Event()
    shared = loop.acquire()
    asyncio.run_coroutine_threadsafe(swallows_cancellations(1, started), shared)
    assert started.wait(5)
    loop.release()
    assert not loop.running()
    assert "modbus-drivers" not in [t.name for t in threading.enumerate()]


def test_a_task_that_never_ends_is_named_and_the_loop_still_stops(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(loop, "STOP_WAIT", 0.5)
    started = threading.Event()
    shared = loop.acquire()
    future = asyncio.run_coroutine_threadsafe(swallows_cancellations(10**6, started), shared)
    assert started.wait(5)
    with caplog.at_level(logging.WARNING, logger="hw.modbus.loop"):
        loop.release()
    assert not loop.running()
    assert "did not end when cancelled" in caplog.text
    assert not future.done() or future.cancelled()


def test_a_driver_whose_poll_swallows_its_cancellation_still_closes(
    emulator: EmulatorProcess, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the poll's pause swallows one cancellation, as pymodbus's wait_for can
    original = ModbusDriver._pause

    async def pause(self: ModbusDriver, seconds: float) -> None:
        with contextlib.suppress(asyncio.CancelledError):
            await original(self, seconds)

    monkeypatch.setattr(ModbusDriver, "_pause", pause)
    name, registers = next(iter(DEVICES.items()))
    driver = ModbusDriver(name, HOST, emulator.ports[name], 1, [r.point for r in registers])
    driver.start()
    until(lambda: driver.available)
    driver.close()
    assert not loop.running()
    assert driver.status().error == "closed"
    # it ended by itself, not by the loop's last round of cancellations
    assert driver._task is not None and driver._task.done() and not driver._task.cancelled()
