"""A device's behaviour over its registers: a clock-free state machine.

Life cycle of a `DeviceLogic`, which the emulator drives and tests drive by hand:

- created at power-on time `now`, every register at its documented initial value;
- `write(point, word)` when a Modbus client writes a coil or holding register: the value is
  stored, the logic reacts at its next step (a command is a level, not an event);
- `step(now)` lets the device act up to time `now`.  Transitions happen at their own
  deadlines, whatever the steps in between: stepping every millisecond or once at the end
  gives the same registers;
- `set(name, value)` when a person or a fault changes the world (a bolt pair placed, a
  sensor bit forced), `stick(name)` freezes one value as a broken sensor does, `reset()`
  clears the device's faults.

Subclasses override `advance` (one transition at a time, returning whether one happened)
and extend `reset` and `faults`; they change registers with `put`, which a stuck value
ignores.  Times are seconds of any clock that does not go back.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from hw.modbus.registers import Kind, Point, RegisterMap, decode, encode

HEARTBEAT_PERIOD = 0.1  # seconds per count of every device's heartbeat register


@dataclass
class Shots:
    """A fault that strikes the next `times` occasions, or every one (`always`)."""

    times: int = 0
    always: bool = False

    def take(self) -> bool:
        if self.always:
            return True
        if self.times > 0:
            self.times -= 1
            return True
        return False

    def as_json(self) -> dict[str, Any]:
        return {"times": self.times, "always": self.always}

    @classmethod
    def from_request(cls, request: Mapping[str, Any]) -> Shots:
        """`{"times": N}` (0 ends the fault) or `{"always": true}`."""
        always = request.get("always", False)
        times = request.get("times", 0 if always else 1)
        if not isinstance(always, bool):
            raise ValueError("'always' is true or false")
        if isinstance(times, bool) or not isinstance(times, int) or times < 0:
            raise ValueError("'times' is a count: 0, 1, 2 ...")
        return cls(times, always)


class DeviceLogic:
    """Registers and behaviour of one device (see the module's life cycle)."""

    register_map: ClassVar[RegisterMap]
    timing_defaults: ClassVar[Mapping[str, float]] = {}

    def __init__(self, now: float, timing: Mapping[str, float] | None = None) -> None:
        self.timing = dict(self.timing_defaults)
        self.set_timing(timing or {})
        self.now = now
        self.since = now  # when the device entered its present phase
        self.raw: dict[Point, int] = {r.point: r.initial_raw for r in self.register_map}
        self._truth = dict(self.raw)  # what the logic says, whatever a stuck value shows
        self.stuck: dict[str, int] = {}
        self._epoch, self._beats = now, 0  # heartbeat counts since power-on
        self._status = [r for r in self.register_map if r.kind is Kind.BITS]
        self._has_heartbeat = any(r.name == "heartbeat" for r in self.register_map)

    def __getitem__(self, name: str) -> int:
        """The raw value of a register, as a client would read it."""
        return self.raw[self.register_map.point(name)]

    def truth(self, name: str) -> int:
        """The raw value the device's logic holds (a stuck value shows another)."""
        return self._truth[self.register_map.point(name)]

    def value(self, name: str) -> bool | int | float | str:
        register = self.register_map[name]
        return decode(register, self.raw[register.point])

    def put(self, name: str, word: int) -> None:
        """The device changes one of its values (a stuck value keeps showing what it shows)."""
        point = self.register_map.point(name)
        self._truth[point] = word
        if name not in self.stuck and self.raw[point] != word:
            self.raw[point] = word
            self._mirror(name)

    def write(self, point: Point, word: int) -> None:
        """A Modbus client wrote a coil or holding register."""
        register = self.register_map.at(point)
        if register is None or not point.table.writable:
            raise ValueError(f"{self.register_map.kind} has no writable {point}")
        self._truth[point] = self.raw[point] = word

    def set(self, name: str, value: object, *, raw: bool = False) -> None:
        """A person or a fault changes a value (see `registers.encode` for `raw`)."""
        register = self.register_map[name]
        word = encode(register, value, raw=raw)
        self._truth[register.point] = self.raw[register.point] = word
        if name in self.stuck:
            self.stuck[name] = word
        self._mirror(name)

    def stick(self, name: str, value: object | None = None, *, raw: bool = False) -> None:
        """The value `name` shows stays at `value` (or where it is) until `reset`."""
        register = self.register_map[name]
        if register.point.table.writable:
            raise ValueError(f"'{name}' is a command ({register.point}), not a sensor")
        word = self.raw[register.point] if value is None else encode(register, value, raw=raw)
        self.stuck[name] = self.raw[register.point] = word
        self._mirror(name)

    def _mirror(self, name: str) -> None:
        """Status words repeat the bits they name: keep them up to date."""
        for status in self._status:
            if name in status.codes:
                word = 0
                for bit, code in enumerate(status.codes):
                    if self.raw[self.register_map.point(code)]:
                        word |= 1 << bit
                self.put(status.name, word)

    def step(self, now: float) -> None:
        """Acts up to time `now`."""
        if now < self.now:
            raise ValueError(f"time went back from {self.now} to {now}")
        if self._has_heartbeat:
            beats = int((now - self._epoch) / HEARTBEAT_PERIOD)
            if beats > self._beats:
                self.put("heartbeat", (self.truth("heartbeat") + beats - self._beats) & 0xFFFF)
                self._beats = beats
        while self.advance(now):
            pass
        self.now = now

    def advance(self, now: float) -> bool:
        """Makes the next transition due by `now`; False when there is none."""
        return False

    def noticed(self) -> float:
        """When a command the device acts on now took effect: it was written at the last step
        (clients' writes come between steps), or it waited for the phase it now ends
        (`since`), whichever is later.  Using this instead of the
        step's own time keeps a device's behaviour independent of how often it is stepped."""
        return max(self.since, self.now)

    def set_timing(self, timing: Mapping[str, float]) -> None:
        for key, seconds in timing.items():
            if key not in self.timing_defaults:
                known = ", ".join(self.timing_defaults) or "none"
                raise ValueError(f"{self.register_map.kind} has no delay '{key}'; known: {known}")
            if isinstance(seconds, bool) or not isinstance(seconds, int | float) or seconds < 0:
                raise ValueError(f"delay '{key}' is a number of seconds, not {seconds!r}")
            self.timing[key] = float(seconds)

    def reset(self) -> None:
        """Clears the device's faults; stuck values show the truth again."""
        unstuck = list(self.stuck)
        self.stuck.clear()
        for name in unstuck:
            point = self.register_map.point(name)
            self.raw[point] = self._truth[point]
            self._mirror(name)

    def faults(self) -> dict[str, Any]:
        return {"stuck": {name: self.value(name) for name in self.stuck}}

    def state(self) -> dict[str, Any]:
        """All registers (meaning and raw word), faults and delays, for the control channel."""
        return {
            "kind": self.register_map.kind,
            "values": {r.name: decode(r, self.raw[r.point]) for r in self.register_map},
            "raw": {r.name: self.raw[r.point] for r in self.register_map},
            "faults": self.faults(),
            "timing": dict(self.timing),
        }

    def flag(self, name: str, on: bool) -> None:
        self.put(name, int(on))
