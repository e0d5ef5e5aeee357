"""What the station is waiting for, and from whom (DESIGN.md section 8's `waiting_for`).

Texts name things by their model names, written so that a page can put each in words
(`planner.words.Wording.text`: "r2 to answer again" → "robot 2 to answer again").

Read off the runner's state, never stored: an approval or a maintenance step is the
operator's, a resource that stopped answering is a device's, and where nothing in the model
gets the station out (no recovery plan, halted automatics, an intention in error with no
maintenance plan, a timed-out effect) it is the engineer's decision.  The list is empty only
when no intention is active: while one is, the station names at least what it works on.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from planner.model.flat import TransitionKind
from planner.runner.runner import Runner
from planner.runner.state import RunnerState, TransitionPlan
from planner.runner.vocabulary import IntentionState, OperationState


class Who(StrEnum):
    OPERATOR = "operator"
    ENGINEER = "engineer"
    DEVICE = "device"


@dataclass(frozen=True)
class Waiting:
    """One thing the station waits for: from whom, about what, in plain words."""

    who: Who
    subject: str
    what: str

    def as_json(self) -> dict[str, str]:
        return {"who": self.who.value, "subject": self.subject, "what": self.what}


def waiting_for(runner: Runner, state: RunnerState) -> list[Waiting]:
    out = [*_stopped(runner, state), *_people(runner, state), *_devices(runner, state)]
    out += _stuck_intentions(runner, state, bool(out))
    active = state.intentions_in(IntentionState.EXECUTING) + state.intentions_in(
        IntentionState.ERROR
    )
    if not out and active:
        out = _working_on(runner, state, active)
    unique: list[Waiting] = []
    for item in out:
        if item not in unique:
            unique.append(item)
    return unique


def _stopped(runner: Runner, state: RunnerState) -> list[Waiting]:
    """What only an engineer can get the station out of."""
    out = []
    if state.halted:
        out.append(
            Waiting(Who.ENGINEER, "automatic transitions", f"{state.halted}: the model needs a fix")
        )
    violated = runner.semantics.violated(runner.index.as_state(state.values))
    if violated:
        out.append(_forbidden(runner, state, ", ".join(violated)))
    for effect in sorted(state.timed_out):
        owner = runner.station.owner_of(effect)
        on = f" on {owner}" if owner else ""
        out.append(
            Waiting(
                Who.ENGINEER,
                effect,
                f"{effect} did not happen in time{on}: mend {owner or 'it'}, then re-enable it",
            )
        )
    if state.restart_mode:
        out.append(Waiting(Who.ENGINEER, "restart mode", "leave restart mode when it is done"))
    return out


def _forbidden(runner: Runner, state: RunnerState, names: str) -> Waiting:
    """The forbidden state, named whenever the station is in one: with no recovery plan
    it is the engineer's; with one, it is whoever that plan waits on first (an approval or
    a person's step: the operator; otherwise the devices that move).  A recovery that waits
    on an effect that timed out is made again (`following.stuck`), never waited on."""
    recovery = state.recovery
    if recovery is None:
        return Waiting(
            Who.ENGINEER,
            names,
            f"forbidden state, broken: {names}; no recovery plan without the rejected "
            "steps: put it right in restart mode",
        )
    index = runner.index
    people = sorted(
        (recovery.asked - recovery.approved)
        | {
            k
            for k in recovery.approved - recovery.taken
            if index.kind_of(recovery.blocks[k].transition) is TransitionKind.MAINTENANCE
            or recovery.blocks[k].transition in index.person_transitions
        }
    )
    if people:
        step = recovery.blocks[people[0]].transition
        return Waiting(
            Who.OPERATOR,
            names,
            f"forbidden state, broken: {names}; the recovery waits on step {people[0] + 1}: {step}",
        )
    effects = sorted(recovery.expected())
    doing = f"waits for {', '.join(effects)}" if effects else "is under way"
    return Waiting(Who.DEVICE, names, f"forbidden state, broken: {names}; the recovery {doing}")


def _people(runner: Runner, state: RunnerState) -> list[Waiting]:
    """Approvals of recovery steps and the operator's maintenance steps."""
    out = []
    recovery = state.recovery
    if recovery is not None:
        for k in sorted(recovery.asked - recovery.approved):
            name = recovery.blocks[k].transition
            out.append(
                Waiting(
                    Who.OPERATOR,
                    name,
                    f"approve or reject recovery step {k + 1}: {name}",
                )
            )
        out += _maintenance_steps(runner, recovery, recovery.approved - recovery.taken)
    maintenance = state.maintenance
    if maintenance is not None:
        out += _maintenance_steps(runner, maintenance, maintenance.asked - maintenance.taken)
    return out


def _maintenance_steps(runner: Runner, plan: TransitionPlan, steps: set[int]) -> list[Waiting]:
    out = []
    for k in sorted(steps):
        name = plan.blocks[k].transition
        if runner.index.kind_of(name) is TransitionKind.MAINTENANCE:
            what = f"{runner.index.describe(name)}, then report it done"
            out.append(Waiting(Who.OPERATOR, name, what))
    return out


def _devices(runner: Runner, state: RunnerState) -> list[Waiting]:
    """Resources that stopped answering, and the effects the plans wait for."""
    index = runner.index
    out = [
        Waiting(Who.OPERATOR, name, state.cannot_act[name])
        if name in state.cannot_act
        else Waiting(Who.DEVICE, name, f"{name} to answer again")
        for name in sorted(state.unavailable)
    ]
    for why, names in state.stale_by_why().items():  # a silent device without a resource
        out.append(Waiting(Who.DEVICE, ", ".join(names), f"{why}: its values are stale"))
    for plan in state.plans_followed():
        for effect in sorted(plan.expected()):
            if index.kind_of(effect) is not TransitionKind.EFFECT:
                continue
            owner = index.station.owner_of(effect)
            if owner in state.unavailable or effect in state.timed_out:
                continue  # said above, or the engineer's (`_stopped`): nobody waits on it
            who = Who.OPERATOR if effect in index.person_effects else Who.DEVICE
            described = index.model.transition(effect).description
            what = described or f"{owner or 'a device'} to report: {effect}"
            out.append(Waiting(who, effect, what))
    return out


def _stuck_intentions(runner: Runner, state: RunnerState, others: bool) -> list[Waiting]:
    """An intention in error that nobody is asked to help: no maintenance plan, and nothing
    else the station waits for."""
    if others or state.maintenance is not None:
        return []
    out = []
    failed = [
        f"{operation}: {state.operation_causes.get(operation, 'in error')}"
        for operation in sorted(state.operations_in(OperationState.ERROR))
    ]
    for name in sorted(state.intentions_in(IntentionState.ERROR)):
        cause = state.intention_causes.get(name, "its goal cannot be reached")
        because = f"; because {'; '.join(failed)}" if failed else ""
        out.append(
            Waiting(
                Who.ENGINEER,
                name,
                f"nothing in the model gets {name} going again ({cause}{because}): mend the "
                "cause, or decide in restart mode",
            )
        )
    return out


def _working_on(runner: Runner, state: RunnerState, active: list[str]) -> list[Waiting]:
    """Nothing stopped: the operations in progress (or, between them, the intentions)."""
    executing = state.operations_in(OperationState.EXECUTING)
    if executing:
        return [Waiting(Who.DEVICE, name, f"in progress: {name}") for name in sorted(executing)]
    return [
        Waiting(Who.DEVICE, name, f"the station plans how to {name}") for name in sorted(active)
    ]
