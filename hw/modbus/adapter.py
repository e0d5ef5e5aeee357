"""A Modbus device behind the model's variables: bits and words to values and back."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Protocol

from hw.adapter import AdapterReport, Driver
from hw.device_file.spec import DeviceSpec, Wire
from hw.link import LinkStatus
from hw.modbus.registers import Point, Table
from hw.pipelines import Nonsense
from planner.model.expressions import Value
from planner.model.flat import VariableKind

Raw = int | bool  # a Modbus value: a bit, or a 16-bit word


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
            return replace(status, connected=False, error=self.nonsense)
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
