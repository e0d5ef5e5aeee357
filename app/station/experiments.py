"""The experiments E1-E9 of seed 000 Table 1 and the fault scenarios beyond them, as the
simulation panel offers and plays them.

Playing one puts the station back to the scenario's start: a runner with the scenario's
settings (its intentions started by the engineer who played it, not by themselves), the
devices back to the start values with the scenario's delays (a simulated world) or put back
by their emulators, the scenario's faults armed on the station's clock.  An open run is
interrupted, and the intentions start in the next round, once the devices have reported
from their new start.  Played hands-free, the station also plays the scenario's operator
(`app.station.stand_in`): a demonstration, or a soak test, that nobody has to tap through.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from app.station.cycle import StationCycle
from app.station.rounds import Round
from app.station.running import Running, delays_of
from app.station.scenario import Scenario, ScenarioError, load_scenario
from app.station.stand_in import STAND_IN, StandIn
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
    # the fault scenarios of models/scenarios/faults/
    "both_connectors_broken": "Both robots' tool locks never confirm",
    "double_bolts_pulled_while_approval_waits": "Bolts pulled while an approval waits",
    "double_both_robots_silent": "Both robots stop answering, one comes back",
    "double_nutrunner_silent_on_bolts": "The nutrunner stops answering on the bolts",
    "double_oil_filters_and_r2_in_zone": "Oil filters early and robot 2 in the way",
    "double_r1_lock_fails_r2_away": "r1's tool lock fails while r2 is away",
    "double_r1_silent_when_r2_holds_the_nutrunner": "r1 stops answering, r2 holding the nutrunner",
    "endless_camera_misses": "The camera never finds the tool",
    "endless_torque_nok": "The nutrunner never reaches its torque",
    "flapping_r2_network": "r2's network comes and goes",
    "nutrunner_power_cycled_on_bolts": "The nutrunner loses power on the bolts",
    "nutrunner_power_cycled_then_mended": "The nutrunner loses power, then is mended",
    "operator_away_for_minutes": "The operator is away for minutes",
    "reject_oil_filter_removal": "E2, the filter removal rejected",
    "reject_oil_filter_removal_and_alternative": "E2, the removal and the alternative rejected",
    "reject_removal_then_filters_off_by_hand": "E2, rejected, then the filters taken off by hand",
    "reject_while_operator_places_bolts": "E2, rejected while the operator places bolts",
    "robots_take_turns_after_camera_dropout": "The robots take turns after a camera drop-out",
    "slow_operator_places_bolts": "A slow operator places the bolts",
    "slow_r1_moves_arrive_late": "r1's moves arrive late",
    "wrong_estimate_in_restart": "A wrong estimate set in restart mode",
}


def experiments(station: Station, emulated: bool = False) -> dict[str, tuple[str, Scenario]]:
    """The E1-E9 scenarios and the fault scenarios of models/scenarios/faults/, for the
    simulation panel (those that fit the active model); on emulated devices also the
    device-level plays of models/scenarios/devices/ (a protective stop, a power cycle,
    ...), which only devices can play.  A fault scenario that makes planning slow on
    purpose is left out: the station plans at its own pace.  In that order, each by name."""
    found: dict[str, tuple[str, Scenario]] = {}
    paths = sorted(SCENARIOS.glob("e*.yaml")) + sorted((SCENARIOS / "faults").glob("*.yaml"))
    if emulated:
        paths += sorted((SCENARIOS / "devices").glob("*.yaml"))
    for path in paths:
        try:
            text = path.read_text(encoding="utf-8")
            scenario = load_scenario(text, str(path), station, devices=emulated)
        except ScenarioError as exc:
            log.warning("experiment %s does not fit the model: %s", path.name, exc)
            continue
        if scenario.planning_delay == 0:
            found[path.stem] = (TITLES.get(path.stem, _title(path)), scenario)
    return found


def group_of(scenario: Scenario) -> str:
    """The panel's group of an experiment: "faults", "devices", or "" for E1-E9."""
    folder = Path(scenario.file).parent.name
    return folder if folder in ("faults", "devices") else ""


def _title(path: Path) -> str:
    """A title from the file name: "devices: r1 protective stop on the way"."""
    return f"{path.parent.name}: " + path.stem.replace("_", " ")


def play(
    running: Running,
    round_: Round,
    scenario: Scenario,
    title: str,
    user: str,
    hands_free: bool = False,
) -> None:
    """Put the station back to `scenario`'s start in this round (module docstring); with
    `hands_free` the station plays its operator too."""
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
    station = running.model.station
    stand_in = StandIn(scenario, station, user=STAND_IN, taps=True) if hands_free else None
    running.cycle = StationCycle(runner, running.devices, state, faults, people, stand_in)
    running.experiment = title
    why = f"{user} played the experiment {title}" + (" hands-free" if hands_free else "")
    round_.reset = why
    detail = {"file": scenario.file, "hands_free": hands_free}
    round_.record(AuditEntry(AuditKind.EXPERIMENT, title, user, "", detail))
    round_.events += running.runs.interrupt(now, why)
    starts = [StartIntention(user=user, name=name) for name in scenario.intentions or ()]
    running.next_actions += starts
