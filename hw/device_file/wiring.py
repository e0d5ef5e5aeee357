"""The device file against the model: every measured and command variable wired exactly once.

A measured variable nobody reads would never change; a command nobody writes would never
reach a device; one wired twice would have two truths.  Decision and estimated variables may
be wired once too (a product tracker reports them as observed), or not at all.
"""

from __future__ import annotations

from collections.abc import Sequence

import yaml

from hw.device_file.spec import DeviceSpec
from planner.model.flat import VariableKind
from planner.model.station import Station
from planner.reading.yaml_reader import Reader

MUST_BE_WIRED = (VariableKind.MEASURED, VariableKind.COMMAND)


def check_wiring(
    reader: Reader, devices: Sequence[DeviceSpec], station: Station, at: yaml.Node
) -> None:
    """Records a located problem per variable wired twice, and per one left unwired (at `at`,
    the file's `devices:` key)."""
    wired: dict[str, DeviceSpec] = {}
    for device in devices:
        for wire in device.wires:
            first = wired.get(wire.variable)
            if first is not None and first.location is not None and wire.location is not None:
                reader.error_at(
                    wire.location,
                    f"'{wire.variable}' is wired already, by device '{first.name}' "
                    f"(line {first.location.line})",
                )
                continue
            wired[wire.variable] = device
    for variable in station.model.variables:
        if variable.kind in MUST_BE_WIRED and variable.name not in wired:
            kind = "measured" if variable.kind is VariableKind.MEASURED else "command"
            reader.error(at, f"the {kind} variable '{variable.name}' is wired to no device")


def check_scene(reader: Reader, devices: Sequence[DeviceSpec]) -> None:
    """The emulated scene's poses (`engaged_at`) are named poses of the file's robots."""
    poses = {name for d in devices if d.programs for name in d.programs.poses.poses}
    for device in devices:
        emulation = device.emulation
        for pose, where in zip(emulation.engaged_at, emulation.engaged_where, strict=True):
            if pose not in poses:
                reader.error_at(where, f"'{pose}' is no named pose of the file's robots")
