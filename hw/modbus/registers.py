"""Where a device keeps a value (`Point`), and what the value means (`Register`).

A device's register map is data: each register has a name, a point (table and address,
from 0 in each table: the four tables are separate blocks, coils and discrete inputs are
addressed per bit), a type and, for words, an enumeration or a scale.  The emulators serve
these maps, the documentation lists them (`docs/modbus_devices.md`) and the station's device
file names points from them.

Values travel as raw Modbus values: `bool` for coils and discrete inputs, 0..65535 for
registers.  `encode` and `decode` translate between raw values and what they mean (an
enumeration name, a number in engineering units, a signed number in two's complement).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property


class Table(enum.Enum):
    """The four Modbus tables: bits or 16-bit words, written by the client or only read."""

    COIL = "coil"
    DISCRETE_INPUT = "discrete_input"
    HOLDING_REGISTER = "holding_register"
    INPUT_REGISTER = "input_register"

    @property
    def is_bit(self) -> bool:
        return self in (Table.COIL, Table.DISCRETE_INPUT)

    @property
    def writable(self) -> bool:
        """Whether a Modbus client may write it (coils and holding registers)."""
        return self in (Table.COIL, Table.HOLDING_REGISTER)


@dataclass(frozen=True, slots=True, order=True)
class Point:
    """One value of a device: a bit (coil, discrete input) or a word (register)."""

    table: Table
    address: int

    def __post_init__(self) -> None:
        if not 0 <= self.address <= 0xFFFF:
            raise ValueError(f"Modbus address {self.address} is not in 0..65535")

    def __str__(self) -> str:
        return f"{self.table.value} {self.address}"


class Kind(enum.Enum):
    """How a register's raw value is read."""

    BOOL = "bool"  # a coil or discrete input
    UNSIGNED = "unsigned"  # 0..65535, times `scale`
    SIGNED = "signed"  # two's complement -32768..32767, times `scale`
    ENUMERATION = "enumeration"  # a code, one of `codes`
    BITS = "bits"  # a status word: bit i means `codes[i]`
    COUNTER = "counter"  # counts up, wraps from 65535 to 0


@dataclass(frozen=True, slots=True)
class Register:
    """A documented value: its name, point, kind and meaning.

    `codes`: the names of an enumeration's codes 0, 1, 2 ... (or a status word's bits 0, 1 ...);
    `scale` and `unit`: value = raw * scale in `unit`; `low`..`high`: the documented range of
    the value (raw for enumerations and counters), outside which a reading is nonsense;
    `initial`: the value at power-on.
    """

    name: str
    point: Point
    kind: Kind
    meaning: str
    initial: bool | int | float | str = 0
    codes: tuple[str, ...] = ()
    scale: float = 1.0
    unit: str = ""
    low: float | None = None
    high: float | None = None

    def __post_init__(self) -> None:
        if self.point.table.is_bit != (self.kind is Kind.BOOL):
            raise ValueError(f"register '{self.name}': a {self.kind.value} in a {self.point}")
        if self.kind in (Kind.ENUMERATION, Kind.BITS) and not self.codes:
            raise ValueError(f"register '{self.name}': a {self.kind.value} needs codes")

    @property
    def initial_raw(self) -> int:
        return encode(self, self.initial)

    def range(self) -> tuple[float, float]:
        """The documented range of the value (raw codes for enumerations)."""
        if self.kind is Kind.BOOL:
            return 0, 1
        if self.kind is Kind.ENUMERATION:
            return 0, len(self.codes) - 1
        if self.kind is Kind.BITS:
            return 0, (1 << len(self.codes)) - 1
        natural = (-32768 * self.scale, 32767 * self.scale)
        if self.kind is not Kind.SIGNED:
            natural = (0, 0xFFFF * self.scale)
        low = natural[0] if self.low is None else self.low
        high = natural[1] if self.high is None else self.high
        return low, high


def encode(register: Register, value: object, *, raw: bool = False) -> int:
    """The raw value (0/1 for bits, 0..65535 for words) that means `value`.

    Without `raw`, `value` is what the register means: a bool, an enumeration name, a number
    in the register's unit; it must be in the documented range.  With `raw`, `value` is the
    word itself and only needs to fit in 16 bits (to play a device that says nonsense).
    """
    if raw:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"a raw value of '{register.name}' is an integer, not {value!r}")
        top = 1 if register.kind is Kind.BOOL else 0xFFFF
        if not 0 <= value <= top:
            raise ValueError(f"raw value {value} of '{register.name}' does not fit: 0..{top}")
        return value
    if register.kind is Kind.BOOL:
        if not isinstance(value, bool):
            raise ValueError(f"'{register.name}' is true or false, not {value!r}")
        return int(value)
    if register.kind is Kind.ENUMERATION:
        if value not in register.codes:
            shown = ", ".join(register.codes)
            raise ValueError(f"'{register.name}' is one of {shown}, not {value!r}")
        return register.codes.index(str(value))
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"'{register.name}' is a number, not {value!r}")
    low, high = register.range()
    if not low <= value <= high:
        raise ValueError(
            f"{value} is outside the documented range {low:g}..{high:g} of '{register.name}' "
            '(send it with "raw": true to play a device that says nonsense)'
        )
    word = round(value / register.scale)
    return word & 0xFFFF if register.kind is Kind.SIGNED else word


def decode(register: Register, word: int) -> bool | int | float | str:
    """What raw value `word` means (an enumeration code out of range stays a number)."""
    if register.kind is Kind.BOOL:
        return bool(word)
    if register.kind is Kind.ENUMERATION:
        return register.codes[word] if 0 <= word < len(register.codes) else word
    if register.kind in (Kind.BITS, Kind.COUNTER):
        return word
    if register.kind is Kind.SIGNED and word >= 0x8000:
        word -= 0x10000
    scaled = word * register.scale
    return word if register.scale == 1 else round(scaled, 6)


def heartbeat() -> Register:
    """Input register 0 of every device: the counter a driver watches to tell a device whose
    logic froze from one that merely answers."""
    return Register(
        "heartbeat",
        Point(Table.INPUT_REGISTER, 0),
        Kind.COUNTER,
        "counts up every 100 ms while the device's logic runs",
    )


def status_word(bits: tuple[str, ...], initial: int) -> Register:
    """Input register 1: the device's discrete inputs as one word, for masters that read words
    only (bit k is `bits[k]`)."""
    return Register(
        "status",
        Point(Table.INPUT_REGISTER, 1),
        Kind.BITS,
        "the discrete inputs as one word",
        initial,
        codes=bits,
    )


@dataclass(frozen=True)
class RegisterMap:
    """The registers of one device kind, by name and by point."""

    kind: str
    description: str
    registers: tuple[Register, ...]

    def __post_init__(self) -> None:
        names = [r.name for r in self.registers]
        points = [r.point for r in self.registers]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.kind}: a register name twice")
        if len(set(points)) != len(points):
            raise ValueError(f"{self.kind}: a point twice")

    def __iter__(self) -> Iterator[Register]:
        return iter(self.registers)

    def __getitem__(self, name: str) -> Register:
        for register in self.registers:
            if register.name == name:
                return register
        known = ", ".join(r.name for r in self.registers)
        raise KeyError(f"{self.kind} has no register '{name}'; known: {known}")

    def point(self, name: str) -> Point:
        return self[name].point

    def at(self, point: Point) -> Register | None:
        return self.by_point.get(point)

    @cached_property
    def by_point(self) -> Mapping[Point, Register]:
        return {r.point: r for r in self.registers}

    def table(self, table: Table) -> tuple[Register, ...]:
        """The registers of one table, by address."""
        return tuple(
            sorted(
                (r for r in self.registers if r.point.table is table), key=lambda r: r.point.address
            )
        )


def markdown(register_map: RegisterMap) -> str:
    """The map as a Markdown table (docs/modbus_devices.md shows these, a test compares)."""
    lines = [
        "| Table | Address | Name | Type | Meaning | Initial |",
        "|---|---|---|---|---|---|",
    ]
    for register in sorted(register_map, key=lambda r: (_TABLES.index(r.point.table), r.point)):
        initial = decode(register, register.initial_raw)
        if register.kind is Kind.COUNTER:
            shown_initial = "0, counting"
        elif isinstance(initial, bool):
            shown_initial = str(initial).lower()
        else:
            shown_initial = f"{initial:g}" if isinstance(initial, float) else str(initial)
        lines.append(
            f"| {register.point.table.value} | {register.point.address} | `{register.name}` "
            f"| {_type(register)} | {register.meaning} | {shown_initial} |"
        )
    return "\n".join(lines)


_TABLES = list(Table)


def _type(register: Register) -> str:
    if register.kind in (Kind.ENUMERATION, Kind.BITS):
        label = "enumeration" if register.kind is Kind.ENUMERATION else "status bits"
        return f"{label}: " + ", ".join(f"{k} {c}" for k, c in enumerate(register.codes))
    if register.kind is Kind.BOOL:
        return "bool"
    if register.kind is Kind.COUNTER:
        return "counter, wraps 65535 to 0"
    low, high = register.range()
    signed = "signed (two's complement)" if register.kind is Kind.SIGNED else "unsigned"
    unit = f" {register.unit}" if register.unit else ""
    return f"{signed}, raw x {register.scale:g}{unit}, {low:g}..{high:g}{unit}"
