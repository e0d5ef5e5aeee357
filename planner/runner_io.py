"""What goes into and out of a runner tick: inputs, operator actions, events, configuration.

Plain values only, so that a tick can be replayed, logged as JSON lines and compared.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from planner.expressions import Value


@dataclass(frozen=True)
class RunnerConfig:
    """Time-outs and limits of the runner (seconds of the injected clock)."""

    effect_timeout: float = 10.0
    # per effect transition: its own time-out, or None for an effect never timed out (a person)
    effect_timeouts: Mapping[str, float | None] = field(default_factory=dict)
    heartbeat_timeout: float = 2.0
    retries: int = 2  # failures after which an operation's goal counts as unreachable
    recheck_period: float = 1.0  # the background check of operations and intentions in error
    max_steps: int = 60
    # intentions that start by themselves when their precondition holds; None: all of them
    auto_intentions: frozenset[str] | None = None
    max_automatic_steps: int = 1000
    # start operations the operation plan calls independent at once; off by default, because
    # disjoint decision variables do not keep their transition plans from undoing each other's
    # measured preconditions (a camera's result is lost when its robot makes way for the other)
    parallel_operations: bool = False

    def timeout_of(self, effect: str) -> float | None:
        if effect in self.effect_timeouts:
            return self.effect_timeouts[effect]
        return self.effect_timeout


# -- operator and engineer actions -------------------------------------------------------------


@dataclass(frozen=True)
class Action:
    """Something a person did; `user` is recorded with it."""

    user: str = "operator"


@dataclass(frozen=True)
class StartIntention(Action):
    name: str = ""


@dataclass(frozen=True)
class CancelIntention(Action):
    name: str = ""


@dataclass(frozen=True)
class Approve(Action):
    """Approve step `step` of the forbidden-state recovery plan."""

    step: int = 0


@dataclass(frozen=True)
class Reject(Action):
    step: int = 0


@dataclass(frozen=True)
class MaintenanceDone(Action):
    """The operator has carried out maintenance transition `transition` in the world."""

    transition: str = ""


@dataclass(frozen=True)
class EnterRestart(Action):
    reason: str = ""


@dataclass(frozen=True)
class LeaveRestart(Action):
    pass


@dataclass(frozen=True)
class SetEstimated(Action):
    """Set an estimated or decision variable to match reality (restart mode, with a reason)."""

    variable: str = ""
    value: Value = False
    reason: str = ""


@dataclass(frozen=True)
class ResetOperation(Action):
    name: str = ""


@dataclass(frozen=True)
class ReenableEffect(Action):
    name: str = ""


@dataclass(frozen=True)
class Inputs:
    """One tick's input: changed measurements, observed product states, heartbeats, actions.

    `measured` holds measured variables as devices report them; `observed` holds decision
    or estimated variables that a pipeline measures directly (a product tracker, seed 000
    sec. 6.4); `heartbeats` names the resources that answered since the last tick.
    """

    measured: Mapping[str, Value] = field(default_factory=dict)
    observed: Mapping[str, Value] = field(default_factory=dict)
    heartbeats: frozenset[str] = frozenset()
    actions: tuple[Action, ...] = ()


@dataclass(frozen=True)
class Event:
    """One thing that happened, typed by `kind` (see `KINDS`), about `subject`."""

    time: float
    kind: str
    subject: str
    detail: Mapping[str, Any] = field(default_factory=dict)
    millis: float | None = field(default=None, compare=False)  # planning time, if a plan

    def as_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"time": round(self.time, 3), "kind": self.kind}
        out["subject"] = self.subject
        out.update(self.detail)
        if self.millis is not None:
            out["millis"] = round(self.millis, 2)
        return out

    def __str__(self) -> str:
        details = " ".join(f"{k}={_show(v)}" for k, v in self.detail.items())
        timing = f" ({self.millis:.1f} ms)" if self.millis is not None else ""
        return f"{self.time:8.2f}  {self.kind:<12} {self.subject}{timing}  {details}".rstrip()


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return str(value)


KINDS = (
    "taken",  # the runner took a transition (controlled, automatic, maintenance)
    "effect",  # a measured change explained by an effect transition
    "unexpected",  # a measured change no effect explains, or another effect than planned
    "observed",  # a decision or estimated variable reported by a pipeline
    "timeout",  # an effect did not happen in time: disabled in planning
    "reenabled",  # a timed-out effect is usable again
    "unavailable",  # a resource stopped answering
    "available",
    "intention",  # an intention changed state (i, e, f, error)
    "operation",  # an operation changed state (i, e, error)
    "plan",  # a planning action: level OP or TP, flags, reason, status
    "repaired",  # the operation plan mended without planning: steps skipped or appended
    "instruction",  # maintenance steps for the operator
    "approval",  # a recovery step waits for an operator's approval
    "forbidden",  # the state violates specifications: recovery starts
    "recovered",  # every specification holds again
    "operator",  # an operator's or engineer's action, accepted
    "refused",  # an action that cannot be taken now, and why
    "restart",  # restart mode entered or left
    "reset",  # an operation reset in restart mode reached its precondition (done) or not
    "error",  # anything else that needs a person (e.g. an automatic cycle)
)
