"""The station's device file: which driver serves each resource, where, and with which wiring.

The model says what a station can do; the device file says how its variables reach the
devices (seed 001 section V, layer 0).  Per device: its driver, its address, its time-outs,
and its wiring, one entry per model variable:

- a UR robot (`driver: ur`) has named joint poses, tools (TCP and payload) and motion limits;
  its variables are wired to roles: `pose` and `last_pose` (measured), `move_to` and `tool`
  (commands);
- a Modbus device (`driver: modbus`) wires each variable to a register: by its name in the
  documented register map of the device's kind (`map: connector`, hw.modbus.emulator.kinds), or as a
  coil, a discrete input, or a holding or input register (a `bit` of it, or a word with
  `values`: the codes of an enumeration);
- a person's watch (`driver: watch`) serves the card and done variables the model declares.

Commands are wired to what can be written; measured variables to what can be read; decision
and estimated variables may be read too, as observed product states (a product tracker).
Every measured and command variable of the model is wired exactly once (`hw.device_file.wiring`).  A
file that breaks any of this is refused with every problem located (file, line, column).
An `emulation` part says how a scenario's faults act on the emulated device (`sp emulate`).
The format is documented in docs/devices.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum

from hw.modbus.registers import Point
from hw.pipelines import RobotPrograms
from planner.model.expressions import Value
from planner.model.flat import SourceLocation, VariableKind

DEVICE_KEYS = (
    "name",
    "driver",
    "resource",
    "address",
    "unit",
    "map",
    "heartbeat_timeout",
    "poll_period",
    "motion",
    "poses",
    "tools",
    "wiring",
    "emulation",
)
MODBUS_PORT = 502
UR_CONTROL_PORT = 30100  # the UR emulator's control channel (hw.emulator_kit.control)
MODBUS_CONTROL_PORT = 5099


class DriverKind(StrEnum):
    UR = "ur"
    MODBUS = "modbus"
    WATCH = "watch"


class RobotRole(StrEnum):
    """What a robot variable is wired to (the pipelines of hw.pipelines)."""

    POSE = "pose"  # measured: the named pose the joints are at, `unknown` off every pose
    LAST_POSE = "last_pose"  # measured: the last named pose the robot was at
    MOVE_TO = "move_to"  # command: a named pose, sent as a moveJ to its joint vector
    TOOL = "tool"  # command: a tool name, sent as set TCP and set payload


@dataclass(frozen=True)
class RegisterWire:
    """Where a variable lives on a Modbus device: a bit, or a word (with enumeration codes)."""

    point: Point
    bit: int | None = None  # a bit of a word
    codes: tuple[tuple[int, Value], ...] = ()  # word code -> model value


@dataclass(frozen=True)
class Wire:
    """One model variable wired to a robot role or a register (or to a watch)."""

    variable: str
    kind: VariableKind
    role: RobotRole | None = None
    register: RegisterWire | None = None
    location: SourceLocation | None = None


@dataclass(frozen=True)
class Emulation:
    """How scenario faults act on the emulated device: model effects (without the resource's
    name, e.g. `lock.connect`) to the emulator's fault operations."""

    blocked: Mapping[str, str] = field(default_factory=dict)
    replaced: Mapping[str, str] = field(default_factory=dict)
    control_port: int = 0
    engaged_at: tuple[str, ...] = ()  # a nutrunner bites only with a robot at these poses
    engaged_where: tuple[SourceLocation, ...] = field(default=(), compare=False)


@dataclass(frozen=True)
class DeviceSpec:
    name: str
    driver: DriverKind
    resource: str  # the model resource it serves ("" for station-wide inputs)
    host: str = ""
    port: int = 0
    unit: int = 1  # the Modbus device id
    map: str = ""  # the documented register map of its kind (hw.modbus.emulator.kinds), if any
    heartbeat_timeout: float = 1.0
    poll_period: float = 0.05
    wires: tuple[Wire, ...] = ()
    programs: RobotPrograms | None = None
    emulation: Emulation = field(default_factory=Emulation)
    location: SourceLocation | None = None


@dataclass(frozen=True)
class DeviceFile:
    file: str
    station: str
    devices: tuple[DeviceSpec, ...]

    def device(self, name: str) -> DeviceSpec:
        return next(d for d in self.devices if d.name == name)
