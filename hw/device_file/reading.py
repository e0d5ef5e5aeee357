"""Reading one device of a device file (hw.device_file.spec), with located problems."""

from __future__ import annotations

import yaml

from hw.device_file.fields import (
    Fields,
    mapping_pairs,
    read_integer,
    read_number,
    unexpected,
)
from hw.device_file.modbus import read_modbus
from hw.device_file.robot import read_robot
from hw.device_file.spec import (
    DEVICE_KEYS,
    MODBUS_CONTROL_PORT,
    UR_CONTROL_PORT,
    DeviceSpec,
    DriverKind,
    Emulation,
    Wire,
)
from planner.model.flat import TransitionKind
from planner.model.station import Station
from planner.reading.yaml_reader import Reader, closest


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
            device = read_robot(reader, fields, station, base)
        case DriverKind.MODBUS:
            device = read_modbus(reader, fields, station, base)
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


def _watch(
    reader: Reader, fields: Fields, station: Station, device: DeviceSpec, node: yaml.Node
) -> DeviceSpec | None:
    unexpected(reader, fields, tuple(k for k in DEVICE_KEYS[3:] if k != "emulation"), "watch")
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
        for effect_node, op_node in mapping_pairs(reader, spec[key][1], key) if key in spec else []:
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
