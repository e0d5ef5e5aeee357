"""The runner's live state: values, intentions and operations, the plans being followed.

`RunnerState` is everything the runner knows between two ticks; a tick works on a copy and
returns it, and `planner.runner.snapshot` saves it whole.  The plans record how far they
have been followed, so that a restarted station carries on where it stopped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TypeVar

from planner.model.expressions import Expr, Value
from planner.model.semantics import State
from planner.planning.partial_order import Block
from planner.runner.vocabulary import IntentionState, OperationState, ReplanReason


@dataclass
class TransitionPlan:
    """A transition plan being followed: its blocks and which of them have been started.

    A block is a controlled (or maintenance) step with the effects and automatic steps that
    follow it (`planner.planning.partial_order`); it may start once the blocks it comes `after` are
    done.  Forbidden-state recovery also records which blocks were shown for approval and
    which were approved.
    """

    goal: Expr
    steps: tuple[str, ...]
    blocks: tuple[Block, ...]
    taken: set[int] = field(default_factory=set)
    # for each taken block, its effects and automatics that have not happened yet
    remaining: dict[int, list[str]] = field(default_factory=dict)
    approved: set[int] = field(default_factory=set)  # recovery: blocks an operator approved
    asked: set[int] = field(default_factory=set)  # recovery, maintenance: blocks shown to people
    # blocks held back when their turn came, with the reason last reported (reported once)
    held: dict[int, str] = field(default_factory=dict)
    # effects and automatics that happened before the block expecting them was taken (an
    # effect the plan put after another robot's step may come first): not waited for again
    early: list[str] = field(default_factory=list)
    # what the plan was made to keep for the next operations' causal links
    # (`planner.runner.links`); a plan made for other links is made again
    kept: tuple[Expr, ...] = ()

    @property
    def done(self) -> set[int]:
        return {k for k in self.taken if not self.remaining.get(k)}

    def start(self, k: int, enabled: Callable[[str], bool] | None = None) -> None:
        """Block k was taken.  Of its effects and automatics, one that came early and cannot
        happen now (`enabled` says, in the state after the step) is not waited for."""
        self.taken.add(k)
        waiting = list(self.blocks[k].steps[1:])
        if enabled is not None:
            for name in [n for n in self.early if n in waiting and not enabled(n)]:
                waiting.remove(name)
                self.early.remove(name)
        self.remaining[k] = waiting
        self.held.pop(k, None)

    def copy(self) -> TransitionPlan:
        return replace(
            self,
            taken=set(self.taken),
            remaining={k: list(v) for k, v in self.remaining.items()},
            approved=set(self.approved),
            asked=set(self.asked),
            held=dict(self.held),
            early=list(self.early),
        )

    def happened(self, name: str) -> None:
        """An effect or automatic step happened: it completes the earliest block expecting it,
        or, when no taken block does, it is remembered for the first block not yet taken that
        will (its guard held before its turn came)."""
        for k in sorted(self.remaining):
            if name in self.remaining[k]:
                self.remaining[k].remove(name)
                return
        ahead = [n for k, b in enumerate(self.blocks) if k not in self.taken for n in b.steps[1:]]
        if ahead.count(name) > self.early.count(name):
            self.early.append(name)

    def mark_taken(self, name: str) -> None:
        """Transition `name` was taken outside the runner (a person's maintenance step)."""
        for k, block in enumerate(self.blocks):
            if k not in self.taken and block.transition == name:
                self.start(k)
                return

    def expected(self) -> set[str]:
        """The effects and automatic steps the taken blocks still wait for."""
        return {name for waiting in self.remaining.values() for name in waiting}


@dataclass
class OperationPlan:
    """An operation plan being followed: operation k may start once those in `after[k]` have
    finished (the operations' partial order, DESIGN.md section 3.4)."""

    steps: tuple[str, ...]
    after: tuple[frozenset[int], ...]
    started: set[int] = field(default_factory=set)
    finished: set[int] = field(default_factory=set)

    def copy(self) -> OperationPlan:
        return replace(self, started=set(self.started), finished=set(self.finished))

    def finish(self, name: str) -> None:
        for k in sorted(self.started - self.finished):
            if self.steps[k] == name:
                self.finished.add(k)
                return

    def unstart(self, name: str) -> None:
        """The plan may start `name` again."""
        for k in sorted(self.started - self.finished):
            if self.steps[k] == name:
                self.started.discard(k)


@dataclass
class RunnerState:
    """Everything live; a tick works on a copy and returns it."""

    values: dict[str, Value]
    intentions: dict[str, IntentionState]
    operations: dict[str, OperationState]
    # the executing operations' goals for the transition planner, fixed when each started
    operation_goals: dict[str, Expr] = field(default_factory=dict)
    failures: dict[str, int] = field(default_factory=dict)  # per operation, since it last finished
    # failures counted while device effects were timed out: per operation, the timed-out
    # effects each such failure is blamed on.  An effect that comes late takes its failures
    # back, and the operations it made fail go on where they were (`resumable`).
    blamed_on_timeouts: dict[str, list[frozenset[str]]] = field(default_factory=dict)
    resumable: set[str] = field(default_factory=set)
    operation_plan: OperationPlan | None = None
    transition_plan: TransitionPlan | None = None
    recovery: TransitionPlan | None = None  # forbidden-state recovery in progress
    relaxed: frozenset[str] = frozenset()  # the specifications the recovery plan may violate
    rejected: set[str] = field(default_factory=set)  # recovery steps an operator rejected
    # the violated specifications last announced (a `forbidden` event), said at once even
    # while the recovery plan is still being made, and once per violation
    announced: tuple[str, ...] = ()
    # recovery found no plan in this state with these transitions disabled: it holds until
    # either changes (not stored: after a restart the runner plans once more, then holds)
    recovery_held: tuple[State, frozenset[str]] | None = None
    # what the background check last looked at: checked again only once it changed (not
    # stored: after a restart everything is checked once more)
    rechecked: tuple[object, ...] | None = None
    # after errors: the plan with maintenance transitions being followed, and the operation
    # in error it was made for (seed 000 sec. 4.5)
    maintenance: TransitionPlan | None = None
    maintenance_for: str = ""
    # intentions went to error while other operations still executed: the maintenance plan
    # is made once they have come to rest, from where they leave the station
    maintenance_due: bool = False
    last_heard: dict[str, float] = field(default_factory=dict)  # per resource
    unavailable: set[str] = field(default_factory=set)
    # resources unavailable because their devices say they cannot act, and what a person
    # must do (`Inputs.cannot_act`)
    cannot_act: dict[str, str] = field(default_factory=dict)
    # variables whose devices (without a resource: a PLC) do not answer, and why
    # (`Inputs.stale`); automatic steps do not trust them (`automatic.may_fire`)
    stale: dict[str, str] = field(default_factory=dict)
    effect_enabled_since: dict[str, float] = field(default_factory=dict)
    timed_out: set[str] = field(default_factory=set)
    reminded: dict[str, int] = field(default_factory=dict)  # a person's effect: reminders sent
    restart_mode: bool = False
    restart_reason: str = ""  # why restart mode was entered, and by whom
    restart_user: str = ""
    # restart mode: operations being reset, planned to reach their precondition
    resetting: set[str] = field(default_factory=set)
    auto_start: set[str] = field(default_factory=set)  # intentions that start by themselves
    # the operations finished since production last started (an intention went executing
    # with none busy), whichever plan they were in: progress counts them across replans
    run_finished: tuple[str, ...] = ()
    next_background_check: float = 0.0
    replan_operations: ReplanReason | None = None  # why the operation plan must be made again
    replan_transitions: ReplanReason | None = None
    halted: str = ""  # a model error stopped automatic steps
    # why each intention and operation in error went there: the first cause, kept until it
    # leaves the error (later failures of the same error do not overwrite it)
    intention_causes: dict[str, str] = field(default_factory=dict)
    operation_causes: dict[str, str] = field(default_factory=dict)
    # what the incremental checks last looked at (None: look at everything): effects were
    # watched for time-outs, automatics were at a fixpoint, no invariant was violated
    effects_watched_at: State | None = None
    automatics_settled_at: State | None = None
    invariants_held_at: State | None = None

    def stale_by_why(self) -> dict[str, list[str]]:
        """The stale variables grouped by why (one silent device each), in name order."""
        groups: dict[str, list[str]] = {}
        for name, why in sorted(self.stale.items()):
            groups.setdefault(why, []).append(name)
        return groups

    def copy(self) -> RunnerState:
        """A copy a tick may change without touching this one (expressions, tuples and
        values are immutable and shared; a deepcopy cost more than the rest of a tick)."""
        return replace(
            self,
            values=dict(self.values),
            intentions=dict(self.intentions),
            operations=dict(self.operations),
            operation_goals=dict(self.operation_goals),
            failures=dict(self.failures),
            blamed_on_timeouts={k: list(v) for k, v in self.blamed_on_timeouts.items()},
            resumable=set(self.resumable),
            operation_plan=_copied(self.operation_plan),
            transition_plan=_copied(self.transition_plan),
            recovery=_copied(self.recovery),
            rejected=set(self.rejected),
            maintenance=_copied(self.maintenance),
            last_heard=dict(self.last_heard),
            unavailable=set(self.unavailable),
            cannot_act=dict(self.cannot_act),
            stale=dict(self.stale),
            effect_enabled_since=dict(self.effect_enabled_since),
            timed_out=set(self.timed_out),
            reminded=dict(self.reminded),
            resetting=set(self.resetting),
            auto_start=set(self.auto_start),
            intention_causes=dict(self.intention_causes),
            operation_causes=dict(self.operation_causes),
        )

    def intentions_in(self, state: IntentionState) -> list[str]:
        return [name for name, current in self.intentions.items() if current == state]

    def busy_intentions(self) -> list[str]:
        """The intentions production is busy with: executing, or in error waiting for a way
        out (a run lasts while there is one; pages and alarms read it)."""
        busy = (IntentionState.EXECUTING, IntentionState.ERROR)
        return [name for name, current in self.intentions.items() if current in busy]

    def operations_in(self, state: OperationState) -> list[str]:
        return [name for name, current in self.operations.items() if current == state]

    def plans_followed(self) -> list[TransitionPlan]:
        """The transition plans being followed: production's, recovery's, maintenance's."""
        plans = (self.transition_plan, self.recovery, self.maintenance)
        return [plan for plan in plans if plan is not None]

    def executing(self) -> list[str]:
        """The executing operations with planning goals, in the order they started."""
        return [
            name
            for name in self.operation_goals
            if self.operations[name] == OperationState.EXECUTING
        ]


_Plan = TypeVar("_Plan", TransitionPlan, OperationPlan)


def _copied(plan: _Plan | None) -> _Plan | None:
    return None if plan is None else plan.copy()
