"""A Modbus device's entry of a device file: address, unit, register map and wired registers."""

from __future__ import annotations

import yaml

from hw.device_file.fields import (
    Fields,
    mapping_pairs,
    read_address,
    read_integer,
    read_wires,
    unexpected,
)
from hw.device_file.spec import (
    MODBUS_PORT,
    DeviceSpec,
    RegisterWire,
    Wire,
)
from hw.modbus.maps import MAPS, register_map
from hw.modbus.registers import Kind, Point, RegisterMap, Table
from planner.model.expressions import Value
from planner.model.flat import Variable, VariableKind
from planner.model.station import Station
from planner.reading.yaml_reader import Reader


def read_modbus(
    reader: Reader, fields: Fields, station: Station, device: DeviceSpec
) -> DeviceSpec | None:
    unexpected(reader, fields, ("motion", "poses", "tools"), "modbus")
    for key in ("address", "wiring"):
        if key not in fields:
            reader.error(fields["name"][1], f"a modbus device needs '{key}'")
            return None
    host, port = read_address(reader, fields["address"][1], MODBUS_PORT)
    unit = read_integer(reader, fields["unit"][1], "unit", 0, 255) if "unit" in fields else 1
    kind, documented = "", None
    if "map" in fields:
        kind = reader.scalar(fields["map"][1], "map") or ""
        if kind not in MAPS:
            reader.error(fields["map"][1], f"no register map '{kind}'; known: {', '.join(MAPS)}")
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

    wires = read_wires(reader, fields["wiring"][1], station, device.resource, wire)
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
            for key, value in mapping_pairs(reader, node, "values")
        ]
    domain = {str(v): v for v in variable.domain}
    for _, text in pairs:
        if text not in domain:
            reader.error(node, f"'{text}' is no value of '{variable.name}'")
    missing = set(domain) - {text for _, text in pairs}
    if variable.kind is VariableKind.COMMAND and missing:
        reader.error(node, f"no code for {', '.join(sorted(missing))} of '{variable.name}'")
    return tuple((code, domain[text]) for code, text in pairs if text in domain)
