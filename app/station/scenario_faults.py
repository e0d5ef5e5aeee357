"""A scenario's `faults`: what goes wrong and when, the device-level kinds (DESIGN.md section 8)
only when the scenario is played on devices, each with its fields checked."""

from __future__ import annotations

from typing import Any

from app.station.cycle import ScheduledFault
from app.station.scenario_fields import (
    Path,
    Problem,
    after_of,
    known,
    mapping,
    number,
    sequence,
    when_of,
)
from hw.faults import DEVICE_FAULTS, FAULTS, Fault, FaultKind
from planner.model.station import Station

FAULT_KEYS = (
    "at",
    "when",
    "after",
    "kind",
    "resource",
    "effect",
    "instead",
    "count",
    "values",
    "on",
    "release",
    "offset",
    "name",
    "value",
)


def read_faults(
    raw: Any, station: Station, scope: Any, devices: bool
) -> tuple[ScheduledFault, ...]:
    return tuple(
        _read_fault(("faults", k), entry, station, scope, devices)
        for k, entry in enumerate(sequence(raw, ("faults",), "faults"))
    )


def _read_fault(
    where: Path, entry: Any, station: Station, scope: Any, devices: bool = False
) -> ScheduledFault:
    """One entry of `faults`: what goes wrong, and when (`at` a time or `when` a condition)."""
    if not isinstance(entry, dict):
        raise Problem(where, f"a fault is a mapping with keys {', '.join(FAULT_KEYS)}")
    if True in entry:  # YAML 1.1 reads the key `on` as true
        entry = {("on" if key is True else key): value for key, value in entry.items()}
    known(where, "fault", entry, FAULT_KEYS)
    kind = entry.get("kind")
    if kind not in FAULTS:
        raise Problem((*where, "kind"), f"kind must be one of {', '.join(FAULTS)}, not {kind!r}")
    if FaultKind(kind) in DEVICE_FAULTS and not devices:
        raise Problem(
            (*where, "kind"),
            f"'{kind}' is a device-level fault: it is played on emulated devices only "
            "(sp run --devices FILE)",
        )
    when = when_of(entry, where, scope)
    fault = Fault(
        FaultKind(kind),
        resource=str(entry.get("resource", "")),
        effect=str(entry.get("effect", "")),
        instead=str(entry.get("instead", "")),
        count=int(number(entry.get("count", 1), (*where, "count"), integer=True)),
        values=dict(mapping(entry.get("values"), (*where, "values"), "values")),
        **_device_fields(where, entry, station),
    )
    if fault.resource and fault.resource not in {r.name for r in station.resources}:
        raise Problem((*where, "resource"), f"unknown resource '{fault.resource}'")
    for key, name in (("effect", fault.effect), ("instead", fault.instead)):
        if name and name not in station.model.transition_index:
            raise Problem((*where, key), f"unknown transition '{name}'")
    for name in fault.values:
        if name not in station.model.variable_index:
            raise Problem((*where, "values", name), f"unknown variable '{name}'")
    text = ", ".join(f"{key}={entry[key]}" for key in FAULT_KEYS[3:] if key in entry)
    at = number(entry["at"], (*where, "at")) if "at" in entry else None
    return ScheduledFault(fault, at, when, text, after_of(entry, where, when))


def _device_fields(where: Path, entry: dict[str, Any], station: Station) -> dict[str, Any]:
    """`on`, `release`, `offset`, `name`, `value` of a device-level fault, checked."""
    fields: dict[str, Any] = {}
    for key in ("on", "release"):
        if key in entry:
            if not isinstance(entry[key], bool):
                raise Problem((*where, key), f"'{key}' is true or false")
            fields[key] = entry[key]
    if "offset" in entry:
        offset = sequence(entry["offset"], (*where, "offset"), "offset")
        if len(offset) != 6:
            raise Problem((*where, "offset"), "'offset' is six joint offsets in rad")
        fields["offset"] = tuple(number(x, (*where, "offset", k)) for k, x in enumerate(offset))
    kind = FaultKind(entry["kind"])
    needs = {
        FaultKind.PUSH: ("resource", "offset"),
        FaultKind.STUCK: ("resource", "name"),
        FaultKind.PROTECTIVE_STOP: ("resource",),
        FaultKind.POWER: ("resource",),
        FaultKind.FREEZE: ("resource",),
        FaultKind.GARBAGE: ("resource",),
        FaultKind.RESTART: ("resource",),
    }.get(kind, ())
    for key in needs:
        if key not in entry:
            raise Problem(where, f"a '{kind}' fault needs '{key}'")
    if "name" in entry:
        name = str(entry["name"])
        if name not in station.model.variable_index:
            raise Problem((*where, "name"), f"unknown variable '{name}'")
        fields["name"] = name
        if "value" in entry:
            domain = station.model.variable(name).domain
            if entry["value"] not in domain:
                shown = ", ".join(str(v).lower() if isinstance(v, bool) else str(v) for v in domain)
                raise Problem((*where, "value"), f"{name} takes one of {shown}")
            fields["value"] = entry["value"]
    return fields
