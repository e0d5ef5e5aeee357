"""The emulated controller itself: modes, safety, the program, registers and the arm.

`Controller` is advanced by `tick(now)` from one loop (the 125 Hz controller cycle of
`hw.ur.emulator.server`, the process around it); the servers call its operations
(`power_on`, `load_program`, `write_inputs` ...) and read `outputs(names)`.  Time comes in as
`now` (monotonic seconds); nothing here does I/O.

Life cycle of the robot, as a CB3 shows it: POWER_OFF --`power on`--> POWER_ON --(delay)-->
IDLE --`brake release`--> RUNNING (after a delay).  A program (the uploaded ur_rtde control
script) plays only while RUNNING; a protective stop halts the arm and pauses it, `unlock
protective stop` clears the stop and `play` resumes it; powering off stops it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from hw.ur.emulator.arm import Arm
from hw.ur.emulator.control_script import ControlScript, Registers, parse_program
from hw.ur.emulator.rtde_wire import OUTPUTS, VECTOR_SIZES


class RobotMode(IntEnum):
    POWER_OFF = 3
    POWER_ON = 4
    IDLE = 5
    RUNNING = 7


class SafetyMode(IntEnum):
    NORMAL = 1
    PROTECTIVE_STOP = 3


class RuntimeState(IntEnum):
    STOPPED = 1
    PLAYING = 2
    PAUSED = 4


JOINT_MODE = {RobotMode.POWER_OFF: 239, RobotMode.POWER_ON: 247, RobotMode.IDLE: 255}
RUNNING_JOINT = 253
POWER_DELAY = 0.3
"""Seconds from `power on` to IDLE and from `brake release` to RUNNING."""
CYCLE = 0.008
"""Seconds per controller cycle of a CB3 (125 Hz); an e-series (version 5) runs at 500 Hz."""
LOST = 0.1
"""Seconds of motion at most per tick: time the emulator did not run beyond this is lost."""


@dataclass
class Controller:
    arm: Arm
    version: tuple[int, int, int, int] = (3, 15, 7, 106331)
    robot_mode: RobotMode = RobotMode.POWER_OFF
    safety_mode: SafetyMode = SafetyMode.NORMAL
    runtime: RuntimeState = RuntimeState.STOPPED
    registers: Registers = field(default_factory=Registers)
    tcp: tuple[float, ...] = (0.0,) * 6
    payload: float = 0.0
    payload_cog: tuple[float, ...] = (0.0,) * 3
    inputs: dict[str, Any] = field(default_factory=dict)
    program: str = ""
    script: ControlScript | None = None
    script_error: str = ""
    stalled: bool = False
    boot: float = 0.0
    clock: float = 0.0
    pending: list[tuple[float, RobotMode]] = field(default_factory=list)
    """Mode changes under way: (when, mode), in time order."""
    unstepped: float = 0.0
    """Seconds the arm has not yet been stepped: it moves in whole cycles only."""

    def power_on(self, now: float) -> None:
        if self.robot_mode == RobotMode.POWER_OFF and not self.pending:
            self.robot_mode = RobotMode.POWER_ON
            self.pending.append((now + POWER_DELAY, RobotMode.IDLE))

    def brake_release(self, now: float) -> None:
        """Releases the brakes (powering on first if needed); RUNNING after a delay."""
        if self.robot_mode == RobotMode.RUNNING or any(
            mode == RobotMode.RUNNING for _, mode in self.pending
        ):
            return
        self.power_on(now)
        start = max([now, *(when for when, _ in self.pending)])
        self.pending.append((start + POWER_DELAY, RobotMode.RUNNING))

    def power_off(self) -> None:
        self.robot_mode = RobotMode.POWER_OFF
        self.pending.clear()
        self.arm.hold()
        self.stop_program()

    def protective_stop(self) -> None:
        self.safety_mode = SafetyMode.PROTECTIVE_STOP
        self.arm.hold()
        if self.script is not None:
            self.script.interrupt(self)
        if self.runtime == RuntimeState.PLAYING:
            self.runtime = RuntimeState.PAUSED

    def unlock_protective_stop(self) -> bool:
        if self.safety_mode != SafetyMode.PROTECTIVE_STOP:
            return False
        self.safety_mode = SafetyMode.NORMAL
        return True

    def load_program(self, text: str) -> None:
        """A program arrived on the script port: it replaces whatever runs."""
        self.stop_program()
        self.program = text
        self.play()

    def play(self) -> bool:
        """Starts (or resumes) the loaded program; False if the robot cannot run it."""
        if not self.program or self.robot_mode != RobotMode.RUNNING:
            return False
        if self.safety_mode != SafetyMode.NORMAL:
            return False
        if self.runtime == RuntimeState.PAUSED and self.script is not None:
            self.runtime = RuntimeState.PLAYING
            return True
        offset = parse_program(self.program)
        if offset is None:
            self.script_error = "the emulator runs only ur_rtde's control script"
            return False
        self.script = ControlScript(offset)
        self.script.start(self)
        self.script_error = ""
        self.runtime = RuntimeState.PLAYING
        return True

    def pause(self) -> bool:
        if self.runtime != RuntimeState.PLAYING:
            return False
        self.runtime = RuntimeState.PAUSED
        return True

    def stop_program(self, error: str = "") -> None:
        if self.script is not None:
            self.script.interrupt(self)
        self.script = None
        self.runtime = RuntimeState.STOPPED
        if error:
            self.script_error = error

    def stall(self, on: bool) -> None:
        self.stalled = on
        if not on and self.script is not None:
            self.script.resume_move(self)

    def push(self, offset: Sequence[float]) -> None:
        moving = self.script is not None and self.script.move_in_progress
        self.arm.q = [q + float(d) for q, d in zip(self.arm.q, offset, strict=True)]
        if not moving:
            self.arm.hold()

    def jog(self, joints: Sequence[float]) -> None:
        """Someone moved the arm by hand: any move is dropped, the arm rests there."""
        if self.script is not None:
            self.script.interrupt(self, done=True)
        self.arm.q = [float(q) for q in joints]
        self.arm.hold()

    def write_inputs(self, values: Mapping[str, Any], now: float) -> None:
        regs = self.registers
        for name, value in values.items():
            if name.startswith("input_int_register_"):
                number = int(name.rsplit("_", 1)[1])
                regs.int_in[number] = int(value)
                regs.updated[number] = now
            elif name.startswith("input_double_register_"):
                regs.double_in[int(name.rsplit("_", 1)[1])] = float(value)
            else:
                self.inputs[name] = value

    def tick(self, now: float) -> None:
        dt = now - self.clock if self.clock else 0.0
        self.clock = now
        while self.pending and now >= self.pending[0][0]:
            self.robot_mode = self.pending.pop(0)[1]
        if self.runtime == RuntimeState.PLAYING and self.script is not None:
            outcome = self.script.cycle(self, now)
            if outcome is not None:
                self.stop_program(outcome)
        if self.stalled and self.arm.target is not None:
            self.arm.stop(max(self.arm.acceleration, default=1.0) or 1.0)
        self.step_arm(dt)

    @property
    def period(self) -> float:
        return CYCLE / 4 if self.version[0] >= 5 else CYCLE

    def step_arm(self, dt: float) -> None:
        """Moves the arm by `dt` in whole controller cycles, as a controller does, however
        irregularly the emulator itself gets to run: the arm's motion profile is exact only
        for a fixed step (a stalled emulator that then stepped 0.1 s overshot a target)."""
        self.unstepped = min(self.unstepped + max(dt, 0.0), LOST)
        period = self.period
        while self.unstepped >= period * (1 - 1e-6):
            self.arm.step(period)
            self.unstepped = max(self.unstepped - period, 0.0)

    @property
    def timestamp(self) -> float:
        """Seconds since the controller booted, in whole controller cycles."""
        return math.floor((self.clock - self.boot) / CYCLE) * CYCLE

    def safety_status_bits(self) -> int:
        if self.safety_mode == SafetyMode.PROTECTIVE_STOP:
            return 1 << 2
        return 1 << 0

    def robot_status_bits(self) -> int:
        bits = 0
        if self.robot_mode != RobotMode.POWER_OFF:
            bits |= 1 << 0
        if self.runtime == RuntimeState.PLAYING:
            bits |= 1 << 1
        return bits

    def outputs(self, names: Iterable[str]) -> dict[str, Any]:
        """The values of these output names now (registers and state together)."""
        state = self._state_values()
        regs = self.registers
        values: dict[str, Any] = {}
        for name in names:
            value = state.get(name, _MISSING)
            if value is _MISSING:
                place = _register_place(name)
                value = getattr(regs, place[0])[place[1]] if place else NEUTRAL.get(name, 0)
            values[name] = value
        return values

    def _state_values(self) -> dict[str, Any]:
        q = tuple(self.arm.q)
        qd = tuple(self.arm.qd)
        joint = JOINT_MODE.get(self.robot_mode, RUNNING_JOINT)
        return {
            "timestamp": self.timestamp,
            "target_q": tuple(self.arm.target) if self.arm.target is not None else q,
            "target_qd": qd,
            "actual_q": q,
            "actual_qd": qd,
            "robot_mode": int(self.robot_mode),
            "joint_mode": (joint,) * 6,
            "safety_mode": int(self.safety_mode),
            "safety_status": int(self.safety_mode),
            "runtime_state": int(self.runtime),
            "robot_status_bits": self.robot_status_bits(),
            "safety_status_bits": self.safety_status_bits(),
            "payload": self.payload,
            "payload_cog": self.payload_cog,
            "speed_scaling": 1.0,
            "target_speed_fraction": 1.0,
            "actual_main_voltage": 48.0,
            "actual_robot_voltage": 48.0 if self.robot_mode != RobotMode.POWER_OFF else 0.0,
            "joint_temperatures": (30.0,) * 6,
            "actual_execution_time": 0.5,
        }


_MISSING = object()
_REGISTER_PREFIXES = {
    "output_int_register_": "int_out",
    "output_double_register_": "double_out",
    "input_int_register_": "int_in",
    "input_double_register_": "double_in",
}


@functools.cache
def _register_place(name: str) -> tuple[str, int] | None:
    """Which register list and index an output name reads, if it is a register."""
    prefix, _, number = name.rpartition("_")
    place = _REGISTER_PREFIXES.get(prefix + "_")
    return (place, int(number)) if place and number.isdigit() else None


def _neutral(kind: str) -> Any:
    size = VECTOR_SIZES.get(kind, 0)
    zero: Any = 0.0 if kind in ("DOUBLE", "VECTOR3D", "VECTOR6D") else 0
    if kind == "BOOL":
        zero = False
    return (zero,) * size if size else zero


NEUTRAL = {name: _neutral(kind) for name, kind in OUTPUTS.items()}
"""A zero of the right shape for each variable the emulator does not model."""
