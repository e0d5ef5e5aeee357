"""Faults that can be injected into devices on demand (scenarios, the demo, tests)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum

from planner.model.expressions import Value


class FaultKind(StrEnum):
    """What can go wrong (the `kind` of a scenario's fault, DESIGN.md section 8)."""

    DISCONNECT = "disconnect"  # a resource stops answering; its measurements freeze (E5-E7)
    RECONNECT = "reconnect"
    BLOCK_EFFECT = "block_effect"  # an effect never happens (a broken lock or release: E3, E4)
    UNBLOCK_EFFECT = "unblock_effect"
    REPLACE_EFFECT = "replace_effect"  # the next `count` times, another effect instead (E8, E9)
    SET = "set"  # a person changes the world: a part moved, mounted or undone by hand (E1, E2)
    # device-level faults, played on emulated devices only (`sp run --devices`): what a real
    # cell does at the protocol level (issue 28)
    PROTECTIVE_STOP = "protective_stop"  # a robot stops protectively; `release` as a person
    POWER = "power"  # `on: false` / `on: true` (a robot: powered on and brakes released)
    PUSH = "push"  # a person pushes a robot's arm: `offset`, six joint offsets in rad
    FREEZE = "freeze"  # `on`: the device's data stop changing, its connection stays
    GARBAGE = "garbage"  # the next `count` answers are malformed (0 ends it)
    STUCK = "stuck"  # a sensor (`name`, a variable of the model) reads `value` whatever happens
    RESTART = "restart"  # a Modbus device power-cycles behind an open connection


FAULTS = tuple(kind.value for kind in FaultKind)
DEVICE_FAULTS = frozenset(
    {
        FaultKind.PROTECTIVE_STOP,
        FaultKind.POWER,
        FaultKind.PUSH,
        FaultKind.FREEZE,
        FaultKind.GARBAGE,
        FaultKind.STUCK,
        FaultKind.RESTART,
    }
)


@dataclass(frozen=True)
class Fault:
    kind: FaultKind
    resource: str = ""
    effect: str = ""
    instead: str = ""
    count: int = 1
    values: Mapping[str, Value] = field(default_factory=dict)
    on: bool = True  # power, freeze
    release: bool = False  # protective_stop: a person releases it
    offset: tuple[float, ...] = ()  # push
    name: str = ""  # stuck: the sensor's variable
    value: Value | None = None  # stuck: what it reads

    def __post_init__(self) -> None:
        """A kind given as its text (a scenario file, a form) becomes a `FaultKind`."""
        if not isinstance(self.kind, FaultKind):
            try:
                object.__setattr__(self, "kind", FaultKind(self.kind))
            except ValueError:
                shown = ", ".join(FAULTS)
                raise ValueError(f"unknown fault '{self.kind}'; use one of {shown}") from None
