"""The station's devices as the station cycle sees them (STYLE.md: a small interface).

Each round the cycle lets the devices act up to the present (`advance`), reads what they
report (`read`), hands the report to the runner, and writes the runner's command values
back (`write`).  A person's maintenance step that the runner accepted is done in the world
too (`maintenance_done`): simulated devices apply it, emulated ones are told, real ones
measure it.  A person's tap on a watch is an effect they `perform`.  The same interface is
served by the simulated world (`hw.simulated`) and by the drivers of a device file
(`hw.station_devices`), so the station loop cannot tell them apart.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Protocol, runtime_checkable

from hw.faults import Fault
from hw.link import LinkStatus
from planner.model.expressions import Value
from planner.model.station import Station


class DeviceKind(StrEnum):
    """What the station runs on; the simulation panel acts on all but real devices."""

    SIMULATED = "simulated"  # the model's own effects, on the station's clock (hw.simulated)
    EMULATED = "emulated"  # the real drivers on emulators (hw.emulation)
    REAL = "real"  # the real drivers on the cell's devices

    @property
    def can_fail_on_demand(self) -> bool:
        """Faults, experiments and restarts to a start state act on these devices."""
        return self is not DeviceKind.REAL


@dataclass(frozen=True)
class Delays:
    """How long a simulated world takes for each effect or resource (a scenario's `delays`),
    and for the rest; devices that run in real time keep their own pace."""

    each: Mapping[str, float] = field(default_factory=dict)
    default: float = 1.0


@dataclass(frozen=True)
class DeviceReport:
    """What the devices said since the last round.

    `measured`: measured variables as the devices report them; `observed`: decision or
    estimated variables a pipeline measures directly (a product tracker); `heartbeats`: the
    resources that answered; `cannot_act`: resources whose devices answer but cannot act
    now, with what a person must do (`hw.adapter.AdapterReport.cannot_act`); `silent`:
    resources with a device its driver judged not answering, and why; `stale`: the
    variables of such devices without a resource (a PLC), and why.
    """

    measured: Mapping[str, Value] = field(default_factory=dict)
    observed: Mapping[str, Value] = field(default_factory=dict)
    heartbeats: frozenset[str] = frozenset()
    cannot_act: Mapping[str, str] = field(default_factory=dict)
    silent: Mapping[str, str] = field(default_factory=dict)
    stale: Mapping[str, str] = field(default_factory=dict)


class Devices(Protocol):
    @property
    def kind(self) -> DeviceKind:
        """Simulated, emulated or real."""

    def advance(self, now: float) -> None:
        """Let the devices act on the last commands up to time `now`."""

    def read(self) -> DeviceReport:
        """What the devices report now."""

    def write(self, commands: Mapping[str, Value]) -> None:
        """The runner's command values, to be carried out."""

    def maintenance_done(self, transition: str) -> None:
        """A person did maintenance transition `transition` in the world."""

    def perform(self, effect: str) -> bool:
        """A person did effect `effect` (tapped Done on a watch); False if it cannot happen now.

        The watch is a device (seed 001): a tap goes to the devices, not to the runner, and the
        runner sees it as the effect in the next reading, as it sees a robot arrive."""

    def links(self) -> Mapping[str, LinkStatus]:
        """How each device's connection is doing, by device name."""

    def dump(self, now: float) -> dict[str, object]:
        """The devices' state as JSON-ready data, stored with the runner's snapshot."""

    def close(self) -> None:
        """Stop talking to the devices (drivers, threads, child processes)."""

    def inject(self, fault: Fault) -> None:
        """Make the devices fail as `fault` says; ValueError on real devices."""

    def restart(self, start: Mapping[str, Value], delays: Delays | None = None) -> None:
        """Back to `start` for an experiment (a simulated world also takes the experiment's
        `delays`); what was seen before is forgotten.  ValueError on real devices."""

    def restore(self, saved: Mapping[str, object], now: float) -> None:
        """Take up the state `dump` saved, after the station process started again; devices
        that keep their own state (emulated, real) have nothing to take up."""

    def for_model(self, station: Station) -> Devices:
        """The devices for another model version, made beside the loop: a simulated world
        makes a new world of that model (which then `restore`s this one's dump); drivers
        serve every version and give themselves."""


@runtime_checkable
class ModelSimulation(Protocol):
    """Devices simulated from the station model's own effect transitions.

    The model's effect guards read the controller's estimates too (which tool a robot
    holds, which bolt pair is placed), so a simulation is also told the runner's estimated
    and decision values; real devices get only commands.
    """

    def follow_estimates(self, values: Mapping[str, Value]) -> None: ...
