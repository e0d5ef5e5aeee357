"""What the engineer's station page shows: plans drawn as their partial order, and the
station's resources, variables, intentions and operations as rows.

Pure functions of the runner's plans and state (no I/O, no control logic).  A plan's start
order (DESIGN.md 3.4) says, for each step, which earlier steps it waits for.  A step's *level*
is the length of the longest chain of steps it waits for; steps of one level do not wait for
each other, so they are drawn side by side: they may run in parallel.  Only the direct
dependencies are drawn as arrows (the transitive reduction): "c after b after a" needs no
arrow from a to c.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

from hw.faults import Fault, FaultKind
from planner.model.expressions import Expr, Value, conjunction, conjuncts, format_value
from planner.model.flat import Model, TransitionKind, VariableKind
from planner.model.station import Station
from planner.runner import (
    IntentionState,
    OperationPlan,
    OperationState,
    RunnerState,
    TransitionPlan,
)
from planner.words import Wording, sentence

# the drawing's grid, in SVG user units (= CSS pixels: the SVG is drawn at its own size)
NODE_WIDTH = 208
NODE_HEIGHT = 44  # for one line of name and one of note; more lines make it taller
LINE = 16  # a text line in a node
GAP_X = 20
GAP_Y = 30
PAD = 8
LABEL_CHARS = 27  # what fits on a node's line at 13 px


@dataclass(frozen=True)
class PlanNode:
    """One step (a transition block or an operation) placed in the drawing.

    status: done, started, ready (waits only for its guard), waiting (for earlier steps),
    error, asks (waits for an operator's approval or work), approved, rejected.
    """

    key: int  # the block's (or operation step's) position in the plan
    name: str
    label: str  # the step in words (its name without words)
    note: str  # the status in words, and what follows the step
    title: str  # everything, for the tooltip and the list
    status: str
    level: int
    lane: int
    after: tuple[int, ...]  # every earlier step it waits for
    x: int
    y: int
    label_lines: tuple[str, ...] = ()  # `label` wrapped to the node's width, never cut
    note_lines: tuple[str, ...] = ()


@dataclass(frozen=True)
class PlanEdge:
    """An arrow from a step to one that waits for it directly."""

    source: int
    target: int
    path: str  # SVG path data
    done: bool  # the step it comes from is done


@dataclass(frozen=True)
class PlanDrawing:
    kind: str  # operations, transitions, recovery, maintenance (also the SVG ids' prefix)
    nodes: tuple[PlanNode, ...]
    edges: tuple[PlanEdge, ...]
    width: int
    height: int
    levels: int
    widest: int  # the most steps on one level: how many may run at once
    node_height: int = NODE_HEIGHT  # every node's: room for the most lines of any

    @property
    def node_width(self) -> int:
        return NODE_WIDTH

    @property
    def summary(self) -> str:
        steps = len(self.nodes)
        done = sum(1 for n in self.nodes if n.status == "done")
        text = f"{steps} step{'' if steps == 1 else 's'} in {self.levels} level"
        text += "" if self.levels == 1 else "s"
        if self.widest > 1:
            text += f", up to {self.widest} in parallel"
        return f"{text}; {done} done"


def levels(after: Sequence[Iterable[int]]) -> list[int]:
    """Each step's level: 0 without predecessors, else one more than its deepest one."""
    out: list[int] = []
    for k, earlier in enumerate(after):
        out.append(1 + max((out[j] for j in earlier if j < k), default=-1))
    return out


def direct(after: Sequence[Iterable[int]]) -> list[frozenset[int]]:
    """The transitive reduction: for each step, the predecessors not implied by another."""
    ancestors: list[frozenset[int]] = []
    reduced: list[frozenset[int]] = []
    for k, earlier in enumerate(after):
        mine = frozenset(j for j in earlier if j < k)
        implied: set[int] = set()
        for j in mine:
            implied |= ancestors[j]
        reduced.append(mine - implied)
        ancestors.append(mine | implied)
    return reduced


def shorten(text: str, limit: int = LABEL_CHARS) -> str:
    return text if len(text) <= limit else text[: limit - 1] + "…"


def wrap(text: str, width: int = LABEL_CHARS) -> tuple[str, ...]:
    """`text` in lines of at most `width` characters, broken at spaces only (a longer word
    keeps a line of its own): wrapped, never cut."""
    lines: list[str] = []
    for word in text.split():
        if lines and len(lines[-1]) + 1 + len(word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return tuple(lines)


@dataclass(frozen=True)
class Step:
    """A step to draw: its name, status, second line and tooltip; `label` its words."""

    name: str
    status: str
    note: str
    title: str
    label: str = ""


def layout(kind: str, steps: Sequence[Step], after: Sequence[Iterable[int]]) -> PlanDrawing:
    """Place the steps level by level (top to bottom), in plan order from the left.

    Columns line up across levels, so that an arrow that skips levels can run down the gap
    between two columns instead of behind the steps in between.
    """
    level = levels(after)
    rows: dict[int, list[int]] = {}
    for k, lv in enumerate(level):
        rows.setdefault(lv, []).append(k)
    widest = max((len(r) for r in rows.values()), default=0)
    wrapped = [(wrap(s.label or s.name), wrap(s.note, LABEL_CHARS + 4)) for s in steps]
    lines = max((len(a) + len(b) for a, b in wrapped), default=2)
    box = max(NODE_HEIGHT, NODE_HEIGHT + (lines - 2) * LINE)
    width = PAD * 2 + max(widest, 1) * (NODE_WIDTH + GAP_X)  # a last gap for arrows
    height = PAD * 2 + max(len(rows), 1) * (box + GAP_Y) - GAP_Y
    place: dict[int, tuple[int, int, int]] = {}
    for lv, row in rows.items():
        for lane, k in enumerate(row):
            x = PAD + lane * (NODE_WIDTH + GAP_X)
            place[k] = (lane, x, PAD + lv * (box + GAP_Y))
    nodes = []
    for k, step in enumerate(steps):
        lane, x, y = place[k]
        nodes.append(
            PlanNode(
                k,
                step.name,
                step.label or step.name,
                step.note,
                step.title,
                step.status,
                level[k],
                lane,
                tuple(sorted(j for j in after[k] if j < k)),
                x,
                y,
                *wrapped[k],
            )
        )
    edges = []
    for k, earlier in enumerate(direct(after)):
        for j in sorted(earlier):
            path = _arrow(nodes[j], nodes[k], box)
            edges.append(PlanEdge(j, k, path, nodes[j].status == "done"))
    drawing = PlanDrawing(kind, tuple(nodes), tuple(edges), width, height, len(rows), widest)
    return replace(drawing, node_height=box)


def _arrow(a: PlanNode, b: PlanNode, box: int = NODE_HEIGHT) -> str:
    """From the bottom of `a` to the top of `b` (nodes `box` tall); across more than one
    level, down the gap right of the leftmost of the two columns."""
    x1, y1 = a.x + NODE_WIDTH // 2, a.y + box
    x2, y2 = b.x + NODE_WIDTH // 2, b.y - 3  # room for the arrowhead
    if b.level - a.level <= 1:
        middle = (y1 + y2) // 2
        return f"M{x1},{y1} C{x1},{middle} {x2},{middle} {x2},{y2}"
    gap = PAD + (min(a.lane, b.lane) + 1) * (NODE_WIDTH + GAP_X) - GAP_X // 2
    down, up = y1 + GAP_Y, y2 - GAP_Y + 3
    bend1, bend2 = y1 + GAP_Y // 2, y2 - (GAP_Y - 3) // 2
    return (
        f"M{x1},{y1} C{x1},{bend1} {gap},{bend1} {gap},{down} L{gap},{up} "
        f"C{gap},{bend2} {x2},{bend2} {x2},{y2}"
    )


# -- the runner's plans ------------------------------------------------------------------------

STATUS_WORDS = {
    "done": "done",
    "started": "running",
    "ready": "next",
    "waiting": "waits for earlier steps",
    "error": "error",
    "asks": "waits for the operator",
    "approved": "approved",
    "rejected": "rejected",
}


def transition_plan(
    kind: str,
    plan: TransitionPlan,
    model: Model,
    rejected: Iterable[str] = (),
    words: Wording | None = None,
) -> PlanDrawing:
    """A transition plan (or the recovery or maintenance plan) as a drawing.

    A block is done when its controlled step and the effects and automatics after it have
    happened, started when its controlled step was taken and some of those are outstanding.
    """
    done = plan.done
    refused = set(rejected)
    steps = []
    for k, block in enumerate(plan.blocks):
        name = block.transition
        transition = model.transition(name)
        if k in done:
            status = "done"
        elif k in plan.taken:
            status = "started"
        elif name in refused:
            status = "rejected"
        elif k in plan.approved:
            status = "approved"
        elif k in plan.asked:
            status = "asks"
        elif block.after <= done:
            status = "ready"
        else:
            status = "waiting"
        following = block.steps[1:]
        waiting_for = plan.remaining.get(k, [])
        note = STATUS_WORDS[status]
        if status == "started" and waiting_for:
            first = words.transition(waiting_for[0]) if words is not None else waiting_for[0]
            note += f", waits for {first}"
        elif following and status != "done":
            note += f" · then {len(following)} more"
        if transition.kind is TransitionKind.MAINTENANCE:
            note = "operator: " + note
        say = words.step if words is not None else str
        label = sentence(say(name))
        title = [label, f"{transition.kind.value}; {STATUS_WORDS[status]}"]
        if following:
            title.append("then: " + ", ".join(say(f) for f in following))
        if block.after:
            title.append(
                "after: " + ", ".join(say(plan.blocks[j].transition) for j in sorted(block.after))
            )
        steps.append(Step(name, status, note, "\n".join(title), label))
    return layout(kind, steps, [b.after for b in plan.blocks])


def operation_plan(
    plan: OperationPlan,
    station: Station,
    states: Mapping[str, OperationState],
    words: Wording | None = None,
) -> PlanDrawing:
    """The operation plan as a drawing; an operation in error is marked wherever it stands."""
    steps = []
    for k, name in enumerate(plan.steps):
        if k in plan.finished:
            status = "done"
        elif states.get(name) == OperationState.ERROR:
            status = "error"
        elif k in plan.started:
            status = "started"
        elif plan.after[k] <= plan.finished:
            status = "ready"
        else:
            status = "waiting"
        say = words.operation if words is not None else str
        label = sentence(say(name))
        title = [label, STATUS_WORDS[status]]
        if plan.after[k]:
            title.append("after: " + ", ".join(say(plan.steps[j]) for j in sorted(plan.after[k])))
        steps.append(Step(name, status, STATUS_WORDS[status], "\n".join(title), label))
    return layout("operations", steps, plan.after)


# -- the station overview ----------------------------------------------------------------------

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


# -- the simulation panel ----------------------------------------------------------------------


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
