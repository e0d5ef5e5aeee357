"""Carrying out people's actions on the live station, shared by the pages and the API.

Names are checked here first, so that a typo gets a 404 or 422 that says what exists; the
runner then decides whether the action is allowed now (a refusal becomes a 409 with the
runner's reason).
"""

from __future__ import annotations

import asyncio
from concurrent.futures import Future
from typing import Literal, TypeVar

from fastapi import HTTPException

from app.pages.cards import CardKind, task_cards
from app.station.live import LiveStation, StationError
from planner.model.flat import TransitionKind, VariableKind
from planner.reading.yaml_reader import closest
from planner.runner import Action, Approve, ApprovePlan, Event, Reject, RejectPlan

T = TypeVar("T")
ANSWER_SECONDS = 30.0


async def answer(future: Future[T]) -> T:
    """Wait for the station loop to carry out a request (it answers after committing)."""
    try:
        return await asyncio.wait_for(asyncio.wrap_future(future), ANSWER_SECONDS)
    except TimeoutError:
        raise HTTPException(503, "the station did not answer in time; try again") from None


class RunnerRefused(StationError):
    """The runner refused a person's action (409); its `refused` event, with the user and
    why, is in the audit log already."""


async def perform(live: LiveStation, action: Action) -> list[Event]:
    """Hand `action` to the runner; the events of its round, or RunnerRefused (409) with
    the runner's reason for refusing it."""
    acted = await answer(live.act(action))
    if not acted.reply.accepted:
        raise RunnerRefused(str(acted.reply))
    return list(acted.events)


def known(name: str, names: list[str], what: str) -> str:
    """`name` if it is one of `names`, else a 404 that suggests the closest."""
    if name in names:
        return name
    guess = closest(name, names)
    hint = f"; did you mean '{guess}'?" if guess else ""
    raise HTTPException(404, f"there is no {what} '{name}'{hint}")


def intention_name(live: LiveStation, name: str) -> str:
    return known(name, [i.name for i in live.model.station.intentions], "intention")


def operation_name(live: LiveStation, name: str) -> str:
    return known(name, [o.name for o in live.model.station.operations], "operation")


def effect_name(live: LiveStation, name: str) -> str:
    names = [e.name for e in live.runner.index.effects]
    return known(name, names, "effect transition")


def estimated_value(live: LiveStation, variable: str, text: str) -> tuple[str, bool | str]:
    """The variable (estimated or decision) and `text` read as one of its values, or a 4xx."""
    model = live.model.station.model
    kinds = (VariableKind.ESTIMATED, VariableKind.DECISION)
    names = [v.name for v in model.variables if v.kind in kinds]
    known(variable, names, "estimated or decision variable")
    domain = model.variable(variable).domain
    for value in domain:
        if str(value).lower() == text.strip().lower():
            return variable, value
    shown = ", ".join(str(v).lower() if isinstance(v, bool) else str(v) for v in domain)
    raise HTTPException(422, f"'{text}' is not a value of {variable}; use one of {shown}")


def maintenance_step(live: LiveStation, transition: str) -> str:
    """A maintenance transition a task card asks for now: 404 for no such maintenance
    transition, 409 for one nobody asked for."""

    model = live.model.station.model
    names = [t.name for t in model.transitions if t.kind is TransitionKind.MAINTENANCE]
    known(transition, names, "maintenance transition")
    cards = task_cards(live.view)
    asked = {c.transition for c in cards if c.kind is CardKind.INSTRUCTION and not c.waiting}
    if transition not in asked:
        raise StationError(f"{transition}: not a maintenance step asked for now")
    return transition


Decision = Literal["approve", "reject"]  # a person's answer to an approval card


def step_decision(user: str, step: int, decision: Decision) -> Approve | Reject:
    """One recovery step approved or rejected (the card's per-step way, and the API's)."""
    return Approve(user=user, step=step) if decision == "approve" else Reject(user=user, step=step)


def plan_decision(
    user: str, steps: tuple[str, ...], decision: Decision
) -> ApprovePlan | RejectPlan:
    """The whole recovery plan approved or rejected, its steps as the card showed them."""
    if decision == "approve":
        return ApprovePlan(user=user, steps=steps)
    return RejectPlan(user=user, steps=steps)
