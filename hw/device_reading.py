"""Reading one device of a device file (hw.device_file), with located problems."""

from __future__ import annotations

from collections.abc import Callable

import yaml

from hw.device_file import (
    DEVICE_KEYS,
    MODBUS_CONTROL_PORT,
    MODBUS_PORT,
    UR_CONTROL_PORT,
    DeviceSpec,
    DriverKind,
    Emulation,
    RegisterWire,
    RobotRole,
    Wire,
    read_address,
    read_integer,
    read_number,
    read_vector,
    robot_programs,
)
from hw.modbus.kinds import KINDS, register_map
from hw.modbus.registers import Kind, Point, RegisterMap, Table
from hw.pipelines import RobotPrograms, Tool
from planner.model.expressions import Value
from planner.model.flat import TransitionKind, Variable, VariableKind
from planner.model.station import Station
from planner.reading.yaml_reader import Reader, closest

Fields = dict[str, tuple[yaml.Node, yaml.Node]]
JOINTS = 6
READ_ONLY = (VariableKind.DECISION, VariableKind.ESTIMATED)


def read_device(
    reader: Reader, node: yaml.Node, station: Station
) -> tuple[DeviceSpec, yaml.Node] | None:
    """One entry of `devices:`; None when it is too broken to use (errors recorded)."""
    fields = reader.mapping(node, "a device", DEVICE_KEYS, required=("name", "driver"))
    if fields is None or "name" not in fields or "driver" not in fields:
        return None
    name = reader.name(fields["name"][1], "device name")
    driver_text = reader.scalar(fields["driver"][1], "driver")
    if name is None or driver_text is None:
        return None
    if driver_text not in [k.value for k in DriverKind]:
        kinds = ", ".join(k.value for k in DriverKind)
        reader.error(
            fields["driver"][1], f"a device's driver is one of {kinds}, not '{driver_text}'"
        )
        return None
    driver = DriverKind(driver_text)
    resource = _resource(reader, fields, station, required=driver is not DriverKind.MODBUS)
    if resource is None:
        return None
    base = DeviceSpec(name, driver, resource, location=reader.at(node))
    base = _timing(reader, fields, base)
    match driver:
        case DriverKind.UR:
            device = _robot(reader, fields, station, base)
        case DriverKind.MODBUS:
            device = _modbus(reader, fields, station, base)
        case DriverKind.WATCH:
            device = _watch(reader, fields, station, base, node)
    if device is None:
        return None
    emulation = _emulation(reader, fields, station, device)
    return DeviceSpec(**{**device.__dict__, "emulation": emulation}), fields["name"][1]


def _resource(reader: Reader, fields: Fields, station: Station, *, required: bool) -> str | None:
    if "resource" not in fields:
        if required:
            reader.error(fields["name"][1], "this device needs the 'resource' it serves")
            return None
        return ""
    text = reader.scalar(fields["resource"][1], "resource")
    known = [r.name for r in station.resources]
    if text not in known:
        hint = closest(text or "", known)
        extra = f" (did you mean '{hint}'?)" if hint else ""
        reader.error(fields["resource"][1], f"the model has no resource '{text}'{extra}")
        return None
    return text


def _timing(reader: Reader, fields: Fields, device: DeviceSpec) -> DeviceSpec:
    heartbeat, poll = device.heartbeat_timeout, device.poll_period
    if "heartbeat_timeout" in fields:
        what = "heartbeat_timeout (seconds)"
        heartbeat = read_number(reader, fields["heartbeat_timeout"][1], what, positive=True)
    if "poll_period" in fields:
        what = "poll_period (seconds)"
        poll = read_number(reader, fields["poll_period"][1], what, positive=True)
    return DeviceSpec(**{**device.__dict__, "heartbeat_timeout": heartbeat, "poll_period": poll})


def _unexpected(reader: Reader, fields: Fields, keys: tuple[str, ...], driver: str) -> None:
    for key in keys:
        if key in fields:
            reader.error(fields[key][0], f"'{key}' does not belong to a {driver} device")


# -- robots --------------------------------------------------------------------------------------


def _robot(
    reader: Reader, fields: Fields, station: Station, device: DeviceSpec
) -> DeviceSpec | None:
    _unexpected(reader, fields, ("unit", "poll_period"), "ur")
    for key in ("address", "poses", "wiring"):
        if key not in fields:
            reader.error(fields["name"][1], f"a ur device needs '{key}'")
            return None
    host, _ = read_address(reader, fields["address"][1], None)
    motion = _motion(reader, fields)
    poses = {
        reader.scalar(key, "pose name") or "": read_vector(reader, value, "a joint vector", JOINTS)
        for key, value in _pairs(reader, fields["poses"][1], "poses")
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

    wires = _wires(reader, fields["wiring"][1], station, device.resource, wire)
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
    for key, value in _pairs(reader, node, "tools"):
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


# -- Modbus devices ------------------------------------------------------------------------------


def _modbus(
    reader: Reader, fields: Fields, station: Station, device: DeviceSpec
) -> DeviceSpec | None:
    _unexpected(reader, fields, ("motion", "poses", "tools"), "modbus")
    for key in ("address", "wiring"):
        if key not in fields:
            reader.error(fields["name"][1], f"a modbus device needs '{key}'")
            return None
    host, port = read_address(reader, fields["address"][1], MODBUS_PORT)
    unit = read_integer(reader, fields["unit"][1], "unit", 0, 255) if "unit" in fields else 1
    kind, documented = "", None
    if "map" in fields:
        kind = reader.scalar(fields["map"][1], "map") or ""
        if kind not in KINDS:
            reader.error(fields["map"][1], f"no register map '{kind}'; known: {', '.join(KINDS)}")
        else:
            documented = register_map(kind)

    def wire(variable: Variable, node: yaml.Node) -> Wire | None:
        if isinstance(node, yaml.ScalarNode):
            register = _named_register(reader, node, variable, documented)
        else:
            register = _register(reader, node, variable)
        if register is None:
            return None
        return Wire(variable.name, variable.kind, register=register, location=reader.at(node))

    wires = _wires(reader, fields["wiring"][1], station, device.resource, wire)
    changes = {"host": host, "port": port, "unit": unit, "map": kind, "wires": wires}
    return DeviceSpec(**{**device.__dict__, **changes})


def _named_register(
    reader: Reader, node: yaml.Node, variable: Variable, documented: RegisterMap | None
) -> RegisterWire | None:
    """A register named in the device kind's documented map."""
    name = str(node.value)
    if documented is None:
        reader.error(node, f"'{name}' names a register: give the device's 'map' first")
        return None
    try:
        register = documented[name]
    except KeyError as problem:
        reader.error(node, str(problem.args[0]))
        return None
    if not _direction_fits(reader, node, variable, register.point.table):
        return None
    boolean = set(variable.domain) == {True, False}
    if register.kind is Kind.BOOL or not register.codes:
        if not boolean or register.kind not in (Kind.BOOL, Kind.UNSIGNED):
            reader.error(node, f"register '{name}' holds no values of '{variable.name}'")
            return None
        return RegisterWire(register.point)
    if register.kind is not Kind.ENUMERATION:
        reader.error(node, f"register '{name}' is a {register.kind.value}, not an enumeration")
        return None
    domain = {str(v): v for v in variable.domain}
    strange = [code for code in register.codes if code not in domain]
    if strange:
        shown = ", ".join(strange)
        reader.error(node, f"register '{name}' has codes {shown} that '{variable.name}' lacks")
        return None
    return RegisterWire(register.point, codes=tuple(enumerate(domain[c] for c in register.codes)))


def _direction_fits(reader: Reader, node: yaml.Node, variable: Variable, table: Table) -> bool:
    if variable.kind is VariableKind.COMMAND and not table.writable:
        reader.error(node, f"the command '{variable.name}' must go to a coil or holding_register")
        return False
    if variable.kind is not VariableKind.COMMAND and table is Table.COIL:
        reader.error(node, f"'{variable.name}' is read, not written: not a coil")
        return False
    return True


def _register(reader: Reader, node: yaml.Node, variable: Variable) -> RegisterWire | None:
    tables = [t.value for t in Table]
    spec = reader.mapping(node, f"the register of '{variable.name}'", (*tables, "bit", "values"))
    if spec is None:
        return None
    chosen = [key for key in spec if key in tables]
    if len(chosen) != 1:
        reader.error(node, f"give exactly one of {', '.join(tables)}")
        return None
    table = Table(chosen[0])
    address = read_integer(reader, spec[table.value][1], "a register address", 0, 65535)
    bit = read_integer(reader, spec["bit"][1], "a bit", 0, 15) if "bit" in spec else None
    if table.is_bit and bit is not None:
        reader.error(spec["bit"][0], f"a {table.value} is a single bit already")
    if not _direction_fits(reader, node, variable, table) or address < 0:
        return None
    codes = _codes(reader, spec, variable, table.is_bit or bit is not None)
    return RegisterWire(Point(table, address), bit, codes)


def _codes(
    reader: Reader, spec: Fields, variable: Variable, is_bit: bool
) -> tuple[tuple[int, Value], ...]:
    boolean = set(variable.domain) == {True, False}
    first = next(iter(spec.values()))[1]
    if is_bit or boolean:
        if "values" in spec:
            reader.error(spec["values"][0], "a boolean needs no 'values'")
        if not boolean:
            reader.error(first, f"a bit holds a boolean; '{variable.name}' is not one")
        return ()
    if "values" not in spec:
        reader.error(first, f"give the 'values' of '{variable.name}' (codes)")
        return ()
    node = spec["values"][1]
    if isinstance(node, yaml.SequenceNode):
        pairs = [(k, reader.scalar(item, "a value") or "") for k, item in enumerate(node.value)]
    else:
        pairs = [
            (read_integer(reader, key, "a code", 0, 65535), reader.scalar(value, "a value") or "")
            for key, value in _pairs(reader, node, "values")
        ]
    domain = {str(v): v for v in variable.domain}
    for _, text in pairs:
        if text not in domain:
            reader.error(node, f"'{text}' is no value of '{variable.name}'")
    missing = set(domain) - {text for _, text in pairs}
    if variable.kind is VariableKind.COMMAND and missing:
        reader.error(node, f"no code for {', '.join(sorted(missing))} of '{variable.name}'")
    return tuple((code, domain[text]) for code, text in pairs if text in domain)


# -- watches -------------------------------------------------------------------------------------


def _watch(
    reader: Reader, fields: Fields, station: Station, device: DeviceSpec, node: yaml.Node
) -> DeviceSpec | None:
    _unexpected(reader, fields, tuple(k for k in DEVICE_KEYS[3:] if k != "emulation"), "watch")
    person = next(r for r in station.resources if r.name == device.resource)
    if person.watch is None:
        reader.error(fields["resource"][1], f"the model declares no watch for '{person.name}'")
        return None
    kinds = station.model.variable_index
    location = reader.at(node)
    wires = tuple(
        Wire(name, station.model.variable(name).kind, location=location)
        for name in (person.watch.card, person.watch.done)
        if name in kinds
    )
    return DeviceSpec(**{**device.__dict__, "wires": wires})


# -- wiring and emulation ------------------------------------------------------------------------


def _pairs(reader: Reader, node: yaml.Node, what: str) -> list[tuple[yaml.Node, yaml.Node]]:
    if not isinstance(node, yaml.MappingNode):
        reader.error(node, f"{what} must be a mapping (name: value)")
        return []
    return list(node.value)


def _wires(
    reader: Reader,
    node: yaml.Node,
    station: Station,
    resource: str,
    wire: Callable[[Variable, yaml.Node], Wire | None],
) -> tuple[Wire, ...]:
    wires = []
    names = [v.name for v in station.model.variables]
    for key, value in _pairs(reader, node, "wiring"):
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


def _emulation(reader: Reader, fields: Fields, station: Station, device: DeviceSpec) -> Emulation:
    default = UR_CONTROL_PORT if device.driver is DriverKind.UR else MODBUS_CONTROL_PORT
    if "emulation" not in fields:
        return Emulation(control_port=default)
    keys = ("blocked", "replaced", "control_port", "engaged_at")
    spec = reader.mapping(fields["emulation"][1], "emulation", keys) or {}
    port = default
    if "control_port" in spec:
        port = read_integer(reader, spec["control_port"][1], "control_port", 1, 65535)
    effects = {
        t.name
        for t in station.model.transitions
        if t.kind is TransitionKind.EFFECT and t.name.startswith(device.resource + ".")
    }
    maps: dict[str, dict[str, str]] = {}
    for key in ("blocked", "replaced"):
        maps[key] = {}
        for effect_node, op_node in _pairs(reader, spec[key][1], key) if key in spec else []:
            effect = reader.scalar(effect_node, "an effect") or ""
            if f"{device.resource}.{effect}" not in effects:
                shown = ", ".join(sorted(e.partition(".")[2] for e in effects)) or "none"
                reader.error(
                    effect_node, f"'{effect}' is no effect of '{device.resource}' ({shown})"
                )
                continue
            maps[key][effect] = reader.scalar(op_node, "an emulator operation") or ""
    engaged: list[tuple[str, yaml.Node]] = []
    if "engaged_at" in spec:
        for item in reader.sequence(spec["engaged_at"][1], "engaged_at"):
            engaged.append((reader.scalar(item, "a pose") or "", item))
    poses = tuple(p for p, _ in engaged)
    where = tuple(reader.at(n) for _, n in engaged)
    return Emulation(maps["blocked"], maps["replaced"], port, poses, where)
