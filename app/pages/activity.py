"""What each resource is doing, read off the same facts as "the station waits for"
(`planner.runner.waiting.waiting_for`) and the runner's state, so that no tile says "Idle"
or "available" about a resource the station is stuck on.

One function, `resource_activities`, for the overview's tiles and the details' rows.  In
order of precedence: a resource that answers but cannot act (with what a person must do),
one that is silent, one that is faulted (an effect of it timed out, or a person is asked to
mend it), one the station waits for (a person's step, by whom), one working, idle.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum

from planner.model.flat import TransitionKind
from planner.model.station import Station
from planner.runner import RunnerState
from planner.runner.waiting import Waiting, Who
from planner.words import Wording, sentence


class Activity(StrEnum):
    CANNOT_ACT = "cannot_act"
    SILENT = "silent"
    FAULTED = "faulted"
    WAITED_FOR = "waited_for"
    WORKING = "working"
    IDLE = "idle"


# the badge's words and its colour (static/css/hmi.css .badge--*)
BADGES: Mapping[Activity, tuple[str, str]] = {
    Activity.CANNOT_ACT: ("cannot act", "unavailable"),
    Activity.SILENT: ("not answering", "unavailable"),
    Activity.FAULTED: ("faulted", "error"),
    Activity.WAITED_FOR: ("waited for", "waits"),
    Activity.WORKING: ("working", "executing"),
    Activity.IDLE: ("idle", "idle"),
}
# whom the station waits for, as a resource's tile says it on the engineer's pages
WAITING_ON: Mapping[Who, str] = {
    Who.ENGINEER: "waiting for you (the engineer)",
    Who.OPERATOR: "waiting for the operator",
    Who.DEVICE: "",
}


@dataclass(frozen=True)
class ResourceActivity:
    name: str
    label: str
    activity: Activity
    detail: str = ""  # the cause, or what it does, in words
    waiting_on: str = ""  # whom the station waits for about it, in words ("" if nobody)
    silent: int = 0  # seconds without an answer (silent only)

    @property
    def available(self) -> bool:
        return self.activity not in (Activity.CANNOT_ACT, Activity.SILENT, Activity.FAULTED)

    @property
    def badge(self) -> str:
        return BADGES[self.activity][0]

    @property
    def badge_class(self) -> str:
        return BADGES[self.activity][1]

    @property
    def cannot_act(self) -> str:
        return self.detail if self.activity is Activity.CANNOT_ACT else ""


def resource_activities(
    station: Station,
    state: RunnerState,
    waits: list[Waiting],
    now: float,
    words: Wording,
) -> list[ResourceActivity]:
    """Every resource's activity in one consistent round (`waits` is `waiting_for` of it)."""
    faults = _faults(station, state, waits, words)
    waited = _people_waited_for(station, waits, words)
    doing = _doing(station, state, words)
    out = []
    for resource in station.resources:
        name = resource.name
        label = sentence(words.resource(name))
        if name in state.cannot_act:
            why = sentence(words.text(state.cannot_act[name]))
            row = ResourceActivity(name, label, Activity.CANNOT_ACT, why, WAITING_ON[Who.OPERATOR])
        elif name in state.unavailable:
            silent = int(now - state.last_heard.get(name, now))
            why = f"Silent for {silent} s: the station waits for it to answer again"
            row = ResourceActivity(name, label, Activity.SILENT, why, silent=silent)
        elif name in faults:
            row = ResourceActivity(name, label, Activity.FAULTED, *faults[name])
        elif name in waited:
            row = ResourceActivity(name, label, Activity.WAITED_FOR, *waited[name])
        elif name in doing:
            row = ResourceActivity(name, label, Activity.WORKING, doing[name])
        else:
            row = ResourceActivity(name, label, Activity.IDLE)
        out.append(row)
    return out


def _faults(
    station: Station, state: RunnerState, waits: list[Waiting], words: Wording
) -> dict[str, tuple[str, str]]:
    """Resources with a timed-out effect, or that a person's maintenance step mends: the
    cause and whom the station waits for."""
    model = station.model
    out: dict[str, tuple[str, str]] = {}
    for effect in sorted(state.timed_out):
        owner = station.owner_of(effect)
        if owner:
            cause = f"{sentence(words.step(effect))}: did not happen in time"
            out.setdefault(owner, (cause, WAITING_ON[Who.ENGINEER]))
    for item in waits:
        if item.subject not in model.transition_index:
            continue
        transition = model.transition(item.subject)
        if transition.kind is not TransitionKind.MAINTENANCE:
            continue
        step = sentence(words.transition(item.subject))
        for variable in sorted(transition.written):
            owner = station.owner_of(variable)
            if owner and owner != station.owner_of(item.subject):
                out[owner] = (f"To be mended by hand: {step}", WAITING_ON[item.who])
    return out


def _people_waited_for(
    station: Station, waits: list[Waiting], words: Wording
) -> dict[str, tuple[str, str]]:
    """People the station waits for (an approval, a step, a report), with the first thing."""
    people = [r.name for r in station.resources if r.person]
    out: dict[str, tuple[str, str]] = {}
    for item in waits:
        if item.who is not Who.OPERATOR:
            continue
        owner = station.owner_of(item.subject)
        for person in [owner] if owner in people else people:
            what = sentence(words.text(item.what))
            out.setdefault(person, (what, WAITING_ON[Who.OPERATOR]))
    return out


def _doing(station: Station, state: RunnerState, words: Wording) -> dict[str, str]:
    """What each resource does now: the first step taken and not done of a plan followed."""
    doing: dict[str, str] = {}
    for followed in (state.recovery, state.maintenance, state.transition_plan):
        if followed is None:
            continue
        for k in sorted(followed.taken - followed.done):
            transition = followed.blocks[k].transition
            doing.setdefault(station.owner_of(transition), words.transition(transition))
    return doing
