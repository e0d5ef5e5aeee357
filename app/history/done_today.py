"""An operator's "done today": the engines the station completed since midnight and the
person's own tasks, read from the audit log (the runs as `app.history.run_history` finds them).

An engine is a finished run of an intention the model marks as the product (`product: true`):
a run that only tightened the bolts is no engine.  A model that marks none keeps the older
count: every finished run is one."""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import select

from app.history.run_history import run_history
from app.station.runs import Outcome
from app.store.db import Store
from app.store.tables import AuditRecord
from planner.model.station import Station
from planner.runner import EventKind
from planner.runner.vocabulary import PersonAct
from planner.words import Wording, sentence

# the records of a person's own taps on the task cards (app.station.live, planner.runner.people)
_TASKS = {
    PersonAct.CARD_DONE: "Done",
    PersonAct.MAINTENANCE_DONE: "Done",
    PersonAct.APPROVE: "Approved",
    PersonAct.REJECT: "Could not do / rejected",
    PersonAct.APPROVE_PLAN: "Approved",
    PersonAct.REJECT_PLAN: "Rejected",
}


@dataclass(frozen=True)
class DoneItem:
    time: float  # wall time
    text: str

    @property
    def clock(self) -> str:
        return datetime.fromtimestamp(self.time).astimezone().strftime("%H:%M")


@dataclass(frozen=True)
class DoneToday:
    engines: tuple[DoneItem, ...]  # completed runs, newest first
    tasks: tuple[DoneItem, ...]  # this person's, newest first


def midnight(now: float) -> float:
    """The start of the local day of wall time `now`."""
    day = datetime.fromtimestamp(now).astimezone()
    return day.replace(hour=0, minute=0, second=0, microsecond=0).timestamp()


def done_today(
    store: Store, station: str, user: str, model: Station, words: Wording, now: float
) -> DoneToday:
    since = midnight(now)
    query = (
        select(AuditRecord)
        .where(
            AuditRecord.station == station,
            AuditRecord.user == user,
            AuditRecord.kind == EventKind.OPERATOR,
            AuditRecord.subject.in_(sorted(_TASKS)),
            AuditRecord.time >= since,
        )
        .order_by(AuditRecord.id.desc())
        .limit(500)
    )
    with store.sessions() as session:
        rows = [(r.time, r.subject, json.loads(r.detail or "{}")) for r in session.scalars(query)]
    cards = [watch.card for _, watch in model.watches]
    tasks = tuple(DoneItem(t, _task_words(words, cards, subject, d)) for t, subject, d in rows)
    engines = []
    products = {i.name for i in model.intentions if i.product}
    for run in run_history(store, station).runs:
        end = run.wall(run.end)
        if products and not products & set(run.intentions):
            continue  # not the product: a part of the work run on its own
        if run.outcome is Outcome.FINISHED and end is not None and end >= since:
            what = sentence(words.names(run.intentions))
            engines.append(DoneItem(end, f"{what}: complete"))
    engines.sort(key=lambda item: item.time, reverse=True)
    return DoneToday(tuple(engines), tasks)


def _task_words(words: Wording, cards: list[str], subject: str, detail: dict[str, object]) -> str:
    """ "Done: the card for placing bolt pair 1", "Approved: robot 1: move down onto ..."."""
    transition, card = str(detail.get("transition", "")), str(detail.get("card", ""))
    planned = detail.get("transitions")
    if isinstance(planned, list) and planned:  # a recovery plan decided at once
        count = f"{len(planned)} step{'s' if len(planned) != 1 else ''}"
        return f"{_TASKS[PersonAct(subject)]}: the recovery plan ({count})"
    if transition:  # the person's own step by what it does, an approved one with its doer
        what = (
            words.transition(transition)
            if subject == PersonAct.MAINTENANCE_DONE
            else words.step(transition)
        )
    elif card:
        # the card's words are its value's words on the watch's card variable
        what = f"the card {words.value_name(cards[0], card)}" if cards else words.text(card)
    else:
        what = "a task"
    return f"{_TASKS[PersonAct(subject)]}: {sentence(what)}"
