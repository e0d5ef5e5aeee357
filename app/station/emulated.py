"""A station on emulated devices: the emulators of a device file, and the devices on them.

`sp run --devices`, `sp serve --devices --emulate` and the tests that play experiments
through the real protocols all start the same way: the device file is checked against the
model, an emulator per device is started (robots at their start poses, the PLC showing the
start's product states), and the station's drivers connect to them (`StationDevices`),
with the scenario's faults and people's maintenance acting on the emulators
(`EmulatedWorld`).  `EmulatedStation` stops all of it, emulators included, on exit.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from hw.device_file import load_devices
from hw.device_file.spec import DeviceFile
from hw.emulation.launch import Emulators, attach, launch
from hw.emulation.world import EmulatedWorld
from hw.station_devices import StationDevices
from planner.model.expressions import Value
from planner.model.station import Station


def read_device_file(path: str, station: Station) -> DeviceFile:
    """The device file at `path`, checked against `station` (`ModelError` when it is wrong;
    `OSError` when it cannot be read)."""
    return load_devices(Path(path).read_text(encoding="utf-8"), path, station)


@dataclass
class EmulatedStation:
    """Running emulators and the station's devices on them."""

    emulators: Emulators
    world: EmulatedWorld
    devices: StationDevices

    def close(self) -> None:
        try:
            self.devices.close()
        finally:
            self.emulators.stop()

    def __enter__(self) -> EmulatedStation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def emulate(
    station: Station,
    devices: DeviceFile,
    start: Mapping[str, Value],
    *,
    hosts: Mapping[str, str] | None = None,
    any_port: bool = False,
    answer_after: float | None = None,
) -> EmulatedStation:
    """Starts the emulators and connects the station's devices to them.

    `start`: the station's start values (every variable); `hosts`/`any_port`: see
    `hw.emulation.launch`; `answer_after`: a simulated person taps Done on their watch after
    that many seconds (headless runs), None for people at the HMI.
    """
    emulators = launch(devices, start, hosts=hosts, any_port=any_port)
    return _on(emulators, station, start, answer_after, put_back=False)


def attach_to(
    station: Station,
    devices: DeviceFile,
    start: Mapping[str, Value],
    *,
    answer_after: float | None = None,
) -> EmulatedStation:
    """The station's devices on emulators already serving `devices` (`sp emulate`): the
    world is put back to `start` first (faults cleared, robots moved there by hand, Modbus
    devices restarted showing it), as for an experiment; the emulators keep running after."""
    return _on(attach(devices), station, start, answer_after, put_back=True)


def _on(
    emulators: Emulators,
    station: Station,
    start: Mapping[str, Value],
    answer_after: float | None,
    *,
    put_back: bool,
) -> EmulatedStation:
    """The station's devices on running `emulators` (stopped again if that fails);
    `put_back`: the world is first put back to `start` (emulators started earlier)."""
    try:
        world = EmulatedWorld(emulators.devices, emulators.controls, station)
        if put_back:
            world.restart(start)
        on = StationDevices(
            emulators.devices, station, start, world=world, answer_after=answer_after
        )
    except BaseException:
        emulators.stop()
        raise
    return EmulatedStation(emulators, world, on)


def start_values(station: Station, start: Mapping[str, Value]) -> dict[str, Value]:
    """Every variable's start value: the model's initial values, then a scenario's `start`."""
    return {**{v.name: v.initial for v in station.model.variables}, **start}
