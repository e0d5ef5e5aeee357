"""The simulation panel: the papers' experiments E1-E9 on the simulated station, each with
its faults and what it expects of the recovery and of the operator, and what the station
does while one plays.  A station on real devices has no panel (404)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

from fastapi import APIRouter, Form, HTTPException, Request
from fastapi.responses import Response

from app.pages import station_rows
from app.pages.cards import task_cards
from app.station.cycle import ScheduledFault
from app.station.experiments import group_of
from app.station.live import LiveStation
from app.station.scenario import Scenario
from app.station.view import StationView
from app.web import outcomes
from app.web.actions import answer, known
from app.web.deps import ServerDep, Simulator
from app.web.limits import NAME_CHARS
from app.web.pages import htmx, live_fragment, render
from planner.runner import IntentionState, OperationState
from planner.words import Wording, recovery_words

router = APIRouter(include_in_schema=False)
Experiments = dict[str, tuple[str, Scenario]]  # id -> (title, scenario), as Server keeps them


def simulated(live: LiveStation) -> StationView:
    view = live.view
    if not live.simulated:
        raise HTTPException(404, "this station runs real devices: there is no simulation panel")
    return view


def fault_text(fault: ScheduledFault, words: Wording) -> str:
    text = station_rows.fault_words(fault.fault, words)
    if fault.when is not None:
        return f"{text}, when {words.condition(fault.when)}"
    if fault.at is not None:
        return f"{text}, {fault.at:g} s after the start"
    return text


def running_words(view: StationView) -> str:
    """The run going on now, in words ("" if none): what playing an experiment drops."""
    busy = view.state.busy_intentions()
    if not busy:
        return ""
    words = view.model.words
    return ", ".join(words.intention(name) for name in busy)


def play_question(title: str, view: StationView, emulated: bool) -> str:
    """What Play asks first: the run it drops, if one is going, then the start it puts."""
    back = "emulated devices are put" if emulated else "simulated station is reset"
    ask = f"Play {title}? The {back} back to the experiment's start."
    running = running_words(view)
    if running:
        ask = f"A run is going ({running}): playing drops it. {ask}"
    return ask


def ending_words(expect: Mapping[str, Any]) -> str:
    """How a fault scenario says a good station ends, in words ("" if it does not say)."""
    if expect.get("ends") == "done":
        return "finishes"
    who = sorted({str(w.get("who")) for w in expect.get("waiting_for") or ()})
    if expect.get("ends") == "stopped" and who:
        return f"stops quietly and waits for the {' and the '.join(who)}"
    return ""


def experiments_context(
    experiments: Experiments, view: StationView, emulated: bool
) -> dict[str, Any]:
    words = view.model.words
    rows = []
    for key, (title, scenario) in experiments.items():
        expect = scenario.expect
        rows.append(
            {
                "id": key,
                "title": words.text(title),
                "description": words.text(scenario.description),
                "intentions": [words.intention(i) for i in scenario.started],
                "faults": [fault_text(f, words) for f in scenario.faults],
                "recovery": [recovery_words(str(r)) for r in expect.get("recovery") or ()],
                "recovery_labels": [str(r) for r in expect.get("recovery") or ()],
                "operator": [words.text(str(o)) for o in expect.get("operator") or ()],
                "confirm": play_question(words.text(title), view, emulated),
                "group": group_of(scenario),
                "ends": ending_words(expect),
            }
        )
    faults = [r for r in rows if r["group"] == "faults"]
    rows = [r for r in rows if r["group"] != "faults"]
    return {"experiments": rows, "fault_scenarios": faults, "running_now": running_words(view)}


def simulation_status(experiments: Experiments, view: StationView) -> dict[str, Any]:
    s, words = view.state, view.model.words
    playing = [sc for title, sc in experiments.values() if title == view.experiment]
    faults = playing[0].faults if playing else ()
    said = {f.text: fault_text(f, words) for f in faults}
    return {
        "armed": [said.get(text, words.text(text)) for text in view.armed_faults],
        "executing": [words.intention(n) for n in s.intentions_in(IntentionState.EXECUTING)]
        + [words.operation(n) for n in s.operations_in(OperationState.EXECUTING)],
        "errors": [words.intention(n) for n in s.intentions_in(IntentionState.ERROR)]
        + [words.operation(n) for n in s.operations_in(OperationState.ERROR)],
        "tasks": len(task_cards(view)),
    }


@router.get("/simulation")
def simulation_page(request: Request, caller: Simulator, srv: ServerDep) -> Response:
    view = simulated(srv.live)
    return render(
        request,
        "simulation.html",
        caller,
        "simulation",
        view=view,
        **experiments_context(srv.experiments, view, srv.live.on_emulators),
        **simulation_status(srv.experiments, view),
    )


@router.get("/simulation/fragments/experiments")
def experiments_fragment(request: Request, caller: Simulator, srv: ServerDep) -> Response:
    """The experiments, live: Play says the run it would drop while one is going."""
    view = simulated(srv.live)
    context = experiments_context(srv.experiments, view, srv.live.on_emulators)
    return live_fragment(
        request, "_simulation_experiments.html", caller, "simulation", view=view, **context
    )


@router.post("/simulation/devices/put-back")
async def put_devices_back(request: Request, caller: Simulator, srv: ServerDep) -> Response:
    """The emulated devices out of the faults an experiment left (audited with the user);
    409 on a simulated world or real devices."""
    simulated(srv.live)
    names = await answer(srv.live.put_devices_back(caller.name))
    words = srv.live.view.model.words
    named = ", ".join(words.resource(n) for n in names) or "no device"
    done = f"Devices put back where they are, out of their faults: {named}."
    if not htmx(request):
        return outcomes.done(request, "/simulation", done)
    view = srv.live.view
    return render(
        request,
        "_simulation_status.html",
        caller,
        "simulation",
        view=view,
        flash=done,
        **simulation_status(srv.experiments, view),
    )


@router.get("/simulation/fragments/status")
def simulation_fragment(request: Request, caller: Simulator, srv: ServerDep) -> Response:
    view = simulated(srv.live)
    context = simulation_status(srv.experiments, view)
    return live_fragment(
        request, "_simulation_status.html", caller, "simulation", view=view, **context
    )


@router.post("/simulation/experiment")
async def play_experiment(
    request: Request,
    caller: Simulator,
    srv: ServerDep,
    experiment: Annotated[str, Form(max_length=NAME_CHARS)],
    hands_free: Annotated[bool, Form()] = False,
) -> Response:
    """Play an experiment; `hands_free` (a checkbox): the station plays its operator too."""
    simulated(srv.live)
    key = known(experiment.strip(), sorted(srv.experiments), "experiment")
    title, scenario = srv.experiments[key]
    await answer(srv.live.play_experiment(scenario, title, caller.name, hands_free))
    view = srv.live.view
    started = f"{view.model.words.text(title)}: started. Watch the station and the tasks pages."
    if hands_free:
        started = f"{view.model.words.text(title)}: started; the station plays the operator too."
    if not htmx(request):
        return outcomes.done(request, "/simulation", started)
    return render(
        request,
        "_simulation_status.html",
        caller,
        "simulation",
        view=view,
        flash=started,
        **simulation_status(srv.experiments, view),
    )
