"""The station's devices from its device file: drivers and adapters behind `hw.devices.Devices`.

`StationDevices` is what the station loop talks to when it runs on devices, real or
emulated: it starts a driver per device of the device file (UR robots through ur_rtde in a
child process each, Modbus devices on one shared event loop), and each round it gathers the
adapters' measured values, observed product states and heartbeats, and hands out the
runner's commands.  A resource has a heartbeat only while all of its devices are alive, so
the runner marks it unavailable after its heartbeat time-out when one stops answering or
talks nonsense.  People's taps on their watches are `perform`ed here.

Faults and maintenance act on emulated devices through `hw.emulation.world`, when given.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Protocol

from hw.adapter import Adapter
from hw.device_file.spec import DeviceFile, DeviceSpec, DriverKind
from hw.devices import Delays, DeviceKind, DeviceReport, Devices
from hw.faults import Fault
from hw.link import LinkStatus
from hw.modbus.adapter import RegisterAdapter
from hw.modbus.driver import ModbusDriver
from hw.modbus.maps import register_map
from hw.ur.adapter import RobotAdapter
from hw.ur.driver import URDriver
from hw.watch import WatchAdapter
from planner.model.expressions import Value
from planner.model.flat import VariableKind
from planner.model.station import Station


class World(Protocol):
    """The emulated world behind the devices (hw.emulation.world.EmulatedWorld)."""

    def inject(self, fault: Fault) -> None: ...

    def maintenance_done(self, transition: str, values: Mapping[str, Value]) -> None: ...

    def restart(self, start: Mapping[str, Value]) -> None: ...

    def put_back(self) -> list[str]: ...

    def take_observed(self) -> dict[str, Value]: ...

    def close(self) -> None: ...


def make_adapter(
    spec: DeviceSpec, station: Station, start: Mapping[str, Value], answer_after: float | None
) -> Adapter:
    """The adapter and driver of one device of the device file."""
    match spec.driver:
        case DriverKind.UR:
            robot = URDriver(spec.host, name=spec.name, heartbeat_timeout=spec.heartbeat_timeout)
            return RobotAdapter(spec, robot, start)
        case DriverKind.MODBUS:
            points = [w.register.point for w in spec.wires if w.register is not None]
            heartbeat = None
            if spec.map and "heartbeat" in {r.name for r in register_map(spec.map)}:
                heartbeat = register_map(spec.map).point("heartbeat")
            registers = ModbusDriver(
                spec.name,
                spec.host,
                spec.port,
                spec.unit,
                points,
                poll_period=spec.poll_period,
                heartbeat_timeout=spec.heartbeat_timeout,
                heartbeat=heartbeat,
            )
            return RegisterAdapter(spec, registers)
        case DriverKind.WATCH:
            person = next(r for r in station.resources if r.name == spec.resource)
            assert person.watch is not None
            card, done = person.watch.card, person.watch.done
            return WatchAdapter(spec, card, done, start, answer_after)


def _silence(adapter: Adapter) -> str:
    """Why a device does not answer, in its driver's words."""
    return f"{adapter.spec.name} does not answer: {adapter.status().error or 'no fresh data'}"


class StationDevices:
    """The devices of a device file (it is `hw.devices.Devices`; see the module docstring)."""

    def __init__(
        self,
        devices: DeviceFile,
        station: Station,
        start: Mapping[str, Value],
        *,
        world: World | None = None,
        answer_after: float | None = None,
        adapter: Callable[..., Adapter] = make_adapter,
    ) -> None:
        self.file = devices
        self.station = station
        self.world = world
        self.adapters = [adapter(spec, station, start, answer_after) for spec in devices.devices]
        self.watches = {
            watch.confirm: a
            for a in self.adapters
            if isinstance(a, WatchAdapter)
            for person, watch in station.watches
            if person.name == a.spec.resource
        }
        self.owner = {w.variable: a for a in self.adapters for w in a.spec.wires}
        self.values = dict(start)  # the last measured values and commands, for maintenance
        self.now = 0.0
        # the adapters that answered since they (re)started: one that stops answering is
        # said at once; one that has not answered yet is the heartbeat time-out's
        self.heard: set[int] = set()
        for each in self.adapters:
            each.start()

    def advance(self, now: float) -> None:
        self.now = now
        for each in self.adapters:
            if isinstance(each, WatchAdapter):
                each.advance(now)

    def read(self) -> DeviceReport:
        measured: dict[str, Value] = {}
        observed: dict[str, Value] = {}
        alive: dict[str, bool] = {}
        cannot_act: dict[str, list[str]] = {}
        silent: dict[str, list[str]] = {}
        stale: dict[str, str] = {}
        for each in self.adapters:
            report = each.read()
            measured.update(report.measured)
            observed.update(report.observed)
            resource = each.spec.resource
            if resource:
                alive[resource] = alive.get(resource, True) and report.alive
                if report.alive and report.cannot_act:
                    cannot_act.setdefault(resource, []).append(report.cannot_act)
            if report.alive:
                self.heard.add(id(each))
            elif id(each) in self.heard:  # it answered since it (re)started, and stopped
                why = _silence(each)
                if resource:
                    silent.setdefault(resource, []).append(why)
                else:
                    stale.update(
                        (w.variable, why)
                        for w in each.spec.wires
                        if w.kind is not VariableKind.COMMAND
                    )
        if self.world is not None:
            observed.update(self.world.take_observed())
        self.values.update(measured)
        self.values.update(observed)
        heartbeats = frozenset(r for r, ok in alive.items() if ok)
        halted = {r: "; ".join(why) for r, why in cannot_act.items() if r in heartbeats}
        said = {r: "; ".join(why) for r, why in silent.items()}
        return DeviceReport(measured, observed, heartbeats - halted.keys(), halted, said, stale)

    def write(self, commands: Mapping[str, Value]) -> None:
        self.values.update(commands)
        by_adapter: dict[int, dict[str, Value]] = {}
        for name, value in commands.items():
            owner = self.owner.get(name)
            if owner is not None:
                by_adapter.setdefault(id(owner), {})[name] = value
        for each in self.adapters:
            if id(each) in by_adapter:
                each.write(by_adapter[id(each)])

    @property
    def kind(self) -> DeviceKind:
        return DeviceKind.REAL if self.world is None else DeviceKind.EMULATED

    def restart(self, start: Mapping[str, Value], delays: Delays | None = None) -> None:
        """Back to `start` for an experiment: the emulated world is reset and the adapters
        forget what they saw before (readings from before now are not taken).  Emulated
        devices run in real time: an experiment's `delays` are the simulated world's."""
        if self.world is None:
            raise ValueError("only emulated devices can be put back to a start")
        self.world.restart(start)
        now = time.monotonic()
        for each in self.adapters:
            each.restart(start, now)
        self.values = dict(start)
        self.heard.clear()

    def put_back(self) -> list[str]:
        """The emulated devices out of the faults an experiment left, where they are (the
        simulation panel's "Put devices back"); the devices put back."""
        if self.world is None:
            raise ValueError("only emulated devices can be put back")
        return self.world.put_back()

    def wait_until_ready(self, timeout: float, poll: float = 0.1) -> list[str]:
        """Waits (before the station's clock starts) until every device answers, as a station
        starting up does; the devices still silent after `timeout` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            silent = [a.spec.name for a in self.adapters if not a.read().alive]
            if not silent or time.monotonic() >= deadline:
                return silent
            time.sleep(poll)

    def restore(self, saved: Mapping[str, object], now: float) -> None:
        """Nothing to take up: the devices keep their own state (the robots stand where
        they stand) and report it."""

    def for_model(self, station: Station) -> Devices:
        """The same drivers serve every model version of the station."""
        return self

    def maintenance_done(self, transition: str) -> None:
        """A person did it in the world: emulated devices are told; real ones measure it."""
        if self.world is not None:
            self.world.maintenance_done(transition, dict(self.values))

    def perform(self, effect: str) -> bool:
        watch = self.watches.get(effect)
        if watch is None:
            raise ValueError(f"'{effect}' is not a watch's confirm effect")
        return watch.tap()

    def inject(self, fault: Fault) -> None:
        if self.world is None:
            raise ValueError("faults act on emulated devices only; these are real")
        self.world.inject(fault)

    def links(self) -> dict[str, LinkStatus]:
        return {each.spec.name: each.status() for each in self.adapters}

    def dump(self, now: float) -> dict[str, object]:
        """Each device's link, for the record (real devices keep their own state)."""
        clock = time.monotonic()
        return {
            name: {
                "connected": link.connected,
                "latency_ms": None if link.latency_ms is None else round(link.latency_ms, 1),
                "data_age": None if link.last_data is None else round(clock - link.last_data, 3),
                "error": link.error,
                "restarts": link.restarts,
                "device_restarts": link.device_restarts,
                "device_restart": link.device_restart,
            }
            for name, link in self.links().items()
        }

    def close(self) -> None:
        for each in self.adapters:
            each.close()
        if self.world is not None:
            self.world.close()
