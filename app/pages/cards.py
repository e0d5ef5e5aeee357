"""What the pages show, read off the runner's state: task cards and the station overview.

Pure functions of a `StationView`; no control logic (the runner decides, this only reads).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from app.pages.recovery_plan import headline, kept_out_words, plan_steps, resource_place
from app.station.view import StationView
from planner.model.flat import TransitionKind
from planner.model.watch import IDLE
from planner.runner import Event, EventKind, IntentionState, OperationState, TransitionPlan
from planner.runner.forbidden import needs_approval
from planner.runner.maintenance import next_maintenance
from planner.words import Wording
from planner.words import sentence as sentence


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
    abnormal: bool = False  # the station is in a forbidden state (ISA-101: coloured)
    overdue: bool = False  # the station has reminded the person (RunnerConfig.reminder)
    cause: str = ""  # what is wrong and what it stops, read first (above the buttons)
    safety: str = ""  # the model's safety note of a maintenance step, read before Done
    # approval: the recovery plan's machine steps in words, listed on demand; `plan` their
    # transitions (what one decision approves, sent back as shown) and `plan_steps` their
    # steps in the plan, of which `asked` may be approved one by one (an engineer's choice)
    steps: tuple[str, ...] = ()
    plan: tuple[str, ...] = ()
    plan_steps: tuple[int, ...] = ()
    numbers: tuple[int, ...] = ()  # the steps' numbers among the plan's machine steps
    asked: tuple[int, ...] = ()
    waiting: str = ""  # instruction: shown ahead; the station first does this (no Done yet)

    @property
    def label(self) -> str:
        """The card's kind in words, read before anything else on the card."""
        if self.kind is CardKind.APPROVAL:
            return "Abnormal \u2014 approve?"
        if self.abnormal:
            return "Abnormal \u2014 your step"
        if self.kind is CardKind.INSTRUCTION:
            ahead = "Next \u00b7 " if self.waiting else ""
            number = f" \u00b7 step {self.step} of {self.of}" if self.of else ""
            return f"{ahead}Maintenance{number}"
        return "Your task"

    @property
    def page_title(self) -> str:
        """What the browser tab says while this card waits ("Approve: …", "Do: …")."""
        verb = "Approve" if self.kind is CardKind.APPROVAL else "Do"
        return f"{verb}: {self.title}"


def task_cards(view: StationView) -> list[TaskCard]:
    """The most urgent first: approvals of forbidden states (nothing runs without them), then
    maintenance and recovery steps, then the routine watch cards.  The operator's page shows
    the first one only, with the count of the others."""
    return [*_approvals(view), *_instructions(view), *_command_cards(view)]


class Activity(StrEnum):
    """What the station is doing when it has nothing for the operator."""

    IDLE = "idle"  # nothing started
    BUSY = "busy"  # an engine is being assembled
    COMPLETE = "complete"  # every started intention finished


@dataclass(frozen=True)
class StationActivity:
    kind: Activity
    title: str
    text: str


def station_activity(view: StationView) -> StationActivity:
    """The words of the "nothing for you" card: idle, assembling (and what), or complete."""
    words = view.model.words
    intentions = view.state.intentions
    running = view.state.busy_intentions()
    if running:
        doing = _executing(view)
        what = f" ({'; '.join(doing)})" if doing else ""
        title = "Nothing for you"
        return StationActivity(
            Activity.BUSY, title, f"The station is working on: {words.intention(running[0])}{what}."
        )
    if any(s is IntentionState.FINISHED for s in intentions.values()):
        return StationActivity(
            Activity.COMPLETE, "Engine complete", "Everything started is finished."
        )
    mode = " It is in restart mode." if view.state.restart_mode else ""
    return StationActivity(
        Activity.IDLE, "Nothing to do", f"The station is idle: nothing is started.{mode}"
    )


def _cancelled(view: StationView) -> bool:
    """Nothing is being worked on, and the last intention to stop was stopped by a person
    (back to initial from executing or error): a watch card left over is not a task."""
    if view.state.busy_intentions():
        return False
    for e in reversed(view.events):
        if e.kind is EventKind.INTENTION:
            return e.detail.get("after") == IntentionState.INITIAL and e.detail.get("before") in (
                IntentionState.EXECUTING,
                IntentionState.ERROR,
            )
    return False


def _executing(view: StationView) -> list[str]:
    words = view.model.words
    executing = set(view.state.operations_in(OperationState.EXECUTING))
    ops = view.model.station.operations
    return [words.operation(o.name) for o in ops if o.name in executing]


def _command_cards(view: StationView) -> list[TaskCard]:
    """The card each person's watch shows (planner.model.watch), until the person taps Done."""
    cards: list[TaskCard] = []
    values = view.state.values
    words = view.model.words
    if _cancelled(view):  # the card's intention was cancelled by the engineer: nothing to do
        return cards
    running = view.state.busy_intentions()
    for person, watch in view.model.station.watches:
        card = values.get(watch.card)
        if card in (None, IDLE) or values.get(watch.done) != IDLE:
            continue
        for ability in view.model.station.abilities:
            executing = ability.predicates.get("executing")
            mine = ability.resource == person.name
            if mine and executing and view.runner.holds(executing, values):
                title = sentence(words.ability(ability.qualified))
                break
        else:
            title = sentence(words.text(str(card).replace("_", " ")))
        why = (
            f"The station needs it for: {words.intention(running[0])}."
            if running
            else "The station needs it next."
        )
        waited = _waited_for_a_person(view)
        if waited:
            why += f" The station has been waiting for you for {waited}."
        cards.append(
            TaskCard(
                CardKind.COMMAND, f"card-{card}", title, why, card=str(card), overdue=bool(waited)
            )
        )
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
    """The maintenance plan's person's steps asked now (or the next one, shown ahead while
    the robots' steps before it run), then a recovery's person's steps."""
    s = view.state
    cards = []
    plan = s.maintenance
    if plan is not None:
        # numbered among a person's steps of the plan (the robots' steps between are not
        # the person's to count): 1 of 2, 2 of 2 -- never "1 of 7" then "3 of 7"
        people = [
            k
            for k, b in enumerate(plan.blocks)
            if view.runner.index.kind_of(b.transition) is TransitionKind.MAINTENANCE
        ]
        cause, stopped = _failure(view, s.maintenance_for)
        shown: list[tuple[int, str]] = [(k, "") for k in sorted(plan.asked - plan.taken)]
        ahead = next_maintenance(view.runner.index, plan)
        if not shown and ahead is not None:
            shown = [(ahead[0], _first_the_station(view, plan, ahead[1]))]
        for k, waiting in shown:
            name = plan.blocks[k].transition
            number = people.index(k) + 1 if k in people else 0
            cards.append(
                TaskCard(
                    CardKind.INSTRUCTION,
                    f"maintenance-{name}",
                    sentence(describe(view, name)),
                    _joined(stopped, _safe(view, name)),
                    detail=f"step {number} of {len(people)}" if number else "",
                    transition=name,
                    step=number,
                    of=len(people) if number else 0,
                    cause=cause,
                    safety=view.model.words.safety(name),
                    waiting=waiting,
                )
            )
    return cards + _recovery_instructions(view)


def _first_the_station(view: StationView, plan: TransitionPlan, blocks: list[int]) -> str:
    """What the station does before a person's step shown ahead ("Wait: the station first
    does this: robot 1: move above the engine; the nutrunner: stop.")."""
    words = view.model.words
    steps = "; ".join(words.step(plan.blocks[j].transition) for j in blocks)
    return f"Wait: the station first does this: {steps}." if steps else "Wait a moment."


def _recovery_instructions(view: StationView) -> list[TaskCard]:
    plan = view.state.recovery
    if plan is None:
        return []
    cards = []
    violated = _violated(view)
    for k in sorted(plan.approved - plan.taken):
        name = plan.blocks[k].transition
        if view.runner.index.kind_of(name) is TransitionKind.MAINTENANCE:
            cards.append(
                TaskCard(
                    CardKind.INSTRUCTION,
                    f"recovery-{name}",
                    sentence(describe(view, name)),
                    _joined(
                        "Your step puts it right; if you cannot do it, say so and the "
                        "station looks for another way.",
                        _safe(view, name),
                    ),
                    transition=name,
                    step=k,
                    rejectable=True,
                    abnormal=True,
                    cause=f"Not allowed now: {violated}.",
                    safety=view.model.words.safety(name),
                )
            )
    return cards


def _approvals(view: StationView) -> list[TaskCard]:
    """The recovery plan as one decision: what is wrong, what the station will do (its
    machine steps, each named by what it acts on), approved or refused once."""
    plan = view.state.recovery
    if plan is None or not plan.asked - plan.approved:
        return []
    index = view.runner.index
    steps = plan_steps(view, plan, needs_approval(index, plan))
    first = min(plan.asked - plan.approved)
    n = len(steps)
    return [
        TaskCard(
            CardKind.APPROVAL,
            f"approval-{first}",
            headline(view.model.words, steps),
            "Nothing moves before you approve. Approve once for every step, or reject the "
            "plan: the station looks for another way without these steps.",
            detail=f"The {n} machine step{'s' if n != 1 else ''}",
            transition=plan.blocks[first].transition,
            step=first,
            of=n,
            abnormal=True,
            cause=f"Not allowed now: {_violated(view)}.",
            steps=tuple(s.line for s in steps),
            plan=tuple(s.transition for s in steps),
            plan_steps=tuple(s.step for s in steps),
            numbers=tuple(s.number for s in steps),
            asked=tuple(sorted(plan.asked - plan.approved)),
        )
    ]


def _violated(view: StationView) -> str:
    """The specifications the state breaks, in words (inside a sentence: not capitalised)."""
    words = view.model.words
    names = sorted(view.state.relaxed)
    return " and ".join(words.specification(n) for n in names) or "the rules"


def _safe(view: StationView, name: str) -> str:
    """What the model made safe before a person's step (its specifications with `before`,
    which the plan already met): "Made safe first: ..."."""
    words = view.model.words
    said = [
        r.display or words.text(r.description) or r.name
        for r in view.model.station.step_requirements
        if name in r.steps
    ]
    return f"Made safe first: {'; '.join(said)}." if said else ""


def _joined(*parts: str) -> str:
    return " ".join(p for p in parts if p)


def describe(view: StationView, name: str) -> str:
    """A transition's words (what the step does)."""
    return view.model.words.transition(name)


def _failure(view: StationView, operation: str) -> tuple[str, str]:
    """The cause ("Robot 2 stopped answering above the engine.") and what it stopped, said
    without a pronoun that could point at the cause ("The station cannot go on with: ...")."""
    words = view.model.words
    cause = first_cause(view)
    if not operation:
        return cause or "Something went wrong that needs your hands.", ""
    stopped = f"The station cannot go on with: {words.operation(operation)}."
    if cause:
        return cause, stopped
    reason = view.state.operation_causes.get(operation, "")
    return (f"{sentence(words.text(reason))}." if reason else ""), stopped


_CAUSES = (EventKind.UNAVAILABLE, EventKind.TIMEOUT, EventKind.UNEXPECTED)


def first_cause(view: StationView) -> str:
    """The first thing that went wrong since the station last started an intention, in
    words ("Robot 2 stopped answering."); "" when nothing did.  The runner's own causes
    (`operation_causes`) name a consequence ("its goal cannot be reached while ..."), the
    events the origin."""
    events = view.events
    start = 0
    for k in range(len(events) - 1, -1, -1):
        e = events[k]
        if e.kind is EventKind.INTENTION and e.detail.get("before") == IntentionState.INITIAL:
            start = k
            break
    values = view.state.values
    for e in events[start:]:
        if e.kind in _CAUSES:
            where = also = ""
            if e.kind is EventKind.UNAVAILABLE:  # where it stopped, and whom it keeps out
                where = resource_place(view, e.subject, values.__getitem__)
                also = kept_out_words(view, e.subject, values.__getitem__)
            return cause_words(view.model.words, e, where, also)
    return ""


def cause_words(words: Wording, event: Event, where: str = "", also: str = "") -> str:
    """One cause event as a sentence for a person; `also`, what follows from it for the
    others ("robot 1 cannot go there")."""
    if event.kind is EventKind.UNAVAILABLE:
        at = f" {where}" if where else ""
        then = f"; {also}" if also else ""
        return sentence(f"{words.resource(event.subject)} stopped answering{at}{then}.")
    if event.kind is EventKind.TIMEOUT:
        return sentence(f"{words.step(event.subject)}: did not happen in time.")
    if event.detail.get("why") == "a different effect":
        return sentence(f"{words.step(event.subject)}: happened instead of what was expected.")
    return sentence(f"Something changed that nothing explains: {words.names(_split(event))}.")


def _split(event: Event) -> list[str]:
    return [n.strip() for n in event.subject.split(",") if n.strip()]
