"""What goes into and comes out of a runner tick: configuration, inputs, events, results.

Plain values only, so that a tick can be replayed, logged as JSON lines and compared.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from planner.model.expressions import Value
from planner.runner.actions import Action, Reply
from planner.runner.vocabulary import EventKind

if TYPE_CHECKING:
    from planner.runner.state import RunnerState


@dataclass(frozen=True)
class RunnerConfig:
    """Time-outs and limits of the runner (seconds of the injected clock)."""

    effect_timeout: float = 10.0
    # per effect transition: its own time-out, or None for an effect never timed out (a person)
    effect_timeouts: Mapping[str, float | None] = field(default_factory=dict)
    heartbeat_timeout: float = 2.0
    # a person's step that waits this long (and every as long again) gets a reminder, not a
    # time-out: people take the time the work takes (None: never remind)
    reminder: float | None = 120.0
    retries: int = 2  # failures after which an operation's goal counts as unreachable
    recheck_period: float = 1.0  # the background check of operations and intentions in error
    max_steps: int = 60
    # intentions that start by themselves when their precondition holds; None: all of them
    auto_intentions: frozenset[str] | None = None
    max_automatic_steps: int = 1000
    # one operation at a time instead of the partial order (DESIGN.md section 3.4): the old
    # behaviour, kept one switch away for comparison (`sp run --sequential`)
    sequential: bool = False

    def timeout_of(self, effect: str, *, person: bool = False) -> float | None:
        """The time-out of `effect`: its own, else none for a person's effect (people take
        the time the work takes), else the devices' `effect_timeout`."""
        if effect in self.effect_timeouts:
            return self.effect_timeouts[effect]
        return None if person else self.effect_timeout


@dataclass(frozen=True)
class Inputs:
    """One tick's input: changed measurements, observed product states, heartbeats, actions.

    `measured` holds measured variables as devices report them; `observed` holds decision
    or estimated variables that a pipeline measures directly (a product tracker, seed 000
    sec. 6.4); `heartbeats` names the resources that answered since the last tick;
    `cannot_act` the resources whose devices answer but say they cannot act now, each with
    what a person must do about it (a robot in a protective stop, powered off), in words
    that name things by their model names; `silent` the resources whose devices say they
    do not answer now (their drivers judged the link: no fresh data, nonsense), each with
    why: unavailable at once, not only after the heartbeat time-out; `stale` the variables
    of devices without a resource (a PLC) that do not answer, each with why.
    """

    measured: Mapping[str, Value] = field(default_factory=dict)
    observed: Mapping[str, Value] = field(default_factory=dict)
    heartbeats: frozenset[str] = frozenset()
    actions: tuple[Action, ...] = ()
    cannot_act: Mapping[str, str] = field(default_factory=dict)
    silent: Mapping[str, str] = field(default_factory=dict)
    stale: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Event:
    """One thing that happened, typed by `kind`, about `subject`."""

    time: float
    kind: EventKind
    subject: str
    detail: Mapping[str, Any] = field(default_factory=dict)
    millis: float | None = field(default=None, compare=False)  # planning time, if a plan

    def as_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"time": round(self.time, 3), "kind": self.kind.value}
        out["subject"] = self.subject
        out.update(self.detail)
        if self.millis is not None:
            out["millis"] = round(self.millis, 2)
        return out

    def __str__(self) -> str:
        details = " ".join(f"{k}={_show(v)}" for k, v in self.detail.items())
        timing = f" ({self.millis:.1f} ms)" if self.millis is not None else ""
        kind = self.kind.value
        return f"{self.time:8.2f}  {kind:<12} {self.subject}{timing}  {details}".rstrip()


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return str(value)


@dataclass(frozen=True)
class TickResult:
    """What a tick gives back: the next state, the command values to publish to the devices,
    the events of the tick and one reply per action of its inputs, in their order."""

    state: RunnerState
    commands: Mapping[str, Value]
    events: tuple[Event, ...]
    replies: tuple[Reply, ...] = ()
