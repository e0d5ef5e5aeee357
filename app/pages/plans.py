"""What the engineer's station page shows of plans: each drawn as its partial order (the
station's state as rows is `app.pages.station_rows`).

Pure functions of the runner's plans and state (no I/O, no control logic).  A plan's start
order (DESIGN.md 3.4) says, for each step, which earlier steps it waits for.  A step's *level*
is the length of the longest chain of steps it waits for; steps of one level do not wait for
each other, so they are drawn side by side: they may run in parallel.  Only the direct
dependencies are drawn as arrows (the transitive reduction): "c after b after a" needs no
arrow from a to c.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

from planner.model.flat import Model, TransitionKind
from planner.model.station import Station
from planner.runner import (
    OperationPlan,
    OperationState,
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
    """`text` in lines of at most `width` characters, broken at spaces; a word longer than a
    line ends in an ellipsis (the node's title has it whole, and the drawing clips each
    node's text to its box)."""
    lines: list[str] = []
    for word in (shorten(w, width) for w in text.split()):
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
