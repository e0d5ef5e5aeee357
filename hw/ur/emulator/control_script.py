"""ur_rtde's control script, as the emulated controller runs it: the register protocol.

`RTDEControlInterface` uploads a URScript (`def rtde_control(): ... end`) whose main loop,
once per controller cycle, reads a command code from `input_int_register_0` (plus an offset of
24 with `FLAG_UPPER_RANGE_REGISTERS`) and answers in `output_int_register_0`: 1 ready, 2 done.
Arguments come in `input_double_register_0..` and `input_int_register_1`; results go to
`output_int_register_1` and `output_double_register_0..5`; `output_int_register_2` carries the
asynchronous-progress word (operation id in bits 24-30, a change counter in bits 16-23, bit 15
running, bits 0-14 progress).  This module runs that loop on the emulated controller instead of
interpreting URScript.  Commands it cannot do stop the program with an error, as a failing
URScript would, so that the client's next command returns False.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Protocol

from hw.ur.emulator.arm import Arm

READY, DONE = 1, 2
MOVE_J, MOVE_J_IK, MOVE_L, MOVE_L_FK = 1, 2, 3, 4
SPEED_STOP, SERVO_STOP, SET_PAYLOAD, SET_TCP = 15, 16, 17, 29
PROTECTIVE_STOP, STOP_L, STOP_J, SET_WATCHDOG = 31, 33, 34, 35
GET_TCP_OFFSET, IS_STEADY, STOP_SCRIPT = 40, 47, 255
REALTIME = frozenset({6, 9, 10, 11, 24, 25, 26, 27, 38, 58})
"""Commands the script processes and answers `ready` at once (no `done`)."""
ACCEPTED = frozenset({7, 8, 18, 19, 20, 21, 36, 37, 42, 53, 59})
"""Commands with no effect on the emulated arm that succeed (force mode settings, teach ...)."""
UNSUPPORTED = {
    MOVE_J_IK: "moveJ_IK needs inverse kinematics, which the emulator does not have",
    MOVE_L: "moveL needs inverse kinematics, which the emulator does not have",
}
ARRIVED = 1e-6
_MARKERS = ("def rtde_control():", "# HEADER_BEGIN")
_OFFSET = re.compile(r"reg_offset_int = # int register offset\n\s*(\d+)")


@dataclass
class Registers:
    """The general-purpose RTDE registers, lower and upper range (0..47)."""

    int_in: list[int] = field(default_factory=lambda: [0] * 48)
    double_in: list[float] = field(default_factory=lambda: [0.0] * 48)
    int_out: list[int] = field(default_factory=lambda: [0] * 48)
    double_out: list[float] = field(default_factory=lambda: [0.0] * 48)
    updated: dict[int, float] = field(default_factory=dict)
    """When each input int register was last written (for the RTDE watchdog)."""


class ScriptHost(Protocol):
    """What the script uses of the controller that runs it (`controller.Controller` is one): its
    registers, arm, clock and version, the tool and payload it sets, the protective stop."""

    tcp: tuple[float, ...]
    payload: float
    payload_cog: tuple[float, ...]

    @property
    def registers(self) -> Registers: ...

    @property
    def arm(self) -> Arm: ...

    @property
    def clock(self) -> float: ...

    @property
    def version(self) -> tuple[int, int, int, int]: ...

    def protective_stop(self) -> None: ...


def parse_program(text: str) -> int | None:
    """The register offset of ur_rtde's control script, or None for any other program."""
    if not all(marker in text for marker in _MARKERS):
        return None
    match = _OFFSET.search(text)
    return int(match.group(1)) if match else 0


@dataclass
class Move:
    goal: tuple[float, ...]
    speed: float
    acceleration: float


@dataclass
class ControlScript:
    """The state of one run of the control script."""

    offset: int = 0
    executing: bool = False
    waiting: str = ""
    """"move" or "stop" while a synchronous motion blocks the main loop."""
    move: Move | None = None
    background: str = ""
    """"move" or "stop" while an asynchronous motion runs."""
    writes: int = 0
    operation: int = 0
    watchdog: float = 0.0
    started: float = 0.0

    def start(self, ctrl: ScriptHost) -> None:
        self.started = ctrl.clock
        self._progress(ctrl, -1)
        self._out_int(ctrl, 0, READY)

    def cycle(self, ctrl: ScriptHost, now: float) -> str | None:
        """Runs one cycle; None to go on, else why the program ended ("" when asked to)."""
        if self.watchdog > 0:
            last = ctrl.registers.updated.get(self.offset, self.started)
            if now - last > 1.0 / self.watchdog:
                return "RTDE watchdog: the client stopped writing input_int_register_0"
        self._follow_background(ctrl)
        if self.waiting:
            if not self._finished(ctrl, self.waiting):
                return None
            self.waiting = ""
            self.move = None
            self._out_int(ctrl, 0, DONE)
        command = ctrl.registers.int_in[self.offset]
        if command in REALTIME:
            outcome = self._process(ctrl, command)
            self._out_int(ctrl, 0, READY)
            return outcome
        if command == 0:
            self.executing = False
            self._out_int(ctrl, 0, READY)
            return None
        if self.executing:
            return None
        self.executing = True
        outcome = self._process(ctrl, command)
        if outcome is None and not self.waiting and command != PROTECTIVE_STOP:
            self._out_int(ctrl, 0, DONE)
        return outcome

    def _process(self, ctrl: ScriptHost, command: int) -> str | None:
        regs = ctrl.registers
        double = regs.double_in[self.offset : self.offset + 8]
        asynchronous = regs.int_in[self.offset + 1] == 1
        if command in (MOVE_J, MOVE_L_FK):
            return self._move_j(ctrl, Move(tuple(double[:6]), double[6], double[7]), asynchronous)
        if command in (STOP_J, STOP_L):
            return self._stop(ctrl, double[0], asynchronous)
        if command in (SPEED_STOP, SERVO_STOP):
            return self._stop(ctrl, double[0], False)
        if command == SET_PAYLOAD:
            ctrl.payload = double[0]
            if any(double[1:4]) or ctrl.version[0] < 5:
                ctrl.payload_cog = tuple(double[1:4])
        elif command == SET_TCP:
            ctrl.tcp = tuple(double[:6])
        elif command == PROTECTIVE_STOP:
            ctrl.protective_stop()
        elif command == SET_WATCHDOG:
            self.watchdog = max(double[0], 0.0)
            regs.updated[self.offset] = ctrl.clock
        elif command == IS_STEADY:
            self._out_int(ctrl, 1, 1 if ctrl.arm.steady else 0)
        elif command == GET_TCP_OFFSET:
            self._out_doubles(ctrl, ctrl.tcp)
        elif command == 26:  # getStepTime
            regs.double_out[self.offset] = 0.008
        elif command == 27:  # getActualJointPositionsHistory: now is the best history we have
            self._out_doubles(ctrl, ctrl.arm.q)
        elif command == 38:  # getJointTorques
            self._out_doubles(ctrl, (0.0,) * 6)
        elif command == STOP_SCRIPT:
            self.interrupt(ctrl)
            return ""
        elif command in (36, 37):  # within safety limits
            self._out_int(ctrl, 1, 1)
        elif command not in ACCEPTED:
            return UNSUPPORTED.get(command, f"command {command} is not emulated")
        return None

    def _move_j(self, ctrl: ScriptHost, move: Move, asynchronous: bool) -> str | None:
        values = (*move.goal, move.speed, move.acceleration)
        if not all(math.isfinite(x) for x in values) or move.speed <= 0 or move.acceleration <= 0:
            return f"movej with speed {move.speed} and acceleration {move.acceleration}"
        self._stop_background(ctrl)
        self.move = move
        ctrl.arm.move_to(move.goal, move.speed, move.acceleration)
        if asynchronous:
            self.background = "move"
            self._progress(ctrl, 0)
        else:
            self.waiting = "move"
        return None

    def _stop(self, ctrl: ScriptHost, deceleration: float, asynchronous: bool) -> str | None:
        if not (math.isfinite(deceleration) and deceleration > 0):
            return f"stop with deceleration {deceleration}"
        self._stop_background(ctrl)
        self.move = None
        ctrl.arm.stop(deceleration)
        if asynchronous:
            self.background = "stop"
            self._progress(ctrl, 0)
        else:
            self.waiting = "stop"
        return None

    def _finished(self, ctrl: ScriptHost, kind: str) -> bool:
        if kind == "stop":
            return ctrl.arm.steady
        move = self.move
        return (
            move is not None
            and ctrl.arm.steady
            and all(abs(q - g) <= ARRIVED for q, g in zip(ctrl.arm.q, move.goal, strict=True))
        )

    def _follow_background(self, ctrl: ScriptHost) -> None:
        if self.background and self._finished(ctrl, self.background):
            self.background = ""
            if not self.waiting:
                self.move = None
            self._progress(ctrl, -1)

    def _stop_background(self, ctrl: ScriptHost) -> None:
        if self.background:
            self.background = ""
            self._progress(ctrl, -1)

    def interrupt(self, ctrl: ScriptHost, done: bool = False) -> None:
        """The motion ends where the arm is (protective stop, power off, a hand, the end).

        `done`: a synchronous move waiting for the arm counts as finished (a hand moved it),
        else its command stays unanswered (a stop pauses the program in the middle of it).
        """
        self._stop_background(ctrl)
        if self.waiting and done:
            self._out_int(ctrl, 0, DONE)
        self.move = None
        self.waiting = ""

    def resume_move(self, ctrl: ScriptHost) -> None:
        """A stalled move goes on."""
        move = self.move
        if move is not None:
            ctrl.arm.move_to(move.goal, move.speed, move.acceleration)

    @property
    def move_in_progress(self) -> bool:
        return self.move is not None

    def _progress(self, ctrl: ScriptHost, value: int) -> None:
        self.writes = (self.writes + 1) % 128
        if value == 0:
            self.operation = (self.operation + 1) % 128
        word = self.writes * 65536 + self.operation * 16777216
        if value >= 0:
            word += min(value, 32767) + 32768
        self._out_int(ctrl, 2, word)

    def _out_int(self, ctrl: ScriptHost, register: int, value: int) -> None:
        ctrl.registers.int_out[self.offset + register] = value

    def _out_doubles(self, ctrl: ScriptHost, values: tuple[float, ...] | list[float]) -> None:
        for k, value in enumerate(values):
            ctrl.registers.double_out[self.offset + k] = float(value)
