"""The station's alarm conditions: which of the runner's errors need a person now.

`conditions` reads the runner's state after a tick and says which alarm conditions hold, in
people's words; `app.station.alarms.AlarmBook` keeps them through the ISA-18.2 states.
Pure: no I/O, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from planner.model.expressions import variables_of
from planner.runner import IntentionState, OperationState, Runner, RunnerState
from planner.runner.waiting import Who, waiting_for
from planner.words import Wording


class Priority(StrEnum):
    CRITICAL = "critical"
    HIGH = "high"
    MEDIUM = "medium"
    LOW = "low"

    @property
    def rank(self) -> int:
        """0 for the most urgent, for sorting."""
        return list(Priority).index(self)


@dataclass(frozen=True, slots=True)
class Condition:
    """An alarm condition that holds now; `key` is its identity across ticks."""

    key: str  # "forbidden", "halted", "resource:r2", "intention:X", "operation:X", "effect:X"
    priority: Priority
    message: str  # plain words for an operator: what is wrong and what it affects
    resource: str = ""  # the resource it concerns, for the audit log's filter ("" if none)
    # what follows from it, in words (app.station.alarm_grouping): listed, not raised
    consequences: tuple[str, ...] = ()
    grouped: tuple[str, ...] = ()  # their keys


def conditions(
    runner: Runner, state: RunnerState, words: Wording | None = None
) -> dict[str, Condition]:
    """The alarm conditions of a runner state, in people's words (`words`, the active
    model's `planner.words.Wording`; built from the runner's station when not given): an
    operator reads them, so no model identifier appears (the key keeps the name)."""
    said = words or Wording(runner.station)
    found = [
        *_halted(state, said),
        *_forbidden(runner, state, said),
        *_not_answering(runner, state, said),
        *_stale(state, said),
        *_intentions_in_error(runner, state, said),
        *_operations_in_error(runner, state, said),
        *_timed_out(runner, state, said),
        *_people_waited_for(runner, state, said),
    ]
    return {condition.key: condition for condition in found}


def _halted(state: RunnerState, words: Wording) -> list[Condition]:
    if not state.halted:
        return []
    what = f"automatic steps are halted ({words.text(state.halted)})"
    return [
        Condition("halted", Priority.CRITICAL, f"{what}; the station model needs an engineer's fix")
    ]


def _forbidden(runner: Runner, state: RunnerState, words: Wording) -> list[Condition]:
    violated = runner.semantics.violated(runner.index.as_state(state.values))
    if not violated and state.recovery is None:
        return []
    broken = violated or sorted(state.relaxed)
    rules = "; ".join(words.specification(s) for s in broken) or "a rule of the station"
    if state.recovery is None:
        what = "no recovery plan was found; the station needs a person"
    elif violated:
        what = "recovery in progress: approve its steps"
    else:
        what = "the rules hold again; approve the rest of the recovery"
    message = f"forbidden state, broken: {rules}; {what}"
    return [Condition("forbidden", Priority.CRITICAL, message)]


def _not_answering(runner: Runner, state: RunnerState, words: Wording) -> list[Condition]:
    resources = {r.name: r for r in runner.station.resources}
    found = []
    for name in sorted(state.unavailable):
        who = words.resource(name)
        about = words.text(resources[name].description) if name in resources else ""
        about = f": {about}" if about else ""
        message = f"{who} is not answering (no heartbeat){about}; its steps are disabled until"
        message += " it answers"
        if name in state.cannot_act:  # it answers, and says why it cannot act
            message = f"{words.text(state.cannot_act[name])}; {who}'s steps wait until it can act"
        found.append(Condition(f"resource:{name}", Priority.HIGH, message, name))
    return found


def _stale(state: RunnerState, words: Wording) -> list[Condition]:
    """A device without a resource (a PLC) that does not answer: what it reports is stale,
    and automatic steps that read it wait."""
    return [
        Condition(
            "stale:" + ",".join(names),
            Priority.HIGH,
            f"{words.text(why)}; the last values it sent are not trusted "
            f"({', '.join(words.variable(n) for n in names)}): steps that read them wait",
        )
        for why, names in state.stale_by_why().items()
    ]


def _intentions_in_error(runner: Runner, state: RunnerState, words: Wording) -> list[Condition]:
    """Where nobody is asked to help, the engineer is: said why and what to do."""
    engineer = {w.subject: w.what for w in waiting_for(runner, state) if w.who is Who.ENGINEER}
    found = []
    for name in sorted(state.intentions_in(IntentionState.ERROR)):
        what = "in error, no plan of operations reaches its goal"
        waiting = "; maintenance steps wait on the task cards" if state.maintenance else ""
        if name in engineer:
            waiting = f"; {words.text(engineer[name])}"
        message = f"{words.intention(name)}: {what}{waiting}"
        found.append(Condition(f"intention:{name}", Priority.HIGH, message))
    return found


def _operations_in_error(runner: Runner, state: RunnerState, words: Wording) -> list[Condition]:
    """An operation in error matters while production needs the station: once no intention
    is executing it waits, harmless, until the background check releases it."""
    if not state.busy_intentions():
        return []
    return [
        Condition(
            f"operation:{name}",
            Priority.MEDIUM,
            _operation_message(runner, state, words, name),
            _operation_resource(runner, name),
        )
        for name in sorted(state.operations_in(OperationState.ERROR))
    ]


def _timed_out(runner: Runner, state: RunnerState, words: Wording) -> list[Condition]:
    what = "it did not happen in time; planning leaves it out until it is re-enabled"
    return [
        Condition(
            f"effect:{name}",
            Priority.LOW,
            f"{words.step(name)}: {what}",
            runner.station.owner_of(name),
        )
        for name in sorted(state.timed_out)
    ]


ESCALATE_AFTER = 2  # reminders: the first buzzes the person's watch, the second the shift


def _people_waited_for(runner: Runner, state: RunnerState, words: Wording) -> list[Condition]:
    """A person's step that waited through `ESCALATE_AFTER` reminders: the watch reminded
    them and nothing happened, so the shift is told (a person is never timed out)."""
    found = []
    every = runner.config.reminder or 0.0
    for name, reminders in sorted(state.reminded.items()):
        if reminders < ESCALATE_AFTER or name not in state.effect_enabled_since:
            continue
        owner = runner.station.owner_of(name)
        minutes = max(1, int(reminders * every // 60))
        message = (
            f"{words.step(name)}: the station has waited {minutes} min for "
            f"{words.resource(owner)}, who was reminded and has not done it"
        )
        found.append(Condition(f"waiting:{name}", Priority.MEDIUM, message, owner))
    return found


def _operation_message(runner: Runner, state: RunnerState, words: Wording, name: str) -> str:
    failures = state.failures.get(name, 0)
    what = "in error, its goal cannot be reached"
    if failures >= runner.config.retries:
        what += f"; it failed {failures} times and is not retried"
    return f"{words.operation(name)}: {what}"


def _operation_resource(runner: Runner, name: str) -> str:
    """The one resource owning what the operation changes, or "" when several or none do
    (operations do not name their resources; get_nr_r2 changes nr, r2_tc and r2_cam)."""
    operation = runner.index.operations[name]
    changed = variables_of(operation.goal) | {a.target for a in operation.effects}
    owners = {r.name for r in runner.station.resources if changed & set(r.variables)}
    return owners.pop() if len(owners) == 1 else ""
