"""What the engineer's station pages show of the station's state as rows: its variables by
resource and kind, its intentions and operations with what each waits for, and a fault of
the simulation panel in words.  Pure functions of the runner's state and the model."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace

from hw.faults import Fault, FaultKind
from planner.model.expressions import Expr, Value, conjunction, conjuncts, format_value
from planner.model.flat import Model, VariableKind
from planner.model.station import Station
from planner.runner import IntentionState, OperationState, RunnerState
from planner.words import Wording, sentence

KIND_ORDER = (
    VariableKind.MEASURED,
    VariableKind.COMMAND,
    VariableKind.ESTIMATED,
    VariableKind.DECISION,
)


SETTABLE = (VariableKind.ESTIMATED, VariableKind.DECISION)


@dataclass(frozen=True)
class VariableRow:
    name: str
    value: str
    kind: str
    settable: bool  # estimated or decision: may be set in restart mode


@dataclass(frozen=True)
class VariableGroup:
    """The variables of one resource (or of none: the product's), by kind."""

    resource: str  # "" for the variables no resource owns
    description: str
    unavailable: bool
    kinds: tuple[tuple[str, tuple[VariableRow, ...]], ...]


def variable_groups(
    station: Station, values: Mapping[str, Value], unavailable: Iterable[str] = ()
) -> list[VariableGroup]:
    model = station.model
    down = set(unavailable)
    owners: list[tuple[str, str, tuple[str, ...]]] = [
        (r.name, r.description, r.variables) for r in station.resources
    ]
    owned = {name for _, _, names in owners for name in names}
    rest = tuple(v.name for v in model.variables if v.name not in owned)
    if rest:
        owners.append(("", "product and station state (no resource)", rest))
    groups = []
    for resource, description, names in owners:
        variables = [model.variable(n) for n in names if n in model.variable_index]
        kinds = []
        for kind in KIND_ORDER:
            rows = tuple(
                VariableRow(
                    v.name,
                    format_value(values[v.name]) if v.name in values else "?",
                    kind.value,
                    kind in SETTABLE,
                )
                for v in variables
                if v.kind is kind
            )
            if rows:
                kinds.append((kind.value, rows))
        groups.append(VariableGroup(resource, description, resource in down, tuple(kinds)))
    return groups


def settable_variables(model: Model) -> list[str]:
    return [v.name for v in model.variables if v.kind in SETTABLE]


def domain_texts(model: Model, name: str) -> list[str]:
    return [format_value(v) for v in model.variable(name).domain]


@dataclass(frozen=True)
class StateRow:
    """An intention or an operation with its state, and why it is in error."""

    name: str
    description: str
    state: IntentionState | OperationState
    why: str = ""  # the first cause of its error (kept in the runner's state)
    failures: int = 0
    armed: bool = False  # intention: starts by itself when its precondition holds
    resetting: bool = False  # operation: being reset in restart mode
    label: str = ""  # its name for people (planner.words); the name itself if not given
    waits_for: str = ""  # intention, idle: the parts of its precondition that do not hold

    @property
    def idle(self) -> bool:
        return self.state in (IntentionState.INITIAL, OperationState.INITIAL)

    @property
    def running(self) -> bool:
        return self.state in (IntentionState.EXECUTING, OperationState.EXECUTING)

    @property
    def failed(self) -> bool:
        return self.state in (IntentionState.ERROR, OperationState.ERROR)

    @property
    def resettable(self) -> bool:
        """Operation, in restart mode: a reset changes something (seed 001 VIII-A: it puts
        the operation back to initial, forgets its failures and plans to its precondition),
        so only one running, in error or with failures counted gets a Reset button."""
        return not self.resetting and (self.running or self.failed or self.failures > 0)


Holds = Callable[[Expr, Mapping[str, Value]], bool]


def unmet(expr: Expr, values: Mapping[str, Value], holds: Holds, words: Wording) -> str:
    """The parts of `expr` that do not hold in `values`, in words ("" if it holds)."""
    if holds(expr, values):
        return ""
    failing = [part for part in conjuncts(expr) if not holds(part, values)]
    return words.condition(conjunction(failing or [expr]))


def intention_rows(
    station: Station,
    state: RunnerState,
    words: Wording | None = None,
    holds: Holds | None = None,
) -> list[StateRow]:
    """With `words`, labels for people; with `holds` too, what an idle intention waits for."""
    rows = []
    for intention in station.intentions:
        name = intention.name
        current = state.intentions.get(name, IntentionState.INITIAL)
        why = state.intention_causes.get(name, "") if current == IntentionState.ERROR else ""
        armed = name in state.auto_start
        label = sentence(words.intention(name)) if words is not None else name
        waits = ""
        if words is not None and holds is not None and current == IntentionState.INITIAL:
            waits = unmet(intention.precondition, state.values, holds, words)
        if words is not None:
            why = words.text(why)
        row = StateRow(name, intention.description, current, why, armed=armed)
        rows.append(replace(row, label=label, waits_for=waits))
    return rows


def operation_rows(
    station: Station, state: RunnerState, words: Wording | None = None
) -> list[StateRow]:
    rows = []
    for operation in station.operations:
        name = operation.name
        current = state.operations.get(name, OperationState.INITIAL)
        why = state.operation_causes.get(name, "") if current == OperationState.ERROR else ""
        failures = state.failures.get(name, 0)
        resetting = name in state.resetting
        label = sentence(words.operation(name)) if words is not None else name
        why = words.text(why) if words is not None else why
        row = StateRow(name, operation.description, current, why, failures, resetting=resetting)
        rows.append(replace(row, label=label))
    return rows


def fault_words(fault: Fault, words: Wording | None = None) -> str:
    """A simulated fault in plain words (the station's `words` for its names, if given)."""
    resource = words.resource if words is not None else str
    step = words.step if words is not None else str
    times = "" if fault.count == 1 else f" ({fault.count} times)"
    match fault.kind:
        case FaultKind.DISCONNECT:
            return f"{resource(fault.resource)} stops answering"
        case FaultKind.RECONNECT:
            return f"{resource(fault.resource)} answers again"
        case FaultKind.BLOCK_EFFECT:
            return f"{step(fault.effect)} never happens"
        case FaultKind.UNBLOCK_EFFECT:
            return f"{step(fault.effect)} happens again"
        case FaultKind.REPLACE_EFFECT:
            instead, effect = step(fault.instead), step(fault.effect)
            return f"{instead} happens instead of {effect}{times}"
        case FaultKind.SET:
            if words is not None:
                changes = ", ".join(words.value(n, v) for n, v in fault.values.items())
            else:
                changes = ", ".join(f"{n} := {format_value(v)}" for n, v in fault.values.items())
            return f"someone changes the world by hand: {changes}"
        case FaultKind.PROTECTIVE_STOP:
            if fault.release:
                return f"{resource(fault.resource)}'s protective stop is released"
            return f"{resource(fault.resource)} stops protectively"
        case FaultKind.POWER:
            return f"{resource(fault.resource)} is powered {'on' if fault.on else 'off'}"
        case FaultKind.PUSH:
            return f"someone pushes {resource(fault.resource)}'s arm by hand"
        case FaultKind.FREEZE:
            frozen = "stand still" if fault.on else "move again"
            return f"{resource(fault.resource)}'s data {frozen}"
        case FaultKind.GARBAGE:
            return f"{resource(fault.resource)} answers garbage{times}"
        case FaultKind.STUCK:
            return f"a sensor of {resource(fault.resource)} is stuck: {fault.name}"
        case FaultKind.RESTART:
            return f"{resource(fault.resource)} restarts behind an open connection"
    return str(fault.kind)
