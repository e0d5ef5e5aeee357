"""What the pages show, read off the runner's state: task cards and the station overview.

Pure functions of a `StationView`; no control logic (the runner decides, this only reads).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import StrEnum

from app.station_view import StationView
from planner.model import TransitionKind
from planner.runner import OperationState, TransitionPlan
from planner.watch import IDLE


class CardKind(StrEnum):
    """What a task card asks of a person."""

    COMMAND = "command"  # the watch card of an operation: tap Done when done
    INSTRUCTION = "instruction"  # a maintenance step after an error: do it, then Done
    APPROVAL = "approval"  # a forbidden-state recovery step: approve or reject it first


@dataclass(frozen=True)
class TaskCard:
    """One thing a person must do now, with one action."""

    kind: CardKind
    key: str  # stable, for the page's DOM and the tests
    title: str
    why: str
    detail: str = ""
    card: str = ""  # command: the card value Done confirms
    transition: str = ""  # instruction, approval: the maintenance or recovery step
    step: int = 0  # approval: the recovery plan's step; instruction: k of `of`
    of: int = 0
    rejectable: bool = False  # a recovery instruction: the person may say they cannot do it


def task_cards(view: StationView) -> list[TaskCard]:
    """Approvals first (nothing runs without them), then instructions, then the watch card."""
    return [*_approvals(view), *_instructions(view), *_command_cards(view)]


def sentence(text: str) -> str:
    """Plain words for a person: capitalised, without the model's references to the papers
    and experiments ("(seed 003 PlaceBolt_i)", "(E6, E7)")."""
    text = _REFERENCE.sub("", text).strip()
    return text[:1].upper() + text[1:] if text else text


_REFERENCE = re.compile(r"\s*\((?:seed \d+[^)]*|E\d[^)]*)\)")


def _executing(view: StationView) -> list[str]:
    ops = view.model.station.operations
    executing = set(view.state.operations_in(OperationState.EXECUTING))
    return [o.description or o.name for o in ops if o.name in executing]


def _command_cards(view: StationView) -> list[TaskCard]:
    """The card each person's watch shows (planner.watch), until the person taps Done."""
    cards = []
    values = view.state.values
    for person, watch in view.model.station.watches:
        card = values.get(watch.card)
        if card in (None, IDLE) or values.get(watch.done) != IDLE:
            continue
        for ability in view.model.station.abilities:
            executing = ability.predicates.get("executing")
            mine = ability.resource == person.name
            if mine and executing and view.runner.holds(executing, values):
                title = sentence(ability.description or ability.name.replace("_", " "))
                break
        else:
            title = sentence(str(card).replace("_", " "))
        why = sentence("; ".join(_executing(view)) or "the operation plan asks for it")
        waited = _waited_for_a_person(view)
        if waited:
            why += f". The station has been waiting for you for {waited}."
        cards.append(TaskCard(CardKind.COMMAND, f"card-{card}", title, why, card=str(card)))
    return cards


def _waited_for_a_person(view: StationView) -> str:
    """How long the station has waited for a person's step, once it has reminded them
    (`RunnerConfig.reminder`): a person gets reminded, never timed out."""
    state = view.state
    since = [
        state.effect_enabled_since[n] for n in state.reminded if n in state.effect_enabled_since
    ]
    if not since:
        return ""
    minutes = int((view.now - min(since)) // 60)
    return f"{minutes} min" if minutes >= 1 else f"{int(view.now - min(since))} s"


def _instructions(view: StationView) -> list[TaskCard]:
    s = view.state
    cards = []
    plans: list[tuple[TransitionPlan | None, str]] = [(s.maintenance, s.maintenance_for)]
    for plan, operation in plans:
        if plan is None:
            continue
        names = [b.transition for b in plan.blocks]
        failed = _failure(view, operation)
        for k in sorted(plan.asked - plan.taken):
            name = plan.blocks[k].transition
            cards.append(
                TaskCard(
                    CardKind.INSTRUCTION,
                    f"maintenance-{name}",
                    sentence(describe(view, name)),
                    failed,
                    detail=f"step {names.index(name) + 1} of {len(names)}",
                    transition=name,
                    step=names.index(name) + 1,
                    of=len(names),
                )
            )
    plan = s.recovery
    if plan is not None:
        violated = ", ".join(sorted(s.relaxed)) or "a specification"
        for k in sorted(plan.approved - plan.taken):
            name = plan.blocks[k].transition
            if view.model.station.model.transition(name).kind is TransitionKind.MAINTENANCE:
                cards.append(
                    TaskCard(
                        CardKind.INSTRUCTION,
                        f"recovery-{name}",
                        sentence(describe(view, name)),
                        f"The station is in a forbidden state ({violated}); this step gets it "
                        "out. If you cannot do it, say so: the station looks for another way.",
                        transition=name,
                        step=k,
                        rejectable=True,
                    )
                )
    return cards


def _approvals(view: StationView) -> list[TaskCard]:
    plan = view.state.recovery
    if plan is None:
        return []
    violated = ", ".join(sorted(view.state.relaxed)) or "a specification"
    cards = []
    for k in sorted(plan.asked - plan.approved):
        name = plan.blocks[k].transition
        cards.append(
            TaskCard(
                CardKind.APPROVAL,
                f"approval-{k}",
                sentence(describe(view, name)),
                f"The station is in a forbidden state ({violated}). The station will do this "
                "step to get out of it, once you approve.",
                detail=f"recovery step {k + 1} of {len(plan.blocks)}: {name}",
                transition=name,
                step=k,
            )
        )
    return cards


def describe(view: StationView, name: str) -> str:
    t = view.model.station.model.transition(name)
    return t.description or name


def _failure(view: StationView, operation: str) -> str:
    """What failed, in plain words: the operation in error and the reason it went there."""
    if not operation:
        return "An error needs your hands"
    description = view.model.station.operation(operation).description or operation
    reason = view.state.operation_causes.get(operation, "")
    text = f"Failed: {sentence(description)[:1].lower()}{sentence(description)[1:]}"
    return f"{text} ({reason})" if reason else text
