"""A simulated world for a station model: the devices' side of the runner, with faults.

It plays the model's effect transitions as the devices would: an effect whose guard holds
(on the runner's published commands and estimates, and the world's own measurements) happens
after its delay, unless a fault stops it.  It owns the measured variables and the products'
true states, answers with heartbeats for every resource that is connected, and applies the
operator's maintenance work.  It is the stand-in for devices in the demo and in tests, and it
is deterministic: the same commands and faults at the same times give the same reports.
"""

from __future__ import annotations

from collections.abc import Mapping

from hw.devices import Delays, DeviceKind, DeviceReport, Devices
from hw.faults import FAULTS, Fault, FaultKind
from hw.link import LinkStatus
from planner.model.expressions import Value
from planner.model.flat import TransitionKind, VariableKind
from planner.model.semantics import Semantics
from planner.model.station import Station


class SimulatedWorld:
    """Devices and products of a station, simulated from its model's effects (it is
    `hw.devices.Devices` and a `hw.devices.ModelSimulation`).

    `people_tap`: the taps on the people's watches (their confirm effects) come from the
    people themselves, at the web HMI, and the world never plays them; by default it plays
    them after their delay, as in headless runs.
    """

    kind = DeviceKind.SIMULATED

    def __init__(
        self,
        station: Station,
        *,
        delays: Mapping[str, float] | None = None,
        default_delay: float = 1.0,
        start: Mapping[str, Value] | None = None,
        people_tap: bool = False,
    ) -> None:
        self.station = station
        self.model = station.model
        self.semantics = Semantics(self.model)
        self.delays = dict(delays or {})
        self.default_delay = default_delay
        self.measured = {v.name for v in self.model.variables if v.kind is VariableKind.MEASURED}
        self.values: dict[str, Value] = {v.name: v.initial for v in self.model.variables}
        self.values.update(start or {})
        self.observed: dict[str, Value] = {}  # product states changed by hand, to report once
        self.resource_variables = {r.name: frozenset(r.variables) for r in station.resources}
        self.disconnected: set[str] = set()
        self.blocked: set[str] = set()
        self.replaced: dict[str, tuple[str, int]] = {}
        self.pending: dict[str, float] = {}  # effect -> when it happens
        self.people_tap = people_tap
        manual = frozenset(w.confirm for _, w in station.watches) if people_tap else frozenset()
        self.effects = [
            c
            for c in self.semantics.transitions
            if c.kind is TransitionKind.EFFECT and c.name not in manual
        ]

    def delay(self, effect: str) -> float:
        if effect in self.delays:
            return self.delays[effect]
        owner = self.station.owner_of(effect)
        return self.delays.get(owner, self.default_delay)

    def inject(self, fault: Fault) -> None:
        match fault.kind:
            case FaultKind.DISCONNECT:
                self.disconnected.add(fault.resource)
            case FaultKind.RECONNECT:
                self.disconnected.discard(fault.resource)
            case FaultKind.BLOCK_EFFECT:
                self.blocked.add(fault.effect)
            case FaultKind.UNBLOCK_EFFECT:
                self.blocked.discard(fault.effect)
            case FaultKind.REPLACE_EFFECT:
                self.replaced[fault.effect] = (fault.instead, fault.count)
            case FaultKind.SET:
                for name, value in fault.values.items():
                    self.values[name] = value
                    if name not in self.measured:
                        self.observed[name] = value
            case _:
                raise ValueError(f"unknown fault '{fault.kind}'; use one of {', '.join(FAULTS)}")

    def maintenance_done(self, transition: str) -> None:
        """The operator has done maintenance transition `transition` in the physical world."""
        chosen = self.semantics.by_name[transition]
        after = self.semantics.values(chosen.apply(self.semantics.state(self.values)))
        for name, value in after.items():
            self.values[name] = value

    def perform(self, effect: str) -> bool:
        """A person did effect `effect` (e.g. confirmed a card): applied if its guard holds."""
        chosen = self.semantics.by_name.get(effect)
        if chosen is None or chosen.kind is not TransitionKind.EFFECT:
            raise ValueError(f"'{effect}' is not an effect transition")
        state = self.semantics.state(self.values)
        if not chosen.guard(state):
            return False
        after = self.semantics.values(chosen.apply(state))
        for name in self.measured:
            self.values[name] = after[name]
        return True

    def links(self) -> dict[str, LinkStatus]:
        """Each resource, connected unless a fault cut it."""
        return {
            name: LinkStatus(True, 0.0)
            if name not in self.disconnected
            else LinkStatus(False, error="cut by a simulated fault")
            for name in self.resource_variables
        }

    def close(self) -> None:
        """Nothing to stop: the simulation runs in the station's own loop."""

    def restart(self, start: Mapping[str, Value], delays: Delays | None = None) -> None:
        """Back to the model's initial values and `start` (an experiment), with no fault,
        nothing pending and, when given, the experiment's `delays`."""
        self.values = {v.name: v.initial for v in self.model.variables}
        self.values.update(start)
        self.observed, self.pending, self.replaced = {}, {}, {}
        self.disconnected, self.blocked = set(), set()
        if delays is not None:
            self.delays, self.default_delay = dict(delays.each), delays.default

    def for_model(self, station: Station) -> Devices:
        """A world of another model version with this one's delays; it takes up this
        world's state from `dump` (`restore`) when the station switches to it."""
        return SimulatedWorld(
            station,
            delays=self.delays,
            default_delay=self.default_delay,
            people_tap=self.people_tap,
        )

    def dump(self, now: float) -> dict[str, object]:
        """The devices' state as JSON-ready data (pending effects relative to `now`)."""
        return {
            "values": dict(self.values),
            "observed": dict(self.observed),
            "disconnected": sorted(self.disconnected),
            "blocked": sorted(self.blocked),
            "replaced": {k: [v[0], v[1]] for k, v in sorted(self.replaced.items())},
            "pending": {k: max(0.0, t - now) for k, t in sorted(self.pending.items())},
        }

    def restore(self, data: Mapping[str, object], now: float) -> None:
        """Resume from `dump` output; names the model no longer has are dropped."""
        known = set(self.values)
        values = data.get("values", {})
        if isinstance(values, Mapping):
            for name, value in values.items():
                if name in known and value in self.model.variable(name).domain:
                    self.values[name] = value
        effects = set(self.semantics.by_name)
        resources = set(self.resource_variables)
        self.disconnected = {r for r in _strings(data.get("disconnected")) if r in resources}
        self.blocked = {e for e in _strings(data.get("blocked")) if e in effects}
        replaced = data.get("replaced", {})
        if isinstance(replaced, Mapping):
            self.replaced = {
                k: (str(v[0]), int(v[1]))
                for k, v in replaced.items()
                if k in effects and str(v[0]) in effects
            }
        pending = data.get("pending", {})
        if isinstance(pending, Mapping):
            self.pending = {k: now + float(t) for k, t in pending.items() if k in effects}

    def write(self, commands: Mapping[str, Value]) -> None:
        """The runner's command values: what the devices are told to do."""
        for name, value in commands.items():
            if name in self.values and name not in self.measured:
                self.values[name] = value

    def follow_estimates(self, values: Mapping[str, Value]) -> None:
        """The runner's estimated and decision values, which the model's effect guards read;
        a product state a person changed and the runner has not been told of yet stays."""
        for name, value in values.items():
            if name in self.values and name not in self.measured and name not in self.observed:
                self.values[name] = value

    def advance(self, now: float) -> None:
        """Let the devices act on the last commands up to time `now`."""
        for _ in range(len(self.effects) + 1):
            state = self.semantics.state(self.values)
            due = None
            for effect in self.effects:
                name = effect.name
                frozen = self.station.owner_of(name) in self.disconnected
                if not effect.guard(state) or frozen or name in self.blocked:
                    self.pending.pop(name, None)
                    continue
                when = self.pending.setdefault(name, now + self.delay(name))
                if when <= now and due is None:
                    due = name
            if due is None:
                return
            self.pending.pop(due)
            happened = due
            if due in self.replaced:
                instead, count = self.replaced[due]
                happened = instead
                if count <= 1:
                    del self.replaced[due]
                else:
                    self.replaced[due] = (instead, count - 1)
            chosen = self.semantics.by_name[happened]
            after = self.semantics.values(chosen.apply(state))
            for name in self.measured:
                self.values[name] = after[name]

    def read(self) -> DeviceReport:
        """Measurements and heartbeats of the connected resources, and observed product states."""
        frozen: set[str] = set()
        for resource in self.disconnected:
            frozen |= self.resource_variables.get(resource, frozenset())
        measured = {n: self.values[n] for n in sorted(self.measured) if n not in frozen}
        observed, self.observed = self.observed, {}
        heartbeats = frozenset(r.name for r in self.station.resources) - self.disconnected
        return DeviceReport(measured=measured, observed=observed, heartbeats=heartbeats)


def _strings(value: object) -> list[str]:
    return [str(v) for v in value] if isinstance(value, list) else []
