"""The UR emulator against the unmodified ur_rtde clients (and a raw RTDE client).

Trap: an `RTDEControlInterface` in this process must never see its connection dropped (ur_rtde
1.6.5 may crash the process), so every test disconnects its control interface before the
emulator stops, and tests where a constructor fails run the client in a subprocess.
"""

from __future__ import annotations

import itertools
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import dashboard_client
import pytest
import rtde_control
import rtde_io
import rtde_receive

from hw.emulator_kit.control import ControlError, control
from hw.ur.emulator import rtde_wire as wire
from hw.ur.emulator.controller import CYCLE
from hw.ur.emulator.launch import emulate, free_host, host_range

HOSTS = host_range(2, 120)
JOINTS = [0.1, -1.5, 1.4, -1.2, -1.5, 0.2]


@dataclass
class Robot:
    host: str
    control_port: int

    def op(self, **request: Any) -> dict[str, Any]:
        return control(self.host, self.control_port, request)


@pytest.fixture
def robot() -> Iterator[Robot]:
    host = free_host(HOSTS)
    with emulate(host, "--joints", ",".join(map(str, JOINTS))) as emulator:
        yield Robot(host, emulator.ports["control"])


def until(condition: Callable[[], bool], timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


def whole_cycles(stamp: float) -> bool:
    """A controller's timestamp counts whole cycles of 8 ms since it booted."""
    return abs(stamp / CYCLE - round(stamp / CYCLE)) < 1e-3


def power_up(robot: Robot) -> None:
    dashboard = dashboard_client.DashboardClient(robot.host)
    dashboard.connect()
    dashboard.brakeRelease()
    assert until(lambda: dashboard.robotmode() == "Robotmode: RUNNING")
    dashboard.disconnect()


@pytest.fixture
def running(robot: Robot) -> Iterator[tuple[Robot, Any, Any]]:
    """A powered robot with a control and a receive interface, disconnected before the end."""
    power_up(robot)
    receive = rtde_receive.RTDEReceiveInterface(robot.host)
    try:
        control_interface = rtde_control.RTDEControlInterface(robot.host)
        try:
            yield robot, control_interface, receive
        finally:
            control_interface.disconnect()
    finally:
        receive.disconnect()


def run_client(code: str, timeout: float = 20.0) -> str:
    """Runs ur_rtde code in its own process (for failing constructors); returns its stdout."""
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout, check=False
    )
    return done.stdout


def test_receive_interface_handshake_and_data(robot: Robot) -> None:
    receive = rtde_receive.RTDEReceiveInterface(robot.host)
    try:
        first = receive.getTimestamp()
        assert until(lambda: receive.getTimestamp() > first)  # the controller's clock goes on
        second = receive.getTimestamp()
        assert whole_cycles(first) and whole_cycles(second)
        assert receive.getActualQ() == pytest.approx(JOINTS)
        assert receive.getRobotMode() == 3  # POWER_OFF
        assert receive.getSafetyStatusBits() == 1
        assert receive.getRuntimeState() == 1
        assert receive.getPayload() == 0.0
        assert robot.op(op="state")["connections"]["rtde"] == 1
    finally:
        receive.disconnect()


def test_dashboard_answers_literally(robot: Robot) -> None:
    dashboard = dashboard_client.DashboardClient(robot.host)
    dashboard.connect()
    try:
        assert dashboard.polyscopeVersion() == "3.15.7.106331"
        assert dashboard.robotmode() == "Robotmode: POWER_OFF"
        dashboard.powerOn()
        assert until(lambda: dashboard.robotmode() == "Robotmode: IDLE")
        dashboard.brakeRelease()
        assert until(lambda: dashboard.robotmode() == "Robotmode: RUNNING")
        assert dashboard.safetymode() == "Safetymode: NORMAL"
        assert dashboard.safetystatus() == "Safetystatus: NORMAL"
        assert not dashboard.running()
        dashboard.stop()  # raises unless "Stopped"
        dashboard.loadURP("station.urp")  # raises unless "Loading program:"
        assert dashboard.getRobotModel() == "UR10"
    finally:
        dashboard.disconnect()


def test_raw_rtde_client_gets_its_rate_and_not_found(robot: Robot) -> None:
    with socket.create_connection((robot.host, 30004), timeout=10) as link:
        buffer = bytearray()

        def ask(kind: int, payload: bytes) -> wire.Message:
            link.sendall(wire.frame(kind, payload))
            while not (messages := wire.split(buffer)):
                buffer.extend(link.recv(4096))
            return messages[0]

        assert ask(wire.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)).payload == b"\x01"
        version = ask(wire.GET_URCONTROL_VERSION, b"").payload
        assert struct.unpack(">IIII", version)[:3] == (3, 15, 7)
        refused = ask(wire.SETUP_OUTPUTS, struct.pack(">d", 10.0) + b"timestamp,flux,")
        assert refused.payload[1:] == b"DOUBLE,NOT_FOUND"
        recipe = ask(wire.SETUP_OUTPUTS, struct.pack(">d", 10.0) + b"timestamp,actual_q,")
        assert recipe.payload[1:] == b"DOUBLE,VECTOR6D"
        assert ask(wire.START, b"").payload == b"\x01"
        stamps: list[float] = []
        link.settimeout(10)
        while len(stamps) < 10:
            buffer.extend(link.recv(4096))
            stamps += [struct.unpack_from(">d", m.payload, 1)[0] for m in wire.split(buffer)]
        assert all(whole_cycles(stamp) for stamp in stamps)
        # never faster than the 10 Hz asked for: a package every 12th cycle of 8 ms, and a
        # controller that fell behind catches up by one cycle at most, however late it ran
        gaps = [round((b - a) / CYCLE) for a, b in itertools.pairwise(stamps)]
        assert min(gaps) >= 10, gaps


def test_control_interface_fails_before_brake_release(robot: Robot) -> None:
    out = run_client(
        "import rtde_control\n"
        "try:\n"
        f"    rtde_control.RTDEControlInterface({robot.host!r})\n"
        "except RuntimeError as e:\n"
        "    print('FAILED', e)\n"
    )
    assert "FAILED" in out and "Failed to start control script" in out


def test_a_second_control_interface_finds_the_inputs_in_use(
    running: tuple[Robot, Any, Any],
) -> None:
    robot, _, _ = running
    out = run_client(
        "import rtde_control, os\n"
        "try:\n"
        f"    rtde_control.RTDEControlInterface({robot.host!r})\n"
        "except RuntimeError as e:\n"
        "    print('FAILED', e, flush=True)\n"
        "os._exit(0)\n"
    )
    assert "already in use" in out


def test_move_j_sync_and_async_with_limited_speed(running: tuple[Robot, Any, Any]) -> None:
    _, control_interface, receive = running
    target = list(JOINTS)
    target[0] += 0.4
    started = time.monotonic()
    assert control_interface.moveJ(target, 0.8, 4.0)
    took = time.monotonic() - started
    # the blocking call returns at the target, and no sooner than the trapezoid allows: the
    # emulator's arm never moves further than the time that went by (it may lag under load)
    assert took >= 0.4 / 0.8 + 0.8 / 4.0 - 2 * CYCLE
    assert receive.getActualQ() == pytest.approx(target)
    assert control_interface.isSteady()

    # asynchronous and slow (about 2 s): the call returns while the arm is still on its way
    assert control_interface.moveJ(JOINTS, 0.2, 4.0, True)
    assert control_interface.getAsyncOperationProgress() >= 0  # running
    assert not control_interface.isSteady()
    assert until(lambda: control_interface.getAsyncOperationProgress() < 0, 30.0)
    assert receive.getActualQ() == pytest.approx(JOINTS)


def test_stop_j_halts_a_move(running: tuple[Robot, Any, Any]) -> None:
    _, control_interface, receive = running
    target = list(JOINTS)
    target[1] += 1.0
    assert control_interface.moveJ(target, 0.5, 2.0, True)
    time.sleep(0.4)
    control_interface.stopJ(4.0)
    held = receive.getActualQ()
    time.sleep(0.2)
    assert receive.getActualQ() == pytest.approx(held)
    assert JOINTS[1] < held[1] < target[1] - 0.5
    assert control_interface.isSteady()


def test_tcp_and_payload_reach_the_controller(running: tuple[Robot, Any, Any]) -> None:
    robot, control_interface, receive = running
    assert control_interface.setTcp([0.0, 0.0, 0.15, 0.0, 0.0, 0.0])
    assert control_interface.setPayload(1.5, [0.0, 0.0, 0.05])
    state = robot.op(op="state")
    assert state["tcp"] == [0.0, 0.0, 0.15, 0.0, 0.0, 0.0]
    assert state["payload"] == 1.5 and state["payload_cog"] == [0.0, 0.0, 0.05]
    assert until(lambda: receive.getPayload() == 1.5)
    assert control_interface.getTCPOffset() == pytest.approx([0.0, 0.0, 0.15, 0.0, 0.0, 0.0])


def test_protective_stop_fails_commands_until_unlocked(running: tuple[Robot, Any, Any]) -> None:
    robot, control_interface, receive = running
    robot.op(op="protective_stop")
    assert until(receive.isProtectiveStopped)
    assert not control_interface.moveJ(JOINTS, 0.5, 1.0)
    assert not control_interface.setTcp([0.0] * 6)
    dashboard = dashboard_client.DashboardClient(robot.host)
    dashboard.connect()
    try:
        dashboard.unlockProtectiveStop()  # raises unless "Protective stop releasing"
        dashboard.play()
        assert until(lambda: receive.getRuntimeState() == 2)
    finally:
        dashboard.disconnect()
    assert not receive.isProtectiveStopped()
    # the control interface reads the robot's state on its own RTDE connection: it sends a
    # command only once it has seen the script run again, which may come after the receive
    # interface saw it (a busy machine showed the gap)
    assert until(control_interface.isProgramRunning)
    assert control_interface.moveJ(JOINTS, 0.5, 1.0)


def test_io_interface_writes_outputs(robot: Robot) -> None:
    io = rtde_io.RTDEIOInterface(robot.host)
    try:
        assert io.setStandardDigitalOut(3, True)
        assert io.setSpeedSlider(0.25)
        assert until(lambda: robot.op(op="state")["inputs"].get("speed_slider_fraction") == 0.25)
        assert robot.op(op="state")["inputs"]["standard_digital_output"] == 8
    finally:
        io.disconnect()


def test_faults_on_demand(robot: Robot) -> None:
    robot.op(op="push", offset=[0.1, 0, 0, 0, 0, 0])
    assert robot.op(op="state")["joints"][0] == pytest.approx(JOINTS[0] + 0.1)
    robot.op(op="jog", joints=[0.0] * 6)
    assert robot.op(op="state")["joints"] == [0.0] * 6
    robot.op(op="freeze", on=True)
    receive = rtde_receive.RTDEReceiveInterface(robot.host)
    try:
        first = receive.getTimestamp()
        time.sleep(0.2)
        assert receive.getTimestamp() == first
        robot.op(op="freeze", on=False)
        assert until(lambda: receive.getTimestamp() > first)
    finally:
        receive.disconnect()
    assert robot.op(op="state")["faults"] == ["power off"]
    with pytest.raises(ControlError, match="no operation"):
        robot.op(op="explode")
    with pytest.raises(ControlError, match="6 numbers"):
        robot.op(op="push", offset=[1.0])


def test_network_refuse_and_silent(robot: Robot) -> None:
    robot.op(op="network", down=True, mode="refuse")
    with pytest.raises(ConnectionRefusedError):
        socket.create_connection((robot.host, 29999), timeout=10).close()
    robot.op(op="network", down=False)
    robot.op(op="network", down=True, mode="silent")
    with socket.create_connection((robot.host, 29999), timeout=10) as link:
        link.settimeout(0.3)
        with pytest.raises(TimeoutError):
            link.recv(100)  # no greeting
        robot.op(op="network", down=False)
        link.sendall(b"robotmode\n")
        link.settimeout(10.0)
        assert link.recv(100) == b"Robotmode: POWER_OFF\n"
    assert robot.op(op="state")["faults"] == ["power off"]


def test_stall_keeps_the_move_in_progress(running: tuple[Robot, Any, Any]) -> None:
    robot, control_interface, receive = running
    robot.op(op="stall", on=True)
    target = list(JOINTS)
    target[0] += 0.5
    assert control_interface.moveJ(target, 1.0, 4.0, True)
    time.sleep(0.5)
    assert control_interface.getAsyncOperationProgress() >= 0  # still running
    assert receive.getActualQ()[0] < target[0] - 0.1
    robot.op(op="stall", on=False)
    assert until(lambda: control_interface.getAsyncOperationProgress() < 0)
    # Two RTDE streams: the receive interface's may be a few packets behind the control's.
    assert until(lambda: receive.getActualQ() == pytest.approx(target))


def test_power_off_stops_the_script(running: tuple[Robot, Any, Any]) -> None:
    robot, control_interface, receive = running
    robot.op(op="power", on=False)
    assert until(lambda: receive.getRobotMode() == 3 and receive.getRuntimeState() == 1)
    assert not control_interface.moveJ(JOINTS, 0.5, 1.0)
