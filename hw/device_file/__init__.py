"""The station's device file: read, checked against the model, every problem located.

`load_devices` is the entry point; `spec` holds what a device file says (drivers, addresses,
wiring, emulation), `reading` reads one device entry (with `robot` and `modbus` for those
drivers and `fields` for the small readers they share), `wiring` checks that every variable
is wired exactly once.  The format: docs/devices.md.
"""

from __future__ import annotations

from hw.device_file.reading import read_device
from hw.device_file.spec import DeviceFile
from hw.device_file.wiring import check_scene, check_wiring
from planner.model.flat import SourceLocation
from planner.model.station import Station
from planner.reading.yaml_reader import Reader


def load_devices(text: str, file: str, station: Station) -> DeviceFile:
    """Reads and checks a device file against `station`; `ModelError` lists every problem."""

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
