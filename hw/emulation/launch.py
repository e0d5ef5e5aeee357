"""Starting the emulators of a device file (`sp emulate`, the demo, tests).

One process per device: a UR controller emulator per robot (`hw.ur.emulator.server`, on the
robot's own loopback address, since ur_rtde's ports are fixed) and a Modbus emulator per
Modbus device (`hw.modbus.emulator.server`, serving the documented map the device file names).
Robots start at the named pose of their start value, the PLC with the start values it
reports.  `launch` returns the device file as the station must see it (with the ports the
emulators really bound, which differ from the file's when tests ask for any free port) and
where each emulator's control channel is.
"""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

from hw.device_file.spec import DeviceFile, DeviceSpec, DriverKind, RobotRole
from hw.emulation.scene import Scene
from hw.emulator_kit.control import ControlError, control
from hw.emulator_kit.process import EmulatorFailed, EmulatorProcess, start
from hw.modbus.maps import register_map
from planner.model.expressions import Value


@dataclass
class Emulators:
    """Running emulators: the device file pointing at them, and their control channels."""

    devices: DeviceFile
    processes: dict[str, EmulatorProcess] = field(default_factory=dict)
    controls: dict[str, tuple[str, int]] = field(default_factory=dict)
    scene: Scene | None = None

    def stop(self) -> None:
        if self.scene is not None:
            self.scene.stop()
        for process in self.processes.values():
            process.stop()

    def __enter__(self) -> Emulators:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def launch(
    devices: DeviceFile,
    start_values: Mapping[str, Value],
    *,
    hosts: Mapping[str, str] | None = None,
    any_port: bool = False,
) -> Emulators:
    """Starts an emulator per device (`hosts` moves devices to other addresses; `any_port`
    lets Modbus servers and control channels take free ports); stops them all if one fails."""
    moved = [replace(d, host=(hosts or {}).get(d.name, d.host)) for d in devices.devices]
    emulated = [d for d in moved if d.driver is not DriverKind.WATCH]
    for device in emulated:
        if device.driver is DriverKind.MODBUS and not device.map:
            raise EmulatorFailed(f"device '{device.name}' names no register map to emulate")
    running = Emulators(replace(devices, devices=tuple(moved)))
    with ThreadPoolExecutor(max(1, len(emulated))) as pool:
        futures = {d.name: pool.submit(_start, d, start_values, any_port) for d in emulated}
        problems = []
        for name, future in futures.items():
            try:
                running.processes[name] = future.result()
            except EmulatorFailed as problem:
                problems.append(f"{name}: {problem}")
    if problems:
        running.stop()
        raise EmulatorFailed("; ".join(problems))
    return _connected(running, start_values)


def attach(devices: DeviceFile) -> Emulators:
    """The emulators already serving a device file (`sp emulate` started them): their
    control channels at the file's ports, each asked for its state once, so that a device
    nobody serves is said now (`EmulatorFailed`), not as silence later."""
    running = Emulators(devices)
    problems = []
    for device in devices.devices:
        if device.driver is DriverKind.WATCH:
            continue
        where = (device.host, device.emulation.control_port)
        try:
            control(*where, {"op": "state"})
        except ControlError as problem:
            problems.append(f"{device.name}: {problem}")
            continue
        running.controls[device.name] = where
    if problems:
        raise EmulatorFailed("; ".join(problems))
    running.scene = Scene(running.devices, running.controls)
    return running


def _start(
    device: DeviceSpec, start_values: Mapping[str, Value], any_port: bool
) -> EmulatorProcess:
    control_port = 0 if any_port else device.emulation.control_port
    if device.driver is DriverKind.UR:
        joints = _start_joints(device, start_values)
        args = ["--host", device.host, "--control-port", str(control_port)]
        return start("hw.ur.emulator.server", *args, "--joints", ",".join(map(str, joints)))
    port = 0 if any_port else device.port
    spec = f"{device.map}:{device.name}:{device.host}:{port}:{device.unit}"
    return start(
        "hw.modbus.emulator.server", "--device", spec, "--control", f"{device.host}:{control_port}"
    )


def _start_joints(device: DeviceSpec, start_values: Mapping[str, Value]) -> tuple[float, ...]:
    assert device.programs is not None
    poses = device.programs.poses.poses
    pose_variable = next((w.variable for w in device.wires if w.role is RobotRole.POSE), "")
    pose = str(start_values.get(pose_variable, ""))
    return poses[pose] if pose in poses else next(iter(poses.values()))


def _connected(running: Emulators, start_values: Mapping[str, Value]) -> Emulators:
    """The device file at the bound ports; each Modbus device told its start values."""
    devices = []
    for device in running.devices.devices:
        process = running.processes.get(device.name)
        if process is None:
            devices.append(device)
            continue
        running.controls[device.name] = (device.host, process.ports["control"])
        if device.driver is DriverKind.MODBUS:
            device = replace(device, port=process.ports[device.name])
            values = start_state(device, start_values)
            if values:
                request = {"op": "set", "device": device.name, "values": values}
                control(*running.controls[device.name], request)
        devices.append(device)
    running.devices = replace(running.devices, devices=tuple(devices))
    running.scene = Scene(running.devices, running.controls)
    return running


def start_state(device: DeviceSpec, start_values: Mapping[str, Value]) -> dict[str, Value]:
    """What a Modbus device shows at the start, by register name: for each wired variable
    whose start value differs from the device's power-on value, the start value (a scenario
    that begins with a tool locked on starts with the connector locked)."""
    documented = register_map(device.map)
    values: dict[str, Value] = {}
    for wire in device.wires:
        register = documented.at(wire.register.point) if wire.register else None
        if register is None or wire.variable not in start_values:
            continue
        if start_values[wire.variable] != register.initial:
            values[register.name] = start_values[wire.variable]
    return values
