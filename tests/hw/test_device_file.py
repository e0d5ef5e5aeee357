"""The station's device file: the demo loads, and every kind of mistake is refused with its
place in the file (file, line, column) and what is wrong."""

from __future__ import annotations

import pytest

from hw.device_file import load_devices
from hw.device_file.spec import DriverKind, RobotRole
from hw.modbus.registers import Point, Table
from planner.model.station import Station
from planner.reading import load_station
from planner.reading.yaml_reader import ModelError
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
DEVICES = ROOT / "models" / "demo_station.devices.yaml"
FILE = "stations/demo.devices.yaml"


@pytest.fixture(scope="module")
def station() -> Station:
    return load_station(MODEL.read_text(), str(MODEL))


def problems(station: Station, text: str) -> list[str]:
    with pytest.raises(ModelError) as raised:
        load_devices(text, FILE, station)
    return [str(d) for d in raised.value.diagnostics]


def edited(old: str, new: str, count: int = 1) -> str:
    text = DEVICES.read_text()
    assert text.count(old) >= count, old
    return text.replace(old, new, count)


def line_of(text: str, fragment: str) -> int:
    return text[: text.index(fragment)].count("\n") + 1


def test_the_demo_device_file_wires_every_measured_and_command_variable(station: Station) -> None:
    devices = load_devices(DEVICES.read_text(), str(DEVICES), station)
    wired = [w.variable for d in devices.devices for w in d.wires]
    assert len(wired) == len(set(wired))
    kinds = {v.name: v.kind.value for v in station.model.variables}
    must = {n for n, k in kinds.items() if k in ("measured", "command")}
    assert must <= set(wired)
    r1 = devices.device("r1")
    assert r1.driver is DriverKind.UR and r1.host == "127.0.0.2"
    assert {w.variable: w.role for w in r1.wires}["r1.pos"] is RobotRole.POSE
    assert r1.programs is not None
    assert r1.programs.goto("scan").joints == (0.0, -1.2, 1.0, -1.4, -1.571, 0.0)
    nr = devices.device("nr")
    nok = next(w for w in nr.wires if w.variable == "nr.nok")
    assert nok.register is not None and nok.register.point == Point(Table.DISCRETE_INPUT, 3)
    bp1 = next(w for w in devices.device("plc").wires if w.variable == "bp1.state")
    assert bp1.register is not None and dict(bp1.register.codes)[1] == "placed"
    assert devices.device("operator_watch").driver is DriverKind.WATCH


def test_a_variable_left_unwired_is_named(station: Station) -> None:
    text = edited("      nok: nok\n", "")
    found = problems(station, text)
    assert any("the measured variable 'nr.nok' is wired to no device" in p for p in found)
    assert all(p.startswith(f"{FILE}:{line_of(text, 'devices:')}:1:") for p in found)


def test_a_variable_wired_twice_points_at_the_second_wire(station: Station) -> None:
    text = edited("      nok: nok\n", "      nok: nok\n      nr.nok: torque_reached\n")
    [problem] = problems(station, text)
    line = line_of(text, "nr.nok: torque_reached")
    assert problem.startswith(f"{FILE}:{line}:")
    assert "'nr.nok' is wired already, by device 'nr'" in problem


@pytest.mark.parametrize(
    ("old", "new", "located_at", "message"),
    [
        (
            "driver: modbus\n    resource: nr\n",
            "driver: canbus\n    resource: nr\n",
            "canbus",
            "a device's driver is one of ur, modbus, watch, not 'canbus'",
        ),
        (
            "resource: r1_cam\n",
            "resource: r1_camera\n",
            "r1_camera",
            "the model has no resource 'r1_camera' (did you mean 'r1_cam'?)",
        ),
        (
            "address: 127.0.0.15:5020",
            "address: nutrunner.local:5020",
            "nutrunner.local",
            "address 'nutrunner.local:5020' needs an IP address",
        ),
        (
            "address: 127.0.0.15:5020",
            "address: 127.0.0.15:70000",
            "127.0.0.15:70000",
            "port '70000' must be a number from 1 to 65535",
        ),
        (
            "address: 127.0.0.2\n",
            "address: 127.0.0.2:30004\n",
            "127.0.0.2:30004",
            "a robot's address has no port",
        ),
        ("      nok: nok\n", "      nok: nokk\n", "nokk", "nutrunner has no register 'nokk'"),
        (
            "      is_idle: is_idle\n",
            "      is_idle: run_forward\n",
            "run_forward\n      is_running",
            "'nr.is_idle' is read, not written: not a coil",
        ),
        (
            "      set_idle: set_idle\n",
            "      set_idle: is_idle\n",
            "is_idle\n      run_forward",
            "the command 'nr.set_idle' must go to a coil or holding_register",
        ),
        (
            "      nok: nok\n",
            "      nok: {input_register: 2, values: [a, b]}\n",
            "{input_register",
            "a boolean needs no 'values'",
        ),
        (
            "      bp1.state: bp1.state\n",
            "      bp1.state: {input_register: 2, bit: 3}\n",
            "{input_register: 2, bit",
            "a bit holds a boolean; 'bp1.state' is not one",
        ),
        (
            "      bp1.state: bp1.state\n",
            "      bp1.state: {input_register: 2, values: [empty, done]}\n",
            "[empty, done]",
            "'done' is no value of 'bp1.state'",
        ),
        (
            "      bp1.state: bp1.state\n",
            "      bp1.state: agv.engine\n",
            "agv.engine\n      bp2",
            "register 'agv.engine' holds no values of 'bp1.state'",
        ),
        (
            "heartbeat_timeout: 1.0\n    motion",
            "heartbeat_timeout: -1\n    motion",
            "-1",
            "heartbeat_timeout (seconds) must be a positive number",
        ),
        (
            "      scan:         [0.0, -1.2, 1.0, -1.4, -1.571, 0.0]",
            "      scan:         [0.0, -1.2, 1.0, -1.4, -1.571]",
            "[0.0, -1.2, 1.0, -1.4, -1.571]",
            "a joint vector needs 6 numbers, not 5",
        ),
        (
            "      scan:         [0.0, -1.2, 1.0, -1.4, -1.571, 0.0]",
            "      scan:         [0.0, -1.571, 1.571, -1.571, -1.571, 0.005]",
            "poses: &poses",
            "poses 'home' and 'scan' are within twice the tolerance",
        ),
        (
            "      lift_ee: {tcp: [0, 0, 0.25, 0, 0, 0], payload: 6.0, cog: [0, 0, 0.10]}\n",
            "",
            "tools: &tools",
            "tools has no entry for lift_ee of 'r1.tcp'",
        ),
        (
            "{pos: pose, last: last_pose",
            "{pos: move_to, last: last_pose",
            "move_to, last",
            "'move_to' is for a command variable; 'r1.pos' is not one",
        ),
        ("{pos: pose,", "{pos: wrist,", "wrist,", "a robot variable is wired to one of pose"),
        (
            "      blocked: {goto.arrive: stall}\n\n  - name: r2",
            "      blocked: {goto.arrve: stall}\n\n  - name: r2",
            "goto.arrve",
            "'goto.arrve' is no effect of 'r1'",
        ),
        (
            "    resource: operator\n",
            "    resource: operator\n    address: 127.0.0.9\n",
            "address: 127.0.0.9",
            "'address' does not belong to a watch device",
        ),
        (
            "    driver: watch\n    resource: operator\n",
            "    driver: watch\n    resource: nr  # the nutrunner\n",
            "nr  # the",
            "the model declares no watch for 'nr'",
        ),
        (
            "  - name: r2_cam\n",
            "  - name: r1_cam\n",
            "r1_cam\n    driver: modbus\n    resource: r2_cam",
            "duplicate device name 'r1_cam'",
        ),
        (
            "station: demo_station",
            "station: paint_shop",
            "paint_shop",
            "this file is for station 'paint_shop', not 'demo_station'",
        ),
        (
            "    map: nutrunner\n",
            "    map: screwdriver\n",
            "screwdriver",
            "no register map 'screwdriver'",
        ),
    ],
)
def test_each_mistake_is_located_and_named(
    station: Station, old: str, new: str, located_at: str, message: str
) -> None:
    text = edited(old, new)
    found = problems(station, text)
    line = line_of(text, located_at)
    assert any(p.startswith(f"{FILE}:{line}:") and message in p for p in found), found


def test_broken_yaml_and_an_empty_file_are_located(station: Station) -> None:
    [problem] = problems(station, "devices: [\n")
    assert problem.startswith(f"{FILE}:2:")
    [problem] = problems(station, "")
    assert problem == f"{FILE}:1:1: the device file is empty"
    [problem] = problems(station, "station: demo_station\n")
    assert "needs 'devices'" in problem


def watch_model(watch: str) -> str:
    return MODEL.read_text().replace(
        "    watch: {card: card, done: done, confirm: confirm}\n", watch
    )


@pytest.mark.parametrize(
    ("watch", "message"),
    [
        (
            "    watch: {card: done, done: done, confirm: confirm}\n",
            "its card 'operator.done' must be a command variable",
        ),
        (
            "    watch: {card: card, done: card, confirm: confirm}\n",
            "its done 'operator.card' must be a measured variable",
        ),
        (
            "    watch: {card: card, done: done, confirm: hang_nr_from_r1}\n",
            "its confirm 'operator.hang_nr_from_r1' must be an effect",
        ),
        (
            "    watch: {card: card, done: done, confirm: tap}\n",
            "'confirm' names none of the resource's own transitions",
        ),
        ("    watch: {card: card, done: done}\n", "a watch needs 'confirm'"),
    ],
)
def test_a_wrong_watch_declaration_is_located(watch: str, message: str) -> None:
    text = watch_model(watch)
    with pytest.raises(ModelError) as raised:
        load_station(text, "m.yaml")
    line = line_of(text, "    watch:")
    assert any(d.location.line == line and message in d.message for d in raised.value.diagnostics)


def test_only_a_person_carries_a_watch() -> None:
    text = watch_model("").replace(
        "    description: tool-changer connector on r1\n",
        "    description: tool-changer connector on r1\n"
        "    watch: {card: lock, done: connected, confirm: lock_nr.connect}\n",
    )
    with pytest.raises(ModelError) as raised:
        load_station(text, "m.yaml")
    assert any("only a person carries a watch" in d.message for d in raised.value.diagnostics)
