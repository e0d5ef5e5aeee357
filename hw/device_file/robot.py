"""A UR robot's entry of a device file: poses, tools, motion limits, wired roles."""

from __future__ import annotations

import yaml

from hw.device_file.fields import (
    JOINTS,
    Fields,
    mapping_pairs,
    read_address,
    read_number,
    read_vector,
    read_wires,
    robot_programs,
    unexpected,
)
from hw.device_file.spec import (
    DeviceSpec,
    RobotRole,
    Wire,
)
from hw.pipelines import RobotPrograms, Tool
from planner.model.flat import Variable, VariableKind
from planner.model.station import Station
from planner.reading.yaml_reader import Reader


def read_robot(
    reader: Reader, fields: Fields, station: Station, device: DeviceSpec
) -> DeviceSpec | None:
    unexpected(reader, fields, ("unit", "poll_period"), "ur")
    for key in ("address", "poses", "wiring"):
        if key not in fields:
            reader.error(fields["name"][1], f"a ur device needs '{key}'")
            return None
    host, _ = read_address(reader, fields["address"][1], None)
    motion = _motion(reader, fields)
    poses = {
        reader.scalar(key, "pose name") or "": read_vector(reader, value, "a joint vector", JOINTS)
        for key, value in mapping_pairs(reader, fields["poses"][1], "poses")
    }
    tools = _tools(reader, fields["tools"][1]) if "tools" in fields else {}
    programs = robot_programs(poses, tools, *motion)
    if isinstance(programs, str):
        reader.error(fields["poses"][1], programs)
        return None
    roles = [r.value for r in RobotRole]

    def wire(variable: Variable, node: yaml.Node) -> Wire | None:
        text = reader.scalar(node, "a robot role")
        if text not in roles:
            reader.error(node, f"a robot variable is wired to one of {', '.join(roles)}")
            return None
        return _robot_wire(reader, node, variable, RobotRole(text), programs, fields)

    wires = read_wires(reader, fields["wiring"][1], station, device.resource, wire)
    return DeviceSpec(**{**device.__dict__, "host": host, "wires": wires, "programs": programs})


def _motion(reader: Reader, fields: Fields) -> tuple[float, float, float]:
    speed, acceleration, tolerance = 1.05, 1.4, 0.01
    if "motion" in fields:
        motion = reader.mapping(
            fields["motion"][1], "motion", ("speed", "acceleration", "tolerance")
        )
        for key, (_, value) in (motion or {}).items():
            number = read_number(reader, value, f"motion {key}", positive=True)
            if key == "speed":
                speed = number
            elif key == "acceleration":
                acceleration = number
            else:
                tolerance = number
    return speed, acceleration, tolerance


def _tools(reader: Reader, node: yaml.Node) -> dict[str, Tool]:
    tools = {}
    for key, value in mapping_pairs(reader, node, "tools"):
        name = reader.scalar(key, "tool name") or ""
        spec = reader.mapping(value, f"tool '{name}'", ("tcp", "payload", "cog"), ("tcp",))
        if spec is None or "tcp" not in spec:
            continue
        tcp = read_vector(reader, spec["tcp"][1], "a TCP (x, y, z, rx, ry, rz)", 6)
        mass = read_number(reader, spec["payload"][1], "payload (kg)") if "payload" in spec else 0.0
        cog = read_vector(reader, spec["cog"][1], "a centre of gravity", 3) if "cog" in spec else ()
        if len(tcp) == 6:
            tools[name] = Tool(
                (tcp[0], tcp[1], tcp[2], tcp[3], tcp[4], tcp[5]),
                mass,
                (cog[0], cog[1], cog[2]) if len(cog) == 3 else (0.0, 0.0, 0.0),
            )
    return tools


def _robot_wire(
    reader: Reader,
    node: yaml.Node,
    variable: Variable,
    role: RobotRole,
    programs: RobotPrograms,
    fields: Fields,
) -> Wire | None:
    commands = (RobotRole.MOVE_TO, RobotRole.TOOL)
    if (variable.kind is VariableKind.COMMAND) != (role in commands):
        direction = "command" if role in commands else "measured"
        reader.error(node, f"'{role}' is for a {direction} variable; '{variable.name}' is not one")
        return None
    if role is RobotRole.TOOL:
        missing = [str(v) for v in variable.domain if v not in programs.tools]
        where, what = fields.get("tools", fields["name"])[1], "tools"
    else:
        if "unknown" not in variable.domain and role is not RobotRole.MOVE_TO:
            reader.error(node, f"'{variable.name}' needs the value 'unknown' (off every pose)")
        missing = [str(v) for v in variable.domain if v not in programs.poses.poses]
        missing = [v for v in missing if v != "unknown"]
        where, what = fields["poses"][1], "poses"
    if missing:
        reader.error(where, f"{what} has no entry for {', '.join(missing)} of '{variable.name}'")
    return Wire(variable.name, variable.kind, role=role, location=reader.at(node))
