"""Scenario faults and people's maintenance, acted out on the emulated devices.

A scenario names faults in the model's words (DESIGN.md section 8): a resource disconnects,
an effect is blocked or replaced, a person sets values.  On emulated devices each becomes
what would happen to the real device, through the emulators' control channels:

- `disconnect` / `reconnect`: the network of every device of the resource goes silent / up;
- `block_effect` / `unblock_effect`, `replace_effect`: the device fault the device file's
  `emulation` names for that effect (a lock that fails, a move that never finishes, a scan
  that misses the next N times);
- `set`: a variable wired to a register is set on its device; a robot's pose means a person
  moved the robot there by hand (`unknown`: pushed aside, which stops it protectively); a
  decision variable no device measures is reported as observed, as the simulated world does;
- the device-level kinds (DESIGN.md section 8) go to the resource's devices that can play
  them: `protective_stop` (or its `release`), `power`, `push` and `freeze` to robots,
  `freeze`, `garbage`, `stuck`, `restart` and `power` to Modbus devices;
- a maintenance step a person did: the devices it changes are reset and shown the values
  the step leaves (a connector cleared, a robot moved home by hand).

Requests go out on a thread of their own, in order, so that no round of the station waits
for an emulator; what could not be done is kept in `problems` and logged.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Mapping
from typing import Any

from hw.device_file.spec import DeviceFile, DeviceSpec, DriverKind, RobotRole
from hw.emulator_kit.control import ControlError, control
from hw.faults import Fault, FaultKind
from hw.modbus.maps import register_map
from planner.model.expressions import Value
from planner.model.flat import VariableKind
from planner.model.semantics import Semantics
from planner.model.station import Station

log = logging.getLogger(__name__)
PUSH = 0.3  # rad on the base joint: far enough off every named pose


class EmulatedWorld:
    """The world of emulated devices, driven through their control channels."""

    def __init__(
        self, devices: DeviceFile, controls: Mapping[str, tuple[str, int]], station: Station
    ) -> None:
        self.devices = devices
        self.controls = dict(controls)
        self.station = station
        self.semantics = Semantics(station.model)
        self.owner = {w.variable: (d, w) for d in devices.devices for w in d.wires}
        self.observed: dict[str, Value] = {}
        self.problems: list[str] = []
        self.requests: queue.Queue[tuple[str, dict[str, Any]] | None] = queue.Queue()
        self.thread = threading.Thread(target=self._send, name="emulated-world", daemon=True)
        self.thread.start()

    def inject(self, fault: Fault) -> None:
        match fault.kind:
            case FaultKind.DISCONNECT | FaultKind.RECONNECT:
                down = fault.kind is FaultKind.DISCONNECT
                for device in self._of_resource(fault.resource):
                    self._network(device, down)
            case FaultKind.BLOCK_EFFECT | FaultKind.UNBLOCK_EFFECT:
                on = fault.kind is FaultKind.BLOCK_EFFECT
                device, op = self._emulated(fault.effect, "blocked")
                self._toggle(device, op, on)
            case FaultKind.REPLACE_EFFECT:
                device, op = self._emulated(fault.effect, "replaced")
                self.request(device.name, {"op": op, "times": fault.count})
            case FaultKind.SET:
                self._set(fault.values)
            case _:
                self._device_fault(fault)

    def _device_fault(self, fault: Fault) -> None:
        """A device-level fault on every emulated device of the fault's resource that can
        play it (a protective stop on a robot, a restart on a Modbus device)."""
        robots = [d for d in self._of_resource(fault.resource) if d.driver is DriverKind.UR]
        others = [d for d in self._of_resource(fault.resource) if d.driver is DriverKind.MODBUS]
        kind = fault.kind
        requests: list[tuple[DeviceSpec, dict[str, Any]]] = []
        if kind is FaultKind.PROTECTIVE_STOP:
            requests = [(d, {"op": "protective_stop", "on": not fault.release}) for d in robots]
        elif kind is FaultKind.POWER:
            for d in robots:
                requests.append((d, {"op": "power", "on": fault.on}))
                if fault.on:  # a person powers it on and releases the brakes
                    requests.append((d, {"op": "power", "on": True, "brake_release": True}))
            for d in others:  # off: the device is gone; on: it boots with its power-on values
                mode = "up" if fault.on else "refuse"
                requests += [(d, {"op": "network", "mode": mode})]
                if fault.on:
                    requests.append((d, {"op": "restart"}))
        elif kind is FaultKind.PUSH:
            requests = [(d, {"op": "push", "offset": list(fault.offset)}) for d in robots]
        elif kind is FaultKind.FREEZE:
            requests = [(d, {"op": "freeze", "on": fault.on}) for d in robots]
            requests += [(d, {"op": "freeze", "frozen": fault.on}) for d in others]
        elif kind is FaultKind.GARBAGE:
            requests = [(d, {"op": "garbage", "count": fault.count}) for d in others]
        elif kind is FaultKind.RESTART:
            requests = [(d, {"op": "restart"}) for d in others]
        elif kind is FaultKind.STUCK:
            requests = self._stuck(fault)
        if not requests:
            raise ValueError(f"no emulated device of '{fault.resource}' can play '{kind}'")
        for device, request in requests:
            self.request(device.name, request)

    def _stuck(self, fault: Fault) -> list[tuple[DeviceSpec, dict[str, Any]]]:
        if fault.name not in self.owner:
            raise ValueError(f"no emulated device measures '{fault.name}'")
        device, wire = self.owner[fault.name]
        register = None
        if wire.register is not None and device.map:
            register = register_map(device.map).at(wire.register.point)
        if register is None:
            raise ValueError(f"'{fault.name}' is not a sensor of a Modbus device")
        request: dict[str, Any] = {"op": "stuck", "name": register.name}
        if fault.value is not None:
            request["value"] = fault.value
        return [(device, request)]

    def maintenance_done(self, transition: str, values: Mapping[str, Value]) -> None:
        """A person did `transition`: what it changed on measured variables, the devices show."""
        chosen = self.semantics.by_name[transition]
        after = self.semantics.values(chosen.apply(self.semantics.state(dict(values))))
        changed = {
            name: value
            for name, value in after.items()
            if values.get(name) != value and self._kind(name) is VariableKind.MEASURED
        }
        for device in {
            self.owner[n][0].name: self.owner[n][0] for n in changed if n in self.owner
        }.values():
            if device.driver is DriverKind.MODBUS:
                self.request(device.name, {"op": "reset"})
        self._set(changed)

    def restart(self, start: Mapping[str, Value]) -> None:
        """Every emulated device back to normal and to the start (an experiment is played):
        faults cleared, networks up, robots moved to their start poses by hand, Modbus devices
        power-cycled and showing the start's values.  Waits until the emulators have it."""
        from hw.emulation.launch import start_state

        for device in self.devices.devices:
            if device.name not in self.controls:
                continue
            if device.driver is DriverKind.UR:
                for op in ("network", "stall", "protective_stop", "freeze"):
                    key = "down" if op == "network" else "on"
                    self.request(device.name, {"op": op, key: False})
                pose = next((w.variable for w in device.wires if w.role is RobotRole.POSE), "")
                self._move_by_hand(device, str(start.get(pose, "")))
            else:
                self.request(device.name, {"op": "network", "mode": "up"})
                self.request(device.name, {"op": "restart"})
                values = start_state(device, start)
                if values:
                    self.request(device.name, {"op": "set", "values": values})
        self.observed.clear()
        self.settle()

    def put_back(self) -> list[str]:
        """Every emulated device out of what an experiment left broken (a cut network, a
        stall, a protective stop, frozen data, power off, a stuck sensor, a failing lock),
        where it is: nothing is moved and no value set, unlike `restart`.  The devices put
        back; waits until the emulators have it."""
        names = []
        for device in self.devices.devices:
            if device.name not in self.controls:
                continue
            if device.driver is DriverKind.UR:
                for op in ("network", "stall", "freeze"):
                    key = "down" if op == "network" else "on"
                    self.request(device.name, {"op": op, key: False})
                self.request(device.name, {"op": "power", "on": True, "brake_release": True})
                self.request(device.name, {"op": "protective_stop", "on": False})
            elif device.driver is DriverKind.MODBUS:
                self.request(device.name, {"op": "network", "mode": "up"})
                self.request(device.name, {"op": "freeze", "frozen": False})
                self.request(device.name, {"op": "reset"})  # stuck sensors, failing locks
            else:
                continue  # a watch has no faults to clear
            names.append(device.name)
        self.settle()
        return names

    def take_observed(self) -> dict[str, Value]:
        """Values people changed that no device measures, once (decision variables)."""
        observed, self.observed = self.observed, {}
        return observed

    def close(self) -> None:
        self.requests.put(None)
        self.thread.join(timeout=5)

    def _of_resource(self, resource: str) -> list[DeviceSpec]:
        found = [
            d for d in self.devices.devices if d.resource == resource and d.name in self.controls
        ]
        if not found:
            raise ValueError(f"no emulated device serves '{resource}'")
        return found

    def _emulated(self, effect: str, how: str) -> tuple[DeviceSpec, str]:
        resource, _, local = effect.partition(".")
        for device in self._of_resource(resource):
            ops = device.emulation.blocked if how == "blocked" else device.emulation.replaced
            if local in ops:
                return device, ops[local]
        raise ValueError(f"the device file says no emulator fault for {how} effect '{effect}'")

    def _network(self, device: DeviceSpec, down: bool) -> None:
        """A resource that drops out stops answering, and stops acting too, as in the
        simulated world (a robot stops where it is; a Modbus device's logic stands still)."""
        if device.driver is DriverKind.UR:
            self.request(device.name, {"op": "network", "down": down, "mode": "silent"})
            self.request(device.name, {"op": "stall", "on": down})
        else:
            self.request(device.name, {"op": "network", "mode": "silent" if down else "up"})
            self.request(device.name, {"op": "freeze", "frozen": down})

    def _toggle(self, device: DeviceSpec, op: str, on: bool) -> None:
        if device.driver is DriverKind.UR:
            self.request(device.name, {"op": op, "on": on})
            if not on:  # the robot is freed: a protective stop on it is released too
                self.request(device.name, {"op": "protective_stop", "on": False})
        elif on:
            self.request(device.name, {"op": op, "always": True})
        else:
            self.request(device.name, {"op": op, "times": 0})

    def _set(self, values: Mapping[str, Value]) -> None:
        registers: dict[str, dict[str, Value]] = {}
        for name, value in values.items():
            if name not in self.owner:
                if self._kind(name) is not VariableKind.MEASURED:
                    self.observed[name] = value
                continue
            device, wire = self.owner[name]
            if wire.role in (RobotRole.POSE, RobotRole.LAST_POSE):
                self._move_by_hand(device, str(value))
            elif wire.register is not None and device.map:
                register = register_map(device.map).at(wire.register.point)
                if register is not None:
                    registers.setdefault(device.name, {})[register.name] = value
        for device_name, named in registers.items():
            self.request(device_name, {"op": "set", "values": named})

    def _move_by_hand(self, device: DeviceSpec, pose: str) -> None:
        assert device.programs is not None
        poses = device.programs.poses.poses
        if pose in poses:
            self.request(device.name, {"op": "jog", "joints": list(poses[pose])})
        else:  # pushed aside: off every pose, and a pushed robot stops
            offset = [PUSH, 0.0, 0.0, 0.0, 0.0, 0.0]
            self.request(device.name, {"op": "push", "offset": offset})
            self.request(device.name, {"op": "protective_stop", "on": True})

    def _kind(self, name: str) -> VariableKind | None:
        model = self.station.model
        return model.variable(name).kind if name in model.variable_index else None

    def request(self, device: str, request: dict[str, Any]) -> None:
        if device not in self.controls:
            raise ValueError(f"device '{device}' is not emulated")
        self.requests.put((device, request))

    def _send(self) -> None:
        while (item := self.requests.get()) is not None:
            device, request = item
            host, port = self.controls[device]
            try:
                control(host, port, {**request, "device": device})
            except ControlError as problem:
                text = f"{device}: {request['op']} failed: {problem}"
                self.problems.append(text)
                log.warning("emulated world: %s", text)
            finally:
                self.requests.task_done()

    def settle(self, timeout: float = 5.0) -> None:
        """Waits until every request so far has been sent (tests, scenario starts)."""
        done = threading.Event()

        def wait() -> None:
            self.requests.join()
            done.set()

        threading.Thread(target=wait, daemon=True).start()
        done.wait(timeout)
