"""The UR emulator's pure parts: RTDE framing and recipes, programs, dashboard, readings."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hw.pipelines import Nonsense
from hw.ur.emulator import rtde_wire as wire
from hw.ur.emulator.arm import Arm
from hw.ur.emulator.control_script import parse_program
from hw.ur.emulator.controller import Controller, RobotMode, RuntimeState
from hw.ur.emulator.dashboard import answer
from hw.ur.emulator.script_server import Programs
from hw.ur.sample import reading_from

RTDE_SCRIPT = (
    "def rtde_control():\n# HEADER_BEGIN\n"
    "    global reg_offset_int = # int register offset\n0    global x = 1\n"
    "# HEADER_END\n        sync()\nend\n"
)


def test_frame_and_split_keep_partial_messages() -> None:
    data = wire.frame(wire.START) + wire.frame(wire.DATA_PACKAGE, b"\x01abc")
    buffer = bytearray(data[:5])
    assert wire.split(buffer) == [wire.Message(wire.START, b"")]
    buffer += data[5:]
    assert wire.split(buffer) == [wire.Message(wire.DATA_PACKAGE, b"\x01abc")]
    assert buffer == bytearray()


def test_a_size_below_the_header_is_refused() -> None:
    with pytest.raises(wire.WireError):
        wire.split(bytearray(b"\x00\x01U"))


def test_output_setup_parses_frequency_and_names() -> None:
    payload = struct.pack(">d", 125.0) + b"timestamp,actual_q,"
    assert wire.output_setup(payload) == (125.0, ["timestamp", "actual_q"])
    assert wire.output_types(["timestamp", "actual_q", "nonsense"]) == [
        "DOUBLE",
        "VECTOR6D",
        wire.NOT_FOUND,
    ]


def test_the_receive_interfaces_variables_are_all_known() -> None:
    names = [
        "timestamp",
        "target_q",
        "target_qd",
        "target_qdd",
        "target_current",
        "target_moment",
        "actual_q",
        "actual_qd",
        "actual_current",
        "joint_control_output",
        "actual_TCP_pose",
        "actual_TCP_speed",
        "actual_TCP_force",
        "target_TCP_pose",
        "target_TCP_speed",
        "actual_digital_input_bits",
        "joint_temperatures",
        "actual_execution_time",
        "robot_mode",
        "joint_mode",
        "safety_mode",
        "actual_tool_accelerometer",
        "speed_scaling",
        "target_speed_fraction",
        "actual_momentum",
        "actual_main_voltage",
        "actual_robot_voltage",
        "actual_robot_current",
        "actual_joint_voltage",
        "actual_digital_output_bits",
        "runtime_state",
        "standard_analog_input0",
        "standard_analog_input1",
        "standard_analog_output0",
        "standard_analog_output1",
        "robot_status_bits",
        "safety_status_bits",
        "payload",
        "payload_cog",
        "payload_inertia",
        "ft_raw_wrench",
        "output_int_register_2",
    ]
    assert wire.NOT_FOUND not in wire.output_types(names)
    assert wire.OUTPUTS["payload_cog"] == "VECTOR3D"
    assert wire.OUTPUTS["joint_mode"] == "VECTOR6INT32"


@given(
    st.lists(st.integers(-(2**31), 2**31 - 1), min_size=1, max_size=3),
    st.lists(st.floats(allow_nan=False), min_size=6, max_size=6),
)
def test_a_recipe_packs_and_unpacks(integers: list[int], vector: list[float]) -> None:
    names = [f"input_int_register_{k}" for k in range(len(integers))] + ["external_force_torque"]
    recipe = wire.Recipe.of(3, names, wire.INPUTS)
    values = {name: value for name, value in zip(names, integers, strict=False)}
    values["external_force_torque"] = tuple(vector)
    message = recipe.pack(values)
    (parsed,) = wire.split(bytearray(message))
    assert parsed.kind == wire.DATA_PACKAGE
    assert recipe.unpack(parsed.payload) == values


def test_a_package_of_the_wrong_size_is_refused() -> None:
    recipe = wire.Recipe.of(1, ["input_int_register_0"], wire.INPUTS)
    with pytest.raises(wire.WireError):
        recipe.unpack(b"\x01\x00")


def test_programs_are_cut_at_end_lines() -> None:
    programs = Programs()
    assert programs.feed(RTDE_SCRIPT[:40]) == []
    assert programs.feed(RTDE_SCRIPT[40:] + "stopj(2)\n") == [RTDE_SCRIPT, "stopj(2)\n"]
    assert parse_program(RTDE_SCRIPT) == 0
    assert parse_program(RTDE_SCRIPT.replace("\n0    global", "\n24    global")) == 24
    assert parse_program("stopj(2)\n") is None


def test_dashboard_answers_and_the_power_sequence() -> None:
    c = Controller(Arm([0.0] * 6))
    assert answer(c, "robotmode", 0.0) == "Robotmode: POWER_OFF"
    assert answer(c, "power on", 0.0) == "Powering on"
    c.tick(1.0)
    assert c.robot_mode == RobotMode.IDLE
    assert answer(c, "brake release", 1.0) == "Brake releasing"
    c.tick(2.0)
    assert answer(c, "robotmode", 2.0) == "Robotmode: RUNNING"
    assert answer(c, "PolyscopeVersion", 2.0).startswith("URSoftware 3.15.7.")
    assert answer(c, "stop", 2.0) == "Stopped"
    assert answer(c, "play", 2.0) == "Failed to execute: play"  # nothing loaded
    c.load_program(RTDE_SCRIPT)
    assert c.runtime == RuntimeState.PLAYING
    assert answer(c, "pause", 2.0) == "Pausing program"
    assert answer(c, "play", 2.0) == "Starting program"
    assert answer(c, "running", 2.0) == "Program running: true"
    assert answer(c, "load x.urp", 2.0).startswith("Loading program:")
    assert answer(c, "unlock protective stop", 2.0) != "Protective stop releasing"
    c.protective_stop()
    assert answer(c, "safetymode", 2.0) == "Safetymode: PROTECTIVE_STOP"
    assert answer(c, "unlock protective stop", 2.0) == "Protective stop releasing"
    assert answer(c, "is in remote control", 2.0) == "true"
    assert answer(c, "fly", 2.0) == "could not understand: 'fly'"


def running_controller() -> Controller:
    c = Controller(Arm([0.0] * 6), clock=1.0)
    c.brake_release(1.0)
    c.tick(3.0)
    c.load_program(RTDE_SCRIPT)
    c.tick(3.008)
    return c


def command(c: Controller, code: int, doubles: list[float], flag: int = 0) -> None:
    c.registers.int_in[0], c.registers.int_in[1] = code, flag
    c.registers.double_in[: len(doubles)] = doubles


def test_the_control_script_answers_ready_then_done() -> None:
    c = running_controller()
    assert c.registers.int_out[0] == 1
    command(c, 1, [0.5, 0, 0, 0, 0, 0, 1.0, 2.0], flag=1)  # async moveJ
    c.tick(c.clock + 0.008)
    assert c.registers.int_out[0] == 2
    assert c.registers.int_out[2] & 0x8000  # running
    command(c, 0, [])
    while not c.arm.steady:
        c.tick(c.clock + 0.008)
    c.tick(c.clock + 0.008)
    assert c.registers.int_out[0] == 1
    assert not c.registers.int_out[2] & 0x8000
    assert c.arm.q[0] == 0.5


def test_move_l_stops_the_script_with_a_reason() -> None:
    c = running_controller()
    command(c, 3, [0.5, 0, 0.3, 0, 0, 0, 0.1, 1.0])
    c.tick(c.clock + 0.008)
    assert c.runtime == RuntimeState.STOPPED
    assert "inverse kinematics" in c.script_error


def sample(**changes: object) -> dict[str, object]:
    raw: dict[str, object] = {
        "stamp": 12.5,
        "q": [0.0] * 6,
        "qd": [0.0] * 6,
        "robot_mode": 7,
        "safety_bits": 4,
        "runtime_state": 2,
    }
    raw.update(changes)
    return raw


def test_a_sensible_reading_is_trusted() -> None:
    reading = reading_from(sample(), 3.0)
    assert reading.protective_stop and reading.steady and reading.running
    assert reading.received == 3.0


@pytest.mark.parametrize(
    "changes",
    [
        {"q": [0.0] * 5},
        {"q": [0.0] * 5 + [math.nan]},
        {"qd": [math.inf] + [0.0] * 5},
        {"q": [100.0] + [0.0] * 5},
        {"stamp": -1.0},
        {"robot_mode": 42},
        {"runtime_state": 2.5},
        {"safety_bits": "x"},
    ],
)
def test_nonsense_is_not_trusted(changes: dict[str, object]) -> None:
    with pytest.raises(Nonsense):
        reading_from(sample(**changes), 0.0)


def test_the_driver_is_ready_only_once_a_reading_shows_the_program_running() -> None:
    """A reading in flight when control comes up may still show the program stopped."""
    from hw.ur.driver import URDriver

    driver = URDriver("127.0.0.9", name="r1", heartbeat_timeout=5.0)
    driver._receive(("ready",))
    driver._receive(("reading", sample(stamp=1.0, safety_bits=1, runtime_state=1)))
    assert not driver.available and "control program" in driver.status().error
    driver._receive(("reading", sample(stamp=1.1, safety_bits=1, runtime_state=2)))
    assert driver.available and driver.status().error == ""


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-3.0, 3.0),
    st.lists(st.sampled_from([0.001, 0.003, 0.008, 0.02, 0.05, 0.1, 0.3]), min_size=1, max_size=30),
)
def test_the_controller_moves_its_arm_in_whole_cycles_however_it_is_ticked(
    goal: float, ticks: list[float]
) -> None:
    """The arm is stepped at the controller's own period, not by the time between ticks: a
    stalled emulator catches up in whole cycles (at most 0.1 s of motion) and the move
    arrives on its goal without passing it (one 0.1 s step once put r1 0.02 rad past a pose)."""
    c = running_controller()
    command(c, 1, [goal, 0, 0, 0, 0, 0, 1.05, 1.4], flag=1)  # async moveJ
    c.tick(c.clock + 0.008)
    command(c, 0, [])
    lo, hi = sorted((0.0, goal))
    k = 0
    while not c.arm.steady:
        before = c.arm.q[0]
        c.tick(c.clock + ticks[k % len(ticks)])
        k += 1
        assert lo - 1e-9 <= c.arm.q[0] <= hi + 1e-9
        assert abs(c.arm.q[0] - before) <= 1.05 * 0.1 + 1e-9  # no more than 0.1 s of motion
        assert k < 10_000
    assert c.arm.q[0] == goal
