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


FAULTS = tuple(kind.value for kind in FaultKind)


@dataclass(frozen=True)
class Fault:
    kind: FaultKind
    resource: str = ""
    effect: str = ""
    instead: str = ""
    count: int = 1
    values: Mapping[str, Value] = field(default_factory=dict)

    def __post_init__(self) -> None:
        """A kind given as its text (a scenario file, a form) becomes a `FaultKind`."""
        if not isinstance(self.kind, FaultKind):
            try:
                object.__setattr__(self, "kind", FaultKind(self.kind))
            except ValueError:
                shown = ", ".join(FAULTS)
                raise ValueError(f"unknown fault '{self.kind}'; use one of {shown}") from None
