"""The station's device file: which driver serves each resource, where, and with which wiring.

The model says what a station can do; the device file says how its variables reach the
devices (seed 001 section V, layer 0).  Per device: its driver, its address, its time-outs,
and its wiring, one entry per model variable:

- a UR robot (`driver: ur`) has named joint poses, tools (TCP and payload) and motion limits;
  its variables are wired to roles: `pose` and `last_pose` (measured), `move_to` and `tool`
  (commands);
- a Modbus device (`driver: modbus`) wires each variable to a register: by its name in the
  documented register map of the device's kind (`map: connector`, hw.modbus.kinds), or as a
  coil, a discrete input, or a holding or input register (a `bit` of it, or a word with
  `values`: the codes of an enumeration);
- a person's watch (`driver: watch`) serves the card and done variables the model declares.

Commands are wired to what can be written; measured variables to what can be read; decision
and estimated variables may be read too, as observed product states (a product tracker).
Every measured and command variable of the model is wired exactly once (`hw.wiring`).  A
file that breaks any of this is refused with every problem located (file, line, column).
An `emulation` part says how a scenario's faults act on the emulated device (`sp emulate`).
The format is documented in docs/devices.md.
"""

from __future__ import annotations

import ipaddress
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum

import yaml

from hw.modbus.registers import Point
from hw.pipelines import NamedPoses, RobotPrograms, Tool
from planner.model.expressions import Value
from planner.model.flat import SourceLocation, VariableKind
from planner.model.station import Station
from planner.reading.yaml_reader import Reader

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
UR_CONTROL_PORT = 30100  # the UR emulator's control channel (hw.emulation.control)
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
    map: str = ""  # the documented register map of its kind (hw.modbus.kinds), if any
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


def load_devices(text: str, file: str, station: Station) -> DeviceFile:
    """Reads and checks a device file against `station`; `ModelError` lists every problem."""
    from hw.device_reading import read_device
    from hw.wiring import check_scene, check_wiring

    reader = Reader(text, file)
    root = reader.compose()
    reader.raise_if_errors()
    if root is None:
        reader.error_at(SourceLocation(file, 1, 1), "the device file is empty")
        reader.raise_if_errors()
        raise AssertionError  # raised above
    top = reader.mapping(root, "the device file", ("station", "devices"), required=("devices",))
    reader.raise_if_errors()
    assert top is not None
    name = reader.scalar(top["station"][1], "station") if "station" in top else None
    if name is not None and station.name and name != station.name:
        reader.error(top["station"][1], f"this file is for station '{name}', not '{station.name}'")
    devices, names = [], []
    for node in reader.sequence(top["devices"][1], "devices"):
        read = read_device(reader, node, station)
        if read is not None:
            devices.append(read[0])
            names.append((read[0].name, read[1]))
    reader.unique(names, "device")
    check_wiring(reader, devices, station, top["devices"][0])
    check_scene(reader, devices)
    reader.raise_if_errors()
    return DeviceFile(file, name or station.name, tuple(devices))


# -- small readers shared by the device readers ----------------------------------------------------


def read_number(reader: Reader, node: yaml.Node, what: str, *, positive: bool = False) -> float:
    text = reader.scalar(node, what)
    if text is None:
        return math.nan
    try:
        number = float(text)
    except ValueError:
        reader.error(node, f"{what} must be a number, not '{text}'")
        return math.nan
    if not math.isfinite(number) or (positive and number <= 0):
        reader.error(node, f"{what} must be a {'positive ' if positive else ''}number")
        return math.nan
    return number


def read_integer(reader: Reader, node: yaml.Node, what: str, low: int, high: int) -> int:
    text = reader.scalar(node, what)
    if text is None:
        return -1
    if not text.isdigit() or not low <= int(text) <= high:
        reader.error(node, f"{what} must be a whole number from {low} to {high}, not '{text}'")
        return -1
    return int(text)


def read_vector(reader: Reader, node: yaml.Node, what: str, size: int) -> tuple[float, ...]:
    items = reader.sequence(node, what)
    if len(items) != size:
        if isinstance(node, yaml.SequenceNode):
            reader.error(node, f"{what} needs {size} numbers, not {len(items)}")
        return ()
    return tuple(read_number(reader, item, what) for item in items)


def read_address(reader: Reader, node: yaml.Node, default_port: int | None) -> tuple[str, int]:
    """`HOST` (a robot: the client's ports are fixed) or `HOST:PORT` (Modbus)."""
    text = reader.scalar(node, "address") or ""
    host, _, port = text.partition(":")
    try:
        ipaddress.ip_address(host)
    except ValueError:
        reader.error(node, f"address '{text}' needs an IP address such as 127.0.0.2")
        return "", 0
    if default_port is None:
        if port:
            reader.error(node, "a robot's address has no port (ur_rtde's ports are fixed)")
        return host, 0
    if not port:
        return host, default_port
    if not port.isdigit() or not 0 < int(port) < 65536:
        reader.error(node, f"port '{port}' must be a number from 1 to 65535")
        return host, 0
    return host, int(port)


def robot_programs(
    poses: Mapping[str, tuple[float, ...]],
    tools: Mapping[str, Tool],
    speed: float,
    acceleration: float,
    tolerance: float,
) -> RobotPrograms | str:
    """The robot's programs, or why its poses cannot be told apart."""
    try:
        named = NamedPoses(poses, tolerance)
    except ValueError as problem:
        return str(problem)
    return RobotPrograms(named, tools, speed, acceleration)
