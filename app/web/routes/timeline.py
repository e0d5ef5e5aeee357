"""The station's timeline (`/station/timeline`): what the station did in its current run and
in the runs before it, as a Gantt chart per resource (`app.history.timeline_drawing`), with
each run's cycle time and the time it lost per cause.  Read from the audit log
(`app.history.run_history`), so it survives restarts and shows runs of earlier model
versions too (their names in the active model's words, or humanised where the active model
does not know them)."""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.responses import Response

from app.history import timeline_drawing
from app.history.run_history import History, run_history
from app.history.runs import Run, seconds
from app.history.timeline import Timeline, timeline
from app.station.runs import Outcome
from app.web.deps import LiveDep, StationViewer, StoreDep
from app.web.limits import MAX_RUN
from app.web.pages import render
from planner.model.station import Station
from planner.words import Wording

router = APIRouter(include_in_schema=False)
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
    at_once: str  # how many operations executed at once, and for how long
    losses: tuple[tuple[str, str], ...]  # (cause, time lost), the most first
    lost: str


def _timeline(history: History, run: Run, station: Station, words: Wording) -> Timeline:
    keys = [h.key for h in history.happenings]
    part = history.happenings[
        bisect.bisect_left(keys, run.first) : bisect.bisect_right(keys, run.last)
    ]
    return timeline(part, station, run, words)


def run_row(history: History, run: Run, station: Station, words: Wording) -> RunRow:
    found = _timeline(history, run, station, words)
    return RunRow(
        run,
        found,
        timeline_drawing.time_of_day(run, run.start),
        words.names(run.intentions) if run.intentions else "no intention",
        OUTCOME_WORDS[run.outcome],
        seconds(run.cycle_time),
        at_once_words(found),
        tuple((loss.cause, seconds(loss.seconds)) for loss in found.losses),
        seconds(found.lost),
    )


def at_once_words(found: Timeline) -> str:
    most, together = found.at_once
    if most < 2:
        return "one operation at a time"
    return f"up to {most} operations at once, for {seconds(together)}"


@router.get("/station/timeline")
def timeline_page(
    request: Request,
    caller: StationViewer,
    live: LiveDep,
    store: StoreDep,
    run: Annotated[int | None, Query(ge=1, le=MAX_RUN)] = None,
) -> Response:
    view = live.view
    station, words = view.model.station, view.model.words
    history = run_history(store, live.name)
    chosen = history.run(run)
    if run is not None and chosen is None:
        raise HTTPException(404, "no run starts at that record: pick one from the list")
    shown = run_row(history, chosen, station, words) if chosen is not None else None
    past = [run_row(history, r, station, words) for r in reversed(history.runs[-PAST_RUNS:])]
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
    return render(request, "timeline.html", caller, "station", **context)
