"""The Modbus emulator process, seen through pymodbus's own client and raw sockets: every
device's register map as documented, each device's logic over the network, the control
channel's operations, and a clean exit on SIGTERM."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from hw.emulator_kit.control import ControlError, control
from hw.emulator_kit.process import EmulatorProcess, start
from hw.modbus.maps import register_map
from hw.modbus.registers import Table

HOST = "127.0.2.10"
DEVICES = {"nr": "nutrunner", "tc": "connector", "cam": "camera", "plc": "tracker"}


@pytest.fixture(scope="module")
def emulator() -> Iterator[EmulatorProcess]:
    args = [a for name, kind in DEVICES.items() for a in ("--device", f"{kind}:{name}:{HOST}:0")]
    process = start("hw.modbus.emulator.server", *args, "--delay-scale", "0.1")
    try:
        yield process
    finally:
        process.stop()


@pytest.fixture
def ask(emulator: EmulatorProcess) -> Iterator[Callable[..., dict[str, Any]]]:
    """The control channel; every device is powered on afresh, network up, for each test."""

    def ask(op: str, device: str | None = None, **fields: Any) -> dict[str, Any]:
        request = {"op": op, **({"device": device} if device else {}), **fields}
        return control(HOST, emulator.ports["control"], request)

    for name in DEVICES:
        ask("network", name, mode="up")
        ask("restart", name)
    yield ask


@pytest.fixture
def client(emulator: EmulatorProcess) -> Callable[[str], ModbusTcpClient]:
    clients: list[ModbusTcpClient] = []

    def connect(name: str) -> ModbusTcpClient:
        modbus = ModbusTcpClient(HOST, port=emulator.ports[name], timeout=0.3, retries=0)
        assert modbus.connect()
        clients.append(modbus)
        return modbus

    yield connect  # type: ignore[misc]
    for modbus in clients:
        modbus.close()


def read(modbus: ModbusTcpClient, kind: str, name: str) -> int | bool:
    point = register_map(kind).point(name)
    address = point.address
    if point.table is Table.COIL:
        return bool(modbus.read_coils(address, count=1, device_id=1).bits[0])
    if point.table is Table.DISCRETE_INPUT:
        return bool(modbus.read_discrete_inputs(address, count=1, device_id=1).bits[0])
    if point.table is Table.HOLDING_REGISTER:
        return int(modbus.read_holding_registers(address, count=1, device_id=1).registers[0])
    return int(modbus.read_input_registers(address, count=1, device_id=1).registers[0])


def until(condition: Callable[[], bool], timeout: float = 3.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("condition not reached in time")
        time.sleep(0.01)


def test_ready_line_names_every_device_and_the_control_port(emulator: EmulatorProcess) -> None:
    assert set(emulator.ports) == {*DEVICES, "control"}
    assert len(set(emulator.ports.values())) == len(emulator.ports)
    assert all(port > 0 for port in emulator.ports.values())


@pytest.mark.parametrize("name", sorted(DEVICES))
def test_every_register_reads_its_documented_initial_value_one_request_per_table(
    name: str, ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    kind = DEVICES[name]
    modbus = client(name)
    registers = register_map(kind)
    for table in Table:
        documented = registers.table(table)
        if not documented:
            continue
        count = len(documented)
        if table is Table.COIL:
            got: list[int] = list(modbus.read_coils(0, count=count, device_id=1).bits[:count])
        elif table is Table.DISCRETE_INPUT:
            got = list(modbus.read_discrete_inputs(0, count=count, device_id=1).bits[:count])
        elif table is Table.HOLDING_REGISTER:
            got = modbus.read_holding_registers(0, count=count, device_id=1).registers
        else:
            got = modbus.read_input_registers(0, count=count, device_id=1).registers
        expected = [r.initial_raw for r in documented]
        if table is Table.INPUT_REGISTER:  # the heartbeat has counted since power-on
            got, expected = got[1:], expected[1:]
        assert [int(v) for v in got] == expected, (name, table)
    # an address past the map is refused, as a real device does
    past = len(registers.table(Table.INPUT_REGISTER))
    answer = modbus.read_input_registers(past, count=1, device_id=1)
    assert answer.isError() and answer.exception_code == 2
    state = ask("state", name)
    assert state["kind"] == kind and set(state["values"]) == {r.name for r in registers}


def test_another_unit_id_is_answered_with_gateway_exception(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    answer = client("plc").read_input_registers(0, count=1, device_id=9)
    assert answer.isError() and answer.exception_code == 11


def test_heartbeat_counts_every_100_ms(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("plc")
    first = read(modbus, "tracker", "heartbeat")
    time.sleep(0.5)
    assert 3 <= int(read(modbus, "tracker", "heartbeat")) - int(first) <= 7


def test_nutrunner_runs_to_torque_and_idles_again(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("nr")
    modbus.write_register(0, 180, device_id=1)  # target torque 18.0 Nm
    modbus.write_coil(0, False, device_id=1)
    modbus.write_coil(1, True, device_id=1)
    until(lambda: bool(read(modbus, "nutrunner", "is_running")))
    assert not read(modbus, "nutrunner", "is_idle")
    until(lambda: bool(read(modbus, "nutrunner", "torque_reached")))
    assert read(modbus, "nutrunner", "torque") == 180
    assert read(modbus, "nutrunner", "status") == 0b0110
    modbus.write_coil(0, True, device_id=1)
    modbus.write_coil(1, False, device_id=1)
    until(lambda: bool(read(modbus, "nutrunner", "is_idle")))
    bits = modbus.read_discrete_inputs(0, count=4, device_id=1).bits[:4]
    assert bits == [True, False, False, False]


def test_nutrunner_nok_on_demand(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    assert ask("nok", "nr", times=1)["faults"]["nok"] == {"times": 1, "always": False}
    modbus = client("nr")
    modbus.write_coil(0, False, device_id=1)
    modbus.write_coil(1, True, device_id=1)
    until(lambda: bool(read(modbus, "nutrunner", "nok")))
    assert not read(modbus, "nutrunner", "torque_reached")
    assert ask("state", "nr")["faults"]["nok"]["times"] == 0


def test_connector_lock_unlock_and_lock_faults(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("tc")

    def sensors() -> list[bool]:
        return list(modbus.read_discrete_inputs(0, count=3, device_id=1).bits[:3])

    modbus.write_coil(1, False, device_id=1)
    modbus.write_coil(0, True, device_id=1)
    until(lambda: sensors() == [True, False, False])
    modbus.write_coil(0, False, device_id=1)
    modbus.write_coil(1, True, device_id=1)
    until(lambda: sensors() == [False, True, False])
    # a lock that never completes
    ask("lock_fails", "tc", mode="never", always=True)
    modbus.write_coil(1, False, device_id=1)
    modbus.write_coil(0, True, device_id=1)
    time.sleep(0.4)  # four lock delays
    assert sensors() == [False, True, False]
    # a lock that ends with the failure bit, cleared by the reset coil
    modbus.write_coil(0, False, device_id=1)
    modbus.write_coil(1, True, device_id=1)  # gives up the hanging lock
    ask("lock_fails", "tc", mode="failure", times=1)
    modbus.write_coil(1, False, device_id=1)
    modbus.write_coil(0, True, device_id=1)
    until(lambda: sensors() == [False, True, True])
    modbus.write_coil(2, True, device_id=1)
    until(lambda: sensors() == [True, False, False])


def test_connector_stuck_sensor_until_reset(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("tc")
    ask("stuck", "tc", name="not_connected", value=True)
    modbus.write_coil(1, False, device_id=1)
    modbus.write_coil(0, True, device_id=1)
    until(lambda: bool(read(modbus, "connector", "connected")))
    assert read(modbus, "connector", "not_connected") is True
    assert read(modbus, "connector", "status") == 0b011
    assert ask("reset", "tc")["faults"]["stuck"] == {}
    assert read(modbus, "connector", "not_connected") is False


def test_camera_locates_with_pose_misses_on_demand_and_clears(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("cam")
    ask("scene", "cam", pose=[120.5, -80.0, 300.0, 0.0, 3.1416, -0.5])
    ask("miss", "cam", times=1)

    def results() -> list[bool]:
        return list(modbus.read_discrete_inputs(0, count=2, device_id=1).bits[:2])

    modbus.write_coil(0, True, device_id=1)
    until(lambda: results() == [False, True])  # missed
    modbus.write_coil(0, False, device_id=1)
    until(lambda: results() == [False, False])
    modbus.write_coil(0, True, device_id=1)
    until(lambda: results() == [True, False])
    pose = modbus.read_input_registers(2, count=6, device_id=1).registers
    assert pose == [1205, 0x10000 - 800, 3000, 0, 3142, 0x10000 - 500]
    assert read(modbus, "camera", "scans") == 2
    modbus.write_coil(0, False, device_id=1)
    until(lambda: results() == [False, False])
    assert modbus.read_input_registers(2, count=6, device_id=1).registers == [0] * 6


def test_tracker_set_by_name_enumerations_and_raw_nonsense(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("plc")
    ask("set", "plc", values={"bp1.state": "placed", "frame.state": "on_engine"})
    ask("set", "plc", values={"agv.engine": False})
    assert modbus.read_input_registers(1, count=2, device_id=1).registers == [1, 1]
    assert read(modbus, "tracker", "agv.engine") is False
    with pytest.raises(ControlError, match="one of empty, placed, tightened"):
        ask("set", "plc", values={"bp2.state": 9})
    ask("set", "plc", values={"bp2.state": 9}, raw=True)
    assert read(modbus, "tracker", "bp2.state") == 9
    time.sleep(0.3)  # nothing changes by itself
    assert modbus.read_input_registers(1, count=3, device_id=1).registers == [1, 1, 9]


def test_control_channel_refuses_what_it_cannot_do(ask: Callable[..., dict[str, Any]]) -> None:
    with pytest.raises(ControlError, match="no device"):
        ask("state", "r9_tc")
    with pytest.raises(ControlError, match="no operation"):
        ask("explode", "nr")
    with pytest.raises(ControlError, match="has no 'nok'"):
        ask("nok", "tc", times=1)
    with pytest.raises(ControlError, match="no register"):
        ask("set", "plc", values={"bp9.state": "placed"})
    with pytest.raises(ControlError, match="has no delay"):
        ask("timing", "nr", values={"warp": 1.0})
    assert set(ask("devices")["devices"]) == set(DEVICES)


def test_network_silent_keeps_connections_but_answers_nothing_and_ignores_writes(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("nr")
    ask("network", "nr", mode="silent")
    with pytest.raises(ModbusException):
        modbus.read_input_registers(0, count=1, device_id=1)
    with pytest.raises(ModbusException):
        modbus.write_coil(1, True, device_id=1)
    assert ask("state", "nr")["values"]["run_forward"] is False
    ask("network", "nr", mode="up")
    fresh = client("nr")
    assert not fresh.read_input_registers(0, count=1, device_id=1).isError()


def test_network_refuse_closes_and_refuses_connections_on_the_same_port(
    emulator: EmulatorProcess, ask: Callable[..., dict[str, Any]]
) -> None:
    port = emulator.ports["tc"]
    with socket.create_connection((HOST, port), timeout=10.0) as link:
        ask("network", "tc", mode="refuse")
        link.settimeout(10.0)
        assert link.recv(16) == b""  # closed by the device
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection((HOST, port), timeout=10.0)
    ask("network", "tc", mode="up")
    assert ask("state", "tc")["port"] == port
    socket.create_connection((HOST, port), timeout=10.0).close()


def raw_read_input_registers(port: int) -> bytes:
    """One request on a raw socket: read input register 0 (transaction 7, unit 1)."""
    with socket.create_connection((HOST, port), timeout=10.0) as link:
        link.sendall(bytes([0, 7, 0, 0, 0, 6, 1, 4, 0, 0, 0, 1]))
        return link.recv(64)


@pytest.mark.parametrize(
    ("kind", "check"),
    [
        ("noise", lambda f: f[2:4] != b"\x00\x00"),
        ("function", lambda f: f[7] == 0x63),
        ("short", lambda f: f[7] == 4 and f[8] == 0 and len(f) == 9),
        ("wrong_id", lambda f: f[:2] == b"\x00\x08"),
        ("other_unit", lambda f: f[:2] == b"\x00\x07" and f[6] == 2 and f[7:9] == b"\x04\x02"),
    ],
)
def test_garbage_answers_are_malformed_as_documented_then_good_again(
    kind: str,
    check: Callable[[bytes], bool],
    emulator: EmulatorProcess,
    ask: Callable[..., dict[str, Any]],
) -> None:
    ask("garbage", "plc", kind=kind, count=1)
    assert check(raw_read_input_registers(emulator.ports["plc"]))
    good = raw_read_input_registers(emulator.ports["plc"])
    assert good[:8] == bytes([0, 7, 0, 0, 0, 5, 1, 4]) and good[8] == 2


def test_freeze_stops_logic_and_heartbeat_and_thaw_goes_on(
    ask: Callable[..., dict[str, Any]], client: Callable[[str], ModbusTcpClient]
) -> None:
    modbus = client("nr")
    ask("freeze", "nr")
    beat = read(modbus, "nutrunner", "heartbeat")
    modbus.write_coil(0, False, device_id=1)  # the Modbus stack still takes writes
    modbus.write_coil(1, True, device_id=1)
    time.sleep(0.4)
    assert read(modbus, "nutrunner", "heartbeat") == beat
    assert read(modbus, "nutrunner", "is_idle") is True
    assert ask("state", "nr")["frozen"] is True
    ask("freeze", "nr", frozen=False)
    until(lambda: read(modbus, "nutrunner", "heartbeat") != beat)
    until(lambda: bool(read(modbus, "nutrunner", "torque_reached")))


def test_sigterm_ends_the_process_cleanly() -> None:
    process = start("hw.modbus.emulator.server", "--device", f"tracker:plc:{HOST}:0")
    try:
        process.stop()
        assert process.process.returncode == 0
    finally:
        process.stop()


def test_bad_arguments_are_refused_with_a_usage_error() -> None:
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-m", "hw.modbus.emulator.server", "--device", "toaster:t:127.0.2.10:0"],
        capture_output=True,
        text=True,
        timeout=20,
    )
    assert done.returncode == 2 and "no device kind" in done.stderr
