"""The experiments E1-E9 of seed 000 Table 1, as the simulation panel offers and plays them.

Playing one puts the station back to the scenario's start: a runner with the scenario's
settings (its intentions started by the engineer who played it, not by themselves), the
devices back to the start values with the scenario's delays (a simulated world) or put back
by their emulators, the scenario's faults armed on the station's clock.  An open run is
interrupted, and the intentions start in the next round, once the devices have reported
from their new start.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from app.station.cycle import StationCycle
from app.station.rounds import Round
from app.station.running import Running, delays_of
from app.station.scenario import Scenario, ScenarioError, load_scenario
from app.store.audit import AuditEntry, AuditKind
from planner.model.station import Station
from planner.runner import StartIntention

log = logging.getLogger(__name__)
SCENARIOS = Path(__file__).resolve().parents[2] / "models" / "scenarios"

TITLES = {
    "e1_bolt_undone": "E1: a tightened bolt pair is undone by hand",
    "e2_oil_filter_early": "E2: oil filters mounted before the bolts are tightened",
    "e3_lock_fails_on_attach": "E3: r1's tool lock never confirms",
    "e4_lock_fails_on_release": "E4: r1's tool release never confirms",
    "e5_r2_disconnects_clear": "E5: r2 stops answering, at home",
    "e6_r2_disconnects_above_engine": "E6: r2 stops answering above the engine",
    "e7_r2_disconnects_holding_tool": "E7: r2 stops answering holding the nutrunner",
    "e8_camera_miss": "E8: the camera does not find the tool",
    "e9_torque_not_reached": "E9: the nutrunner does not reach its torque",
}


def experiments(station: Station, emulated: bool = False) -> dict[str, tuple[str, Scenario]]:
    """The E1-E9 scenarios, for the simulation panel (those that fit the active model); on
    emulated devices also the device-level plays of models/scenarios/devices/ (a protective
    stop, a power cycle, ...), which only devices can play."""
    found: dict[str, tuple[str, Scenario]] = {}
    paths = sorted(SCENARIOS.glob("e*.yaml"))
    if emulated:
        paths += sorted((SCENARIOS / "devices").glob("*.yaml"))
    for path in paths:
        try:
            text = path.read_text(encoding="utf-8")
            scenario = load_scenario(text, str(path), station, devices=emulated)
        except ScenarioError as exc:
            log.warning("experiment %s does not fit the model: %s", path.name, exc)
            continue
        found[path.stem] = (TITLES.get(path.stem, _title(path.stem)), scenario)
    return found


def _title(stem: str) -> str:
    """A device play's title from its file name: "devices: r1 protective stop on the way"."""
    return "devices: " + stem.replace("_", " ")


def play(running: Running, round_: Round, scenario: Scenario, title: str, user: str) -> None:
    """Put the station back to `scenario`'s start in this round (module docstring)."""
    now = round_.now
    sequential = scenario.config.sequential or running.config.sequential  # `sp serve --sequential`
    config = replace(scenario.config, auto_intentions=frozenset(), sequential=sequential)
    runner = running.runner_with(config)
    state = runner.initial(now, scenario.start)
    running.devices.restart(state.values, delays_of(scenario))
    faults = [replace(f, at=None if f.at is None else now + f.at) for f in scenario.faults]
    people = [  # the scenario's people's actions, in the name of who played it
        replace(a, at=None if a.at is None else now + a.at, action=replace(a.action, user=user))
        for a in scenario.actions
    ]
    running.cycle = StationCycle(runner, running.devices, state, faults, people)
    running.experiment = title
    why = f"{user} played the experiment {title}"
    round_.reset = why
    round_.record(AuditEntry(AuditKind.EXPERIMENT, title, user, "", {"file": scenario.file}))
    round_.events += running.runs.interrupt(now, why)
    starts = [StartIntention(user=user, name=name) for name in scenario.intentions or ()]
    running.next_actions += starts
