"""The small readers every device entry uses: numbers, addresses, mappings, wiring lists."""

from __future__ import annotations

import ipaddress
import math
from collections.abc import Callable, Mapping

import yaml

from hw.device_file.spec import (
    Wire,
)
from hw.pipelines import NamedPoses, RobotPrograms, Tool
from planner.model.flat import Variable
from planner.model.station import Station
from planner.reading.yaml_reader import Reader, closest


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


Fields = dict[str, tuple[yaml.Node, yaml.Node]]


JOINTS = 6


def unexpected(reader: Reader, fields: Fields, keys: tuple[str, ...], driver: str) -> None:
    for key in keys:
        if key in fields:
            reader.error(fields[key][0], f"'{key}' does not belong to a {driver} device")


def mapping_pairs(reader: Reader, node: yaml.Node, what: str) -> list[tuple[yaml.Node, yaml.Node]]:
    if not isinstance(node, yaml.MappingNode):
        reader.error(node, f"{what} must be a mapping (name: value)")
        return []
    return list(node.value)


def read_wires(
    reader: Reader,
    node: yaml.Node,
    station: Station,
    resource: str,
    wire: Callable[[Variable, yaml.Node], Wire | None],
) -> tuple[Wire, ...]:
    wires = []
    names = [v.name for v in station.model.variables]
    for key, value in mapping_pairs(reader, node, "wiring"):
        text = reader.scalar(key, "a variable") or ""
        name = f"{resource}.{text}" if f"{resource}.{text}" in names else text
        if name not in names:
            hint = closest(name, names)
            extra = f" (did you mean '{hint}'?)" if hint else ""
            reader.error(key, f"the model has no variable '{text}'{extra}")
            continue
        made = wire(station.model.variable(name), value)
        if made is not None:
            wires.append(made)
    return tuple(wires)
