"""Runner snapshots: a state saved as JSON restores to the same state, and a restored runner
carries on exactly as the one that was killed would have."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any

import pytest

import app.station.player
from app.station import supervisor_cache
from app.station.player import Planners, play
from app.station.scenario import Scenario, load_scenario
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.partial_order import Block
from planner.reading import load_station
from planner.runner import (
    Event,
    Inputs,
    OperationPlan,
    Runner,
    RunnerState,
    TickResult,
    TransitionPlan,
)
from planner.runner.snapshot import FORMAT, STORED_AS, SnapshotError, dump, load
from tests.support.paths import REPOSITORY

ROOT = REPOSITORY
MODEL = ROOT / "models" / "demo_station.yaml"
SCENARIOS = sorted((ROOT / "models" / "scenarios").glob("*.yaml"))
E6 = "e6_r2_disconnects_above_engine"
# not stored: None after loading
CACHES = {
    "effects_watched_at",
    "automatics_settled_at",
    "invariants_held_at",
    "recovery_held",
    "rechecked",
}


@dataclass
class TickRecord:
    inputs: Inputs
    now: float
    commands: dict[str, Any]
    events: list[Event]


@dataclass
class Run:
    scenario: Scenario
    runner: Runner
    states: list[RunnerState]  # after each tick, as `play`'s watch saw them
    ticks: list[TickRecord]


@pytest.fixture(scope="module")
def demo() -> tuple[Station, Planners]:
    text = MODEL.read_text()
    station = load_station(text, str(MODEL))
    directory = supervisor_cache.default_directory()
    transition = supervisor_cache.planner(station.model, text, "bdd", directory)
    return station, Planners(transition, OperationPlanner(station))


@pytest.fixture(scope="module")
def runs(demo: tuple[Station, Planners]) -> dict[str, Run]:
    """Every scenario played once, with what each tick was given and gave back."""
    station, planners = demo
    made: list[Runner] = []
    ticks: list[TickRecord] = []

    class Recording(Runner):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            made.append(self)

        def tick(self, state: RunnerState, inputs: Inputs, now: float) -> TickResult:
            result = super().tick(state, inputs, now)
            ticks.append(TickRecord(inputs, now, dict(result.commands), list(result.events)))
            return result

    out = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(app.station.player, "Runner", Recording)
        for path in SCENARIOS:
            scenario = load_scenario(path.read_text(), str(path), station)
            states: list[RunnerState] = []
            made.clear()
            ticks.clear()
            events = list(play(station, scenario, planners, watch=states.append))
            assert events[-1].kind == "done", path.name
            out[path.stem] = Run(scenario, made[0], states, list(ticks))
    return out


def restored(runner: Runner, state: RunnerState, now: float) -> RunnerState:
    """Through JSON text, as the database keeps it."""
    return load(runner, json.loads(json.dumps(dump(state))), now)


def sampled(states: list[RunnerState]) -> list[RunnerState]:
    """Every 10th state, and every one in the middle of something rare."""
    return [
        s
        for k, s in enumerate(states)
        if k % 10 == 0 or s.recovery or s.maintenance or s.resetting or s.timed_out or s.unavailable
    ]


def assert_round_trip(runner: Runner, state: RunnerState) -> None:
    now = state.next_background_check
    back = restored(runner, state, now)
    assert [getattr(back, cache) for cache in sorted(CACHES)] == [None] * len(CACHES)
    assert back.last_heard == dict.fromkeys(state.last_heard, now)
    assert back.effect_enabled_since == dict.fromkeys(state.effect_enabled_since, now)
    assert back.next_background_check == now
    rest = replace(
        back, last_heard=state.last_heard, effect_enabled_since=state.effect_enabled_since
    )
    caches = {cache: getattr(state, cache) for cache in CACHES}
    assert replace(rest, **caches) == state
    # where the runner iterates in order, the order survives too
    for name in ("values", "intentions", "operations", "operation_goals"):
        assert list(getattr(back, name)) == list(getattr(state, name)), name


@pytest.mark.parametrize("name", [p.stem for p in SCENARIOS])
def test_a_state_saved_after_a_tick_loads_back_the_same(runs: dict[str, Run], name: str) -> None:
    run = runs[name]
    for state in sampled(run.states):
        assert_round_trip(run.runner, state)


def test_the_scenarios_exercise_every_stored_field(runs: dict[str, Run]) -> None:
    """The round trips above are only as good as what the states held."""
    names = {f.name for f in fields(RunnerState)} - CACHES
    used = {n for run in runs.values() for s in sampled(run.states) for n in names if getattr(s, n)}
    # no scenario here rejects a step, cycles, has a late effect, a person long away or a
    # robot that says it cannot move (that one: tests/planner/runner/test_cannot_act.py) or a
    # silent device without a resource (tests/planner/runner/test_stale_values.py)
    assert names - used == {"rejected", "halted", "resumable", "reminded", "cannot_act", "stale"}


def test_rejected_steps_a_halt_a_late_effect_and_reminders_round_trip(
    runs: dict[str, Run],
) -> None:
    run = runs["e2_oil_filter_early"]
    state = next(s for s in run.states if s.recovery is not None)
    assert state.recovery is not None
    rejected = {state.recovery.blocks[0].transition}
    rare = replace(
        state,
        rejected=rejected,
        halted="automatic cycle",
        resumable={"get_nr_r1"},
        reminded={"operator.confirm": 2},
        unavailable={"r2"},
        cannot_act={"r2": "r2 is in a protective stop: release it on r2's teach pendant"},
        stale={"agv.engine": "plc does not answer: no good answer for 1.2 s"},
    )
    assert_round_trip(run.runner, rare)


def test_every_field_is_stored_or_declared_a_cache(runs: dict[str, Run]) -> None:
    """Fails when a field is added to the runner's state (or its plans) and not to snapshots."""
    state = next(s for s in runs[E6].states if s.operation_plan is not None and s.transition_plan)
    saved = dump(state)
    stored = {STORED_AS.get(f.name, f.name) for f in fields(RunnerState)} - CACHES
    assert set(saved) - {"format"} == stored
    assert set(saved["transition_plan"]) == {f.name for f in fields(TransitionPlan)}
    assert set(saved["transition_plan"]["blocks"][0]) == {f.name for f in fields(Block)}
    assert set(saved["operation_plan"]) == {f.name for f in fields(OperationPlan)}


def test_a_restored_runner_carries_on_exactly_like_the_original(
    demo: tuple[Station, Planners], runs: dict[str, Run]
) -> None:
    """Killed in E6 while the operator is asked to move the dead r2 home; a fresh runner,
    given the same inputs from then on, must do exactly what the original did.

    Rebasing changes nothing here, so the streams can be compared event for event: r2 is
    already unavailable (its `heard` no longer matters until it answers) and every connected
    resource answers every tick; the background check runs on the same ticks because the
    new clock starts at the saved `next_recheck`; no effect is close to timing out.
    """
    station, planners = demo
    run = runs[E6]
    k = next(
        k for k, s in enumerate(run.states) if s.maintenance is not None and "r2" in s.unavailable
    )
    saved = run.states[k]
    assert any(e.kind == "instruction" for t in run.ticks[: k + 1] for e in t.events)
    fresh = Runner(station, planners.transition, planners.operation, run.scenario.config)
    state = restored(fresh, saved, saved.next_background_check)
    later = run.ticks[k + 1 :]
    assert len(later) >= 200
    for tick in later:
        result = fresh.tick(state, tick.inputs, tick.now)
        state = result.state
        assert [(e.kind, e.subject, e.detail) for e in result.events] == [
            (e.kind, e.subject, e.detail) for e in tick.events
        ], tick.now
        assert result.commands == tick.commands
    final, original = dump(state), dump(run.states[-1])
    # the one difference: r2 never answered again, so its heartbeat stayed rebased
    assert final.pop("heard") == original.pop("heard") | {"r2": saved.next_background_check}
    assert final == original


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """Set the entry at a path of keys separated by `/` (list positions as numbers)."""

    def change(data: dict[str, Any]) -> None:
        *parents, last = [int(p) if p.isdigit() else p for p in path.split("/")]
        for key in parents:
            data = data[key]
        data[last] = value

    return change


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (_set("format", FORMAT + 1), f"snapshot format {FORMAT + 1}"),
        (_set("values/r9.pos", "home"), "values: unknown variable 'r9.pos'"),
        (_set("values", {"r1.pos": "moon"}), "'moon' is not a value of 'r1.pos'"),
        (_set("values", {"r1_tc.lock": 1}), "1 is not a value of 'r1_tc.lock' (bool)"),
        (_set("transition_plan/blocks/0/steps/0", "r1.fly"), "unknown transition 'r1.fly'"),
        (_set("transition_plan/steps/0", "r1.fly"), "transition_plan.steps: unknown transition"),
        (_set("intentions/tighten_bolts", "done"), "intentions['tighten_bolts']: state 'done'"),
        (_set("operations/place_bp4", "f"), "operations['place_bp4']: state 'f' is not one of"),
        (_set("intentions/build_car", "i"), "intentions: unknown intention 'build_car'"),
        (_set("goals", [["place_bp4", "r1.poss == home"]]), "goals['place_bp4']: unknown"),
        (_set("transition_plan/taken", [99]), "transition_plan.taken: [99]"),
        (_set("restart", "yes"), "restart: expected bool, found 'yes'"),
        (lambda data: data.pop("armed"), "the snapshot: armed missing"),
    ],
)
def test_an_unusable_snapshot_raises_naming_what_is_wrong(
    runs: dict[str, Run], change: Callable[[dict[str, Any]], None], message: str
) -> None:
    run = runs[E6]
    state = next(s for s in run.states if s.transition_plan is not None)
    data = json.loads(json.dumps(dump(state)))
    change(data)
    with pytest.raises(SnapshotError) as caught:
        load(run.runner, data, 0.0)
    assert message in str(caught.value)


def test_an_older_or_newer_model_loads_what_it_knows_unless_strict(runs: dict[str, Run]) -> None:
    run = runs[E6]
    state = run.states[-1]
    data = json.loads(json.dumps(dump(state)))
    data["values"]["r9.pos"] = "home"  # from a model that had an r9
    data["intentions"]["build_car"] = "e"
    data["armed"].append("build_car")
    del data["values"]["r1.pos"]  # the model added a variable and an intention since
    del data["intentions"]["tighten_bolts"]
    with pytest.raises(SnapshotError, match=r"unknown variable 'r9\.pos'"):
        load(run.runner, data, 5.0)
    back = load(run.runner, data, 5.0, strict=False)
    assert "r9.pos" not in back.values
    assert "build_car" not in back.intentions and "build_car" not in back.auto_start
    assert back.values["r1.pos"] == run.runner.model.variable("r1.pos").initial
    assert back.intentions["tighten_bolts"] == "i"
    assert back.operations == state.operations


def test_a_snapshot_saved_before_causes_and_held_steps_were_kept_loads(
    runs: dict[str, Run],
) -> None:
    """Snapshots written before the runner kept the first causes of errors, the restart
    reason and held steps lack those keys; they load with none of them."""
    run = runs[E6]
    state = next(s for s in run.states if s.operation_causes and s.transition_plan is not None)
    data = json.loads(json.dumps(dump(state)))
    for key in ("restart_reason", "restart_user", "intention_causes", "operation_causes"):
        del data[key]
    del data["transition_plan"]["held"]
    back = load(run.runner, data, state.next_background_check)
    assert back.operation_causes == {} and back.intention_causes == {}
    assert back.transition_plan is not None and back.transition_plan.held == {}
    assert back.values == state.values and back.operations == state.operations


def test_restart_reason_and_first_causes_round_trip(runs: dict[str, Run]) -> None:
    run = runs[E6]
    state = next(s for s in run.states if s.operation_causes)
    changed = replace(
        state,
        restart_mode=True,
        restart_reason="r2 pushed aside by hand",
        restart_user="eve",
        intention_causes={"tighten_bolts": "no plan of operations"},
    )
    back = restored(run.runner, changed, changed.next_background_check)
    assert (back.restart_reason, back.restart_user) == ("r2 pushed aside by hand", "eve")
    assert back.intention_causes == {"tighten_bolts": "no plan of operations"}
    assert back.operation_causes == state.operation_causes
