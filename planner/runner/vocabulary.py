"""The runner's words as types: life cycles, plan labels, replan reasons and event kinds.

Each enum is a `StrEnum` whose values are the strings the event log, the snapshots, the API
and DESIGN.md section 8 have always used, so a member compares equal to, prints as and
serialises as its old text.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import StrEnum


class IntentionState(StrEnum):
    """Where an intention is in its life cycle (seed 000 Definition 6).

    initial -> executing   it is allowed to start by itself and its precondition holds
                           (not in restart mode)
    executing -> finished  its goal holds; its actions are applied
    executing -> error     no operation plan reaches its goal (seed 000 Figure 6)
    error -> executing     the background check finds its goal reachable again
    executing, error -> initial    an engineer cancels it
    finished, error -> initial     a person starts it again
    """

    INITIAL = "i"
    EXECUTING = "e"
    FINISHED = "f"
    ERROR = "error"


class OperationState(StrEnum):
    """Where an operation is in its life cycle (seed 000 Definition 5).

    initial -> executing   it is next in the operation plan and its precondition holds
    executing -> initial   its goal holds (its actions are applied), or it is reset
    executing -> error     the transition planner cannot reach its goal
    error -> initial       the background check can reach its goal again, the maintenance it
                           needed is done (within its retries), or it is reset
    error -> executing     it failed only because a device's effect timed out, and the effect
                           came late: it goes on where it was
    """

    INITIAL = "i"
    EXECUTING = "e"
    ERROR = "error"


INTENTION_LIFE_CYCLE: Mapping[IntentionState, frozenset[IntentionState]] = {
    IntentionState.INITIAL: frozenset({IntentionState.EXECUTING}),
    IntentionState.EXECUTING: frozenset(
        {IntentionState.FINISHED, IntentionState.ERROR, IntentionState.INITIAL}
    ),
    IntentionState.ERROR: frozenset({IntentionState.EXECUTING, IntentionState.INITIAL}),
    IntentionState.FINISHED: frozenset({IntentionState.INITIAL}),
}
"""Which state of an intention may follow which (the docstring of `IntentionState`)."""

OPERATION_LIFE_CYCLE: Mapping[OperationState, frozenset[OperationState]] = {
    OperationState.INITIAL: frozenset({OperationState.EXECUTING}),
    OperationState.EXECUTING: frozenset({OperationState.INITIAL, OperationState.ERROR}),
    OperationState.ERROR: frozenset({OperationState.INITIAL, OperationState.EXECUTING}),
}
"""Which state of an operation may follow which (the docstring of `OperationState`)."""


class PlanLevel(StrEnum):
    """Which planner a planning action asks (seed 000 Table 1)."""

    OPERATIONS = "OP"
    TRANSITIONS = "TP"


class RecoveryFlag(StrEnum):
    """What a planning action leaves out or adds (seed 000 Table 1: "TP w/ETO" and so on)."""

    EFFECT_TIMED_OUT = "ETO"  # effects that did not happen in time are disabled
    RESOURCE_TIMED_OUT = "RTO"  # the transitions of resources that stopped answering are disabled
    MAINTENANCE = "MT"  # maintenance transitions (a person's work) are allowed
    DISABLED_OPERATIONS = "DO"  # operations in error are left out


def plan_label(level: PlanLevel, flags: Iterable[RecoveryFlag]) -> str:
    """The paper's label of a planning action: "TP", "TP w/RTO w/MT", "OP w/DO"."""
    return level.value + "".join(f" w/{flag.value}" for flag in flags)


class ReplanReason(StrEnum):
    """Why a plan is made again.  `GOALS` and `INTENTIONS` are routine; the rest recover."""

    GOALS = "goals"  # the executing operations changed
    INTENTIONS = "intentions"  # an intention started, finished or failed
    DEVIATION = "deviation"  # the rest of the plan no longer reaches the goal safely
    TIMEOUT = "timeout"  # an effect did not happen in time
    AVAILABILITY = "availability"  # a resource stopped answering or answers again
    ERROR = "error"  # operations went to error
    MAINTENANCE = "maintenance"  # a plan with maintenance transitions for what is in error
    FORBIDDEN_STATE = "forbidden state"  # a specification is violated
    RESET = "reset"  # restart mode: an operation is reset
    RESTART = "restart"  # restart mode entered or left
    ESTIMATED = "estimated"  # a person set an estimated value
    RECOVERED = "recovered"  # every specification holds again
    CLEARED = "cleared"  # an operation left its error
    REENABLED = "reenabled"  # a timed-out effect was re-enabled by a person

    @property
    def routine(self) -> bool:
        return self in (ReplanReason.GOALS, ReplanReason.INTENTIONS)


class PersonAct(StrEnum):
    """The subject of an `operator` event: what a person did that the station took."""

    START_INTENTION = "start intention"
    CANCEL_INTENTION = "cancel intention"
    APPROVE = "approve"  # a recovery step approved
    REJECT = "reject"  # a recovery step rejected: "I cannot do this"
    APPROVE_PLAN = "approve plan"  # every machine step of a recovery plan approved at once
    REJECT_PLAN = "reject plan"  # a recovery plan refused at once: its machine steps left out
    MAINTENANCE_DONE = "maintenance done"  # a maintenance step done by hand
    RESET_OPERATION = "reset operation"  # restart mode
    CARD_DONE = "card done"  # a tap on the watch's Done (the watch's effect, recorded by the app)


class RestartMove(StrEnum):
    """The subject of a `restart` event: restart mode entered or left (seed 001 VIII-A)."""

    ENTERED = "entered"
    LEFT = "left"


class EventKind(StrEnum):
    """What an event is about; its subject and details depend on the kind."""

    TAKEN = "taken"  # the runner took a transition (controlled, automatic, maintenance)
    EFFECT = "effect"  # a measured change explained by an effect transition
    UNEXPECTED = "unexpected"  # a measured change no effect explains, or another effect
    OBSERVED = "observed"  # a decision or estimated variable reported by a pipeline
    TIMEOUT = "timeout"  # an effect did not happen in time: disabled in planning
    REMINDER = "reminder"  # a person's step has waited a while (never a time-out)
    REENABLED = "reenabled"  # a timed-out effect is usable again
    UNAVAILABLE = "unavailable"  # a resource stopped answering
    AVAILABLE = "available"  # it answers again
    STALE = "stale"  # a device without a resource stopped answering: its values are stale
    FRESH = "fresh"  # it answers again: its values are trusted again
    INTENTION = "intention"  # an intention changed state (i, e, f, error)
    OPERATION = "operation"  # an operation changed state (i, e, error)
    PLAN = "plan"  # a planning action: level OP or TP, flags, reason, status
    REPAIRED = "repaired"  # the operation plan mended without planning
    BLOCKED = "blocked"  # a planned step is held back, and why
    INSTRUCTION = "instruction"  # a maintenance step for the operator
    APPROVAL = "approval"  # a recovery step waits for an operator's approval
    FORBIDDEN = "forbidden"  # the state violates specifications: recovery starts
    RECOVERED = "recovered"  # every specification holds again
    OPERATOR = "operator"  # a person's action, accepted
    REFUSED = "refused"  # a person's action that cannot be taken now, and why
    RESTART = "restart"  # restart mode entered or left
    RESET = "reset"  # an operation reset in restart mode reached its precondition, or not
    ERROR = "error"  # anything else that needs a person (an automatic cycle)
    FAULT = "fault"  # a fault injected into the simulated world (scenarios, demo)
    RUN = "run"  # a run of the station's intentions started or ended (app.station.runs)
    DONE = "done"  # every intention finished (the last event of `sp run`)
    STOPPED = "stopped"  # the run ended before that (the last event of `sp run`)
