"""One device of the device file as the runner sees it: model values in and out.

An adapter puts a driver (hw.ur, hw.modbus) or a watch behind the model's variables with
the pipelines of `hw.pipelines`: `read` gives the device's measured values (and observed
product states), `write` takes the runner's command values, `alive` says whether the runner
may trust the device this round.  Nothing here blocks: drivers do their I/O on their own
threads and processes, and adapters only look at their newest reading.

A reading no pipeline can explain makes the device not alive (the runner marks its resource
unavailable after its heartbeat time-out), and its values are not passed on.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from hw.device_file import DeviceSpec, RobotRole, Wire
from hw.link import LinkStatus
from hw.modbus.registers import Point, Table
from hw.pipelines import UNKNOWN, Nonsense, PoseAndLast, RobotPrograms, track_move
from planner.model.expressions import Value
from planner.model.flat import VariableKind

Raw = int | bool  # a Modbus value: a bit, or a 16-bit word


@dataclass
class AdapterReport:
    measured: dict[str, Value] = field(default_factory=dict)
    observed: dict[str, Value] = field(default_factory=dict)
    alive: bool = False


class Adapter(Protocol):
    spec: DeviceSpec

    def start(self) -> None: ...

    def restart(self, start: Mapping[str, Value], now: float) -> None: ...

    def close(self) -> None: ...

    def read(self) -> AdapterReport: ...

    def write(self, commands: Mapping[str, Value]) -> None: ...

    def status(self) -> LinkStatus: ...


# -- robots ----------------------------------------------------------------------------------------


class Driver(Protocol):
    """The life cycle and link every driver has."""

    def start(self) -> None: ...

    def close(self) -> None: ...

    @property
    def available(self) -> bool: ...

    def status(self) -> LinkStatus: ...


class RobotDriver(Driver, Protocol):
    """What a robot adapter needs of its driver (hw.ur.driver.URDriver)."""

    def latest(self) -> RobotSample | None: ...

    def move_j(self, q: tuple[float, ...], speed: float, acceleration: float) -> None: ...

    def set_tool(self, tcp: tuple[float, ...], payload_kg: float) -> None: ...


class RobotSample(Protocol):
    @property
    def q(self) -> tuple[float, ...]: ...

    @property
    def protective_stop(self) -> bool: ...

    @property
    def received(self) -> float: ...

    @property
    def running(self) -> bool: ...


class RobotAdapter:
    """A UR robot: joints to named poses (`pose`, `last_pose`), named poses to moveJ
    (`move_to`), tool names to TCP and payload (`tool`)."""

    def __init__(self, spec: DeviceSpec, driver: RobotDriver, start: Mapping[str, Value]) -> None:
        assert spec.programs is not None
        self.spec = spec
        self.driver = driver
        self.programs: RobotPrograms = spec.programs
        self.roles = {w.role: w.variable for w in spec.wires if w.role is not None}
        pos = str(start.get(self.roles.get(RobotRole.POSE, ""), UNKNOWN))
        last = str(start.get(self.roles.get(RobotRole.LAST_POSE, ""), pos))
        self.pose = PoseAndLast(pos, last)
        self.target: str | None = None  # the named pose a commanded move is heading for
        self.sent: dict[RobotRole, Value] = {}
        self.nonsense = ""
        self.not_before = 0.0  # readings older than this are from before a restart

    def restart(self, start: Mapping[str, Value], now: float) -> None:
        """The world was put back to `start` at `now` (time.monotonic()): forget the rest."""
        pos = str(start.get(self.roles.get(RobotRole.POSE, ""), UNKNOWN))
        self.pose = PoseAndLast(pos, str(start.get(self.roles.get(RobotRole.LAST_POSE, ""), pos)))
        self.target, self.sent, self.not_before = None, {}, now

    def start(self) -> None:
        self.driver.start()

    def close(self) -> None:
        self.driver.close()

    def read(self) -> AdapterReport:
        sample = self.driver.latest()
        if sample is None or not self.driver.available or sample.received < self.not_before:
            return AdapterReport()
        if self.target is not None and (sample.protective_stop or not sample.running):
            self.target = None  # the move was aborted: wherever it stopped is where it is
        try:
            self.pose = track_move(self.programs.poses, sample.q, self.pose, self.target)
        except Nonsense as problem:
            self.nonsense = f"nonsense from the robot: {problem}"
            return AdapterReport()
        self.nonsense = ""
        if self.pose.pos == self.target:
            self.target = None
        measured: dict[str, Value] = {}
        if RobotRole.POSE in self.roles:
            measured[self.roles[RobotRole.POSE]] = self.pose.pos
        if RobotRole.LAST_POSE in self.roles:
            measured[self.roles[RobotRole.LAST_POSE]] = self.pose.last
        return AdapterReport(measured, alive=True)

    def write(self, commands: Mapping[str, Value]) -> None:
        for role in (RobotRole.TOOL, RobotRole.MOVE_TO):
            name = self.roles.get(role)
            if name is None or name not in commands:
                continue
            value = commands[name]
            first = role not in self.sent
            if not first and self.sent[role] == value:
                continue
            self.sent[role] = value
            if role is RobotRole.TOOL and str(value) in self.programs.tools:
                tcp, payload = self.programs.tool(str(value))
                self.driver.set_tool(tcp.pose, payload.mass)
            elif (
                role is RobotRole.MOVE_TO and not first and str(value) in self.programs.poses.poses
            ):
                # the first value is where the runner believes the robot is: no move
                move = self.programs.goto(str(value))
                self.target = str(value)
                self.driver.move_j(move.joints, move.speed, move.acceleration)

    def status(self) -> LinkStatus:
        status = self.driver.status()
        if self.nonsense:
            return LinkStatus(
                False, status.latency_ms, status.last_data, self.nonsense, status.restarts
            )
        return status


# -- Modbus devices --------------------------------------------------------------------------------


class RegisterDriver(Driver, Protocol):
    """What a register adapter needs of its driver (hw.modbus.driver.ModbusDriver)."""

    def latest(self) -> RegisterSample | None: ...

    def write(self, point: Point, value: Raw) -> None: ...


class RegisterSample(Protocol):
    @property
    def values(self) -> Mapping[Point, Raw]: ...

    @property
    def received(self) -> float: ...


class RegisterAdapter:
    """A Modbus device: bits and words to the model's values and back.  Observed product
    states are passed on when they change, not on the first reading (the runner's estimates
    after a restart are not overwritten by a device that just came up)."""

    def __init__(self, spec: DeviceSpec, driver: RegisterDriver) -> None:
        self.spec = spec
        self.driver = driver
        self.wires = [w for w in spec.wires if w.register is not None]
        self.seen: dict[str, Value] = {}
        self.nonsense = ""
        self.not_before = 0.0

    def restart(self, start: Mapping[str, Value], now: float) -> None:
        self.seen, self.not_before = {}, now

    def start(self) -> None:
        self.driver.start()

    def close(self) -> None:
        self.driver.close()

    def read(self) -> AdapterReport:
        sample = self.driver.latest()
        if sample is None or not self.driver.available or sample.received < self.not_before:
            return AdapterReport()
        try:
            values = {
                w.variable: decode(w, sample.values)
                for w in self.wires
                if w.kind is not VariableKind.COMMAND
            }
        except Nonsense as problem:
            self.nonsense = f"nonsense from the device: {problem}"
            return AdapterReport()
        self.nonsense = ""
        report = AdapterReport(alive=True)
        for wire in self.wires:
            if wire.variable not in values:
                continue
            value = values[wire.variable]
            if wire.kind is VariableKind.MEASURED:
                report.measured[wire.variable] = value
            elif wire.variable in self.seen and self.seen[wire.variable] != value:
                report.observed[wire.variable] = value
            self.seen[wire.variable] = value
        return report

    def write(self, commands: Mapping[str, Value]) -> None:
        sample = self.driver.latest()
        for wire in self.wires:
            if wire.kind is VariableKind.COMMAND and wire.variable in commands:
                assert wire.register is not None
                word = encode(wire, commands[wire.variable], sample.values if sample else {})
                self.driver.write(wire.register.point, word)

    def status(self) -> LinkStatus:
        status = self.driver.status()
        if self.nonsense:
            return LinkStatus(
                False, status.latency_ms, status.last_data, self.nonsense, status.restarts
            )
        return status


def decode(wire: Wire, values: Mapping[Point, Raw]) -> Value:
    """A wired variable's value from the raw reading; `Nonsense` when it cannot be."""
    register = wire.register
    assert register is not None
    raw = values.get(register.point)
    if raw is None:
        raise Nonsense(f"no value for {register.point} ({wire.variable})")
    if register.point.table.is_bit:
        if not isinstance(raw, bool):
            raise Nonsense(f"{register.point} is not a bit: {raw!r}")
        return raw
    if isinstance(raw, bool) or not isinstance(raw, int) or not 0 <= raw <= 0xFFFF:
        raise Nonsense(f"{register.point} is not a 16-bit word: {raw!r}")
    if register.bit is not None:
        return bool(raw >> register.bit & 1)
    if register.codes:
        codes = dict(register.codes)
        if raw not in codes:
            raise Nonsense(f"{wire.variable}: code {raw} at {register.point} means nothing")
        return codes[raw]
    if raw not in (0, 1):
        raise Nonsense(f"{wire.variable}: {raw} at {register.point} is not 0 or 1")
    return raw == 1


def encode(wire: Wire, value: Value, values: Mapping[Point, Raw]) -> Raw:
    """The raw value that says `value` (a bit of a word keeps the word's other bits)."""
    register = wire.register
    assert register is not None
    if register.point.table is Table.COIL:
        return bool(value)
    if register.bit is not None:
        word = values.get(register.point, 0)
        word = word if isinstance(word, int) and not isinstance(word, bool) else 0
        mask = 1 << register.bit
        return word | mask if value else word & ~mask
    if register.codes:
        return next(code for code, meaning in register.codes if meaning == value)
    return 1 if value else 0


# -- a person's watch ------------------------------------------------------------------------------


class WatchAdapter:
    """A person's watch: the card the runner shows, and Done when the person taps it.

    `answer_after`: seconds after which a simulated person taps Done by themselves (headless
    runs on emulated devices); None for people at the web HMI.
    """

    def __init__(
        self,
        spec: DeviceSpec,
        card: str,
        done: str,
        start: Mapping[str, Value],
        answer_after: float | None = None,
    ) -> None:
        self.spec = spec
        self.card_name, self.done_name = card, done
        self.card = start.get(card, "idle")
        self.done = start.get(done, "idle")
        self.answer_after = answer_after
        self.shown_at: float | None = None
        self.now = 0.0

    def restart(self, start: Mapping[str, Value], now: float) -> None:
        self.card = start.get(self.card_name, "idle")
        self.done = start.get(self.done_name, "idle")
        self.shown_at = None

    def start(self) -> None:
        """In the station process: nothing to connect."""

    def close(self) -> None:
        """Nothing to stop."""

    def advance(self, now: float) -> None:
        self.now = now
        if self.card == "idle" and self.done != "idle":
            self.done = "idle"  # the watch clears a confirmed card once the station takes it
        waiting = self.card != "idle" and self.done == "idle"
        if not waiting:
            self.shown_at = None
        elif self.shown_at is None:
            self.shown_at = now
        elif self.answer_after is not None and now - self.shown_at >= self.answer_after:
            self.tap()

    def tap(self) -> bool:
        """The person tapped Done: the card shown is confirmed."""
        if self.card == "idle" or self.done != "idle":
            return False
        self.done = self.card
        return True

    def read(self) -> AdapterReport:
        return AdapterReport({self.done_name: self.done}, alive=True)

    def write(self, commands: Mapping[str, Value]) -> None:
        if self.card_name in commands:
            self.card = commands[self.card_name]

    def status(self) -> LinkStatus:
        return LinkStatus(True, 0.0)
