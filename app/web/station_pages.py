"""The station's overview and its timeline (ISA-101 level 2 and the history behind it).

The overview (`/station`) fits one screen: each intention with its state and progress, each
resource's availability and what it does now, the alarms, what the station waits for, and
links to the details (`/station/details`, app.web.engineer: plans, operations, variables,
devices, controls) and to the timeline.

The timeline (`/station/timeline`): what the station did in its current run and in the runs
before it, as a Gantt chart per resource (`app.history.timeline_drawing`), with each run's cycle
time and the time it lost per cause.  Read from the audit log (`app.history.run_history`), so it
survives restarts and shows runs of earlier model versions too (their names in the active
model's words, or humanised where the active model does not know them)."""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import APIRouter, Depends, HTTPException, Query, Request
from fastapi.responses import Response

from app.history import timeline_drawing
from app.history.run_history import History, run_history
from app.history.runs import Run, seconds
from app.history.timeline import Timeline, timeline
from app.pages import plans as plan_view
from app.people.auth import Permission
from app.station.runs import Outcome
from app.station.view import StationView
from app.web.deps import Caller, page_context, require, server
from app.web.engineer import live_fragment, render
from planner.runner import IntentionState
from planner.runner.waiting import waiting_for
from planner.words import Wording, sentence

router = APIRouter(include_in_schema=False)

Station = Annotated[Caller, Depends(require(Permission.STATION))]
PAST_RUNS = 20  # listed below the chart, newest first

OUTCOME_WORDS = {
    Outcome.FINISHED: "finished",
    Outcome.CANCELLED: "cancelled",
    Outcome.INTERRUPTED: "interrupted: an experiment was played",
    Outcome.STOPPED: "stopped before the end",
    Outcome.RUNNING: "running",
}


@dataclass(frozen=True)
class RunRow:
    """A run as the page lists it."""

    run: Run
    timeline: Timeline
    started: str  # time of day
    intentions: str  # in words
    outcome: str
    cycle_time: str
    losses: tuple[tuple[str, str], ...]  # (cause, time lost), the most first
    lost: str


def _timeline(history: History, run: Run, words: Wording, request: Request) -> Timeline:
    keys = [h.key for h in history.happenings]
    part = history.happenings[
        bisect.bisect_left(keys, run.first) : bisect.bisect_right(keys, run.last)
    ]
    return timeline(part, server(request).live.view.model.station, run, words)


def run_row(history: History, run: Run, words: Wording, request: Request) -> RunRow:
    found = _timeline(history, run, words, request)
    return RunRow(
        run,
        found,
        timeline_drawing.time_of_day(run, run.start),
        words.names(run.intentions) if run.intentions else "no intention",
        OUTCOME_WORDS[run.outcome],
        seconds(run.cycle_time),
        tuple((loss.cause, seconds(loss.seconds)) for loss in found.losses),
        seconds(found.lost),
    )


@router.get("/station/timeline")
def timeline_page(
    request: Request,
    caller: Station,
    run: Annotated[int | None, Query(ge=1, le=2**62)] = None,
) -> Response:
    srv = server(request)
    view = srv.live.view
    words = view.model.words
    history = run_history(srv.store, srv.live.name)
    chosen = history.run(run)
    if run is not None and chosen is None:
        raise HTTPException(404, "no run starts at that record: pick one from the list")
    shown = run_row(history, chosen, words, request) if chosen is not None else None
    past = [run_row(history, r, words, request) for r in reversed(history.runs[-PAST_RUNS:])]
    title = ""
    chart = None
    if shown is not None:
        title = f"Timeline of the run started at {shown.started}: {shown.intentions}"
        chart = timeline_drawing.draw(shown.timeline, title)
    context: dict[str, Any] = {
        "shown": shown,
        "chart": chart,
        "chart_title": title,
        "past": past,
        "legend": timeline_drawing.LEGEND,
        "newest": history.runs[-1].first if history.runs else None,
    }
    response: Response = srv.templates.TemplateResponse(
        request, "timeline.html", page_context(request, caller, "station", **context)
    )
    return response


# -- the overview -------------------------------------------------------------------------------


@dataclass(frozen=True)
class ResourceRow:
    name: str
    label: str
    available: bool
    silent: int  # seconds without an answer
    doing: str  # what it does now, in words ("" if nothing)


def overview_context(view: StationView) -> dict[str, Any]:
    """What the overview shows: one consistent round."""
    s, station, words = view.state, view.model.station, view.model.words
    owner = view.runner.index.owner
    doing: dict[str, str] = {}
    for followed in (s.recovery, s.maintenance, s.transition_plan):
        if followed is None:
            continue
        for k in sorted(followed.taken - followed.done):
            transition = followed.blocks[k].transition
            doing.setdefault(owner.get(transition, ""), words.transition(transition))
    resources = [
        ResourceRow(
            r.name,
            sentence(words.resource(r.name)),
            r.name not in s.unavailable,
            int(view.now - s.last_heard.get(r.name, view.now)),
            doing.get(r.name, ""),
        )
        for r in station.resources
    ]
    progress = ""
    if s.operation_plan is not None:
        finished, steps = len(s.operation_plan.finished), len(s.operation_plan.steps)
        progress = f"{finished} of {steps} operations done"
    waits = [(str(w.who), sentence(words.text(w.what))) for w in waiting_for(view.runner, s)]
    return {
        "intentions": plan_view.intention_rows(station, s, words, view.runner.holds),
        "progress": progress,
        "resources": resources,
        "waits": waits,
        "restart": s.restart_mode,
        "forbidden": [words.specification(n) for n in sorted(s.relaxed)]
        if s.recovery is not None
        else [],
        "halted": words.text(s.halted) if s.halted else "",
        "active": bool(s.intentions_in(IntentionState.EXECUTING)),
    }


def overview_fragment(request: Request, caller: Caller, flash: str = "") -> Response:
    """The overview's live part, after a Start or Cancel on it (with `flash`)."""
    view = server(request).live.view
    context = overview_context(view)
    return render(
        request, "_station_overview.html", caller, "station", view, flash=flash, **context
    )


@router.get("/station")
def station_overview(request: Request, caller: Station) -> Response:
    view = server(request).live.view
    return render(request, "station.html", caller, "station", view, **overview_context(view))


@router.get("/station/fragments/overview")
def station_overview_part(request: Request, caller: Station) -> Response:
    view = server(request).live.view
    context = overview_context(view)
    return live_fragment(request, "_station_overview.html", caller, "station", view, **context)
