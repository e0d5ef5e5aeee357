"""`RunnerState.copy` gives a tick a state of its own.

`attempt` rolls a phase whose query is not answered yet back to the copy it saved before the
phase ran (`planner.runner.runner`).  `copy` names its container fields one by one, so a new
`dict`, `list` or `set` field left out of it would be shared by the saved copy and the
working one, and a rolled-back phase would leak its changes into the next tick.
"""

from __future__ import annotations

from dataclasses import MISSING, fields, is_dataclass

from planner.model.expressions import TRUE
from planner.planning.partial_order import Block
from planner.runner.state import OperationPlan, RunnerState, TransitionPlan
from planner.runner.vocabulary import IntentionState, OperationState, ReplanReason


def _plan() -> TransitionPlan:
    block = Block(
        0, ("r1.go", "r1.arrive"), frozenset({"r1.pos"}), frozenset({"r1.pos"}), frozenset()
    )
    return TransitionPlan(
        TRUE, ("r1.go", "r1.arrive"), (block,), {0}, {0: ["r1.arrive"]}, {0}, {0}, {0: "held"}
    )


def _filled() -> RunnerState:
    """A state with every field away from its default (a new field must be given one here)."""
    return RunnerState(
        values={"r1.pos": "home"},
        intentions={"assemble": IntentionState.EXECUTING},
        operations={"tighten": OperationState.EXECUTING},
        operation_goals={"tighten": TRUE},
        failures={"tighten": 1},
        blamed_on_timeouts={"tighten": [frozenset({"r1.arrive"})]},
        resumable={"tighten"},
        operation_plan=OperationPlan(("tighten",), (frozenset(),), {0}, {0}),
        transition_plan=_plan(),
        recovery=_plan(),
        relaxed=frozenset({"apart"}),
        rejected={"r1.go"},
        announced=("apart",),
        recovery_held=(("home",), frozenset({"r1.arrive"})),
        rechecked=("checked",),
        maintenance=_plan(),
        maintenance_for="tighten",
        maintenance_due=True,
        last_heard={"r1": 1.0},
        unavailable={"r1"},
        cannot_act={"r1": "r1 is in a protective stop: release it on r1's teach pendant"},
        stale={"agv.engine": "plc does not answer: no good answer for 1.2 s"},
        effect_enabled_since={"r1.arrive": 1.0},
        timed_out={"r1.arrive"},
        reminded={"r1.arrive": 1},
        restart_mode=True,
        restart_reason="a part fell",
        restart_user="engineer",
        resetting={"tighten"},
        auto_start={"assemble"},
        run_finished=("tighten",),
        next_background_check=1.0,
        replan_operations=ReplanReason.RESET,
        replan_transitions=ReplanReason.RESET,
        halted="an automatic cycle",
        intention_causes={"assemble": "why"},
        operation_causes={"tighten": "why"},
        effects_watched_at=("home",),
        automatics_settled_at=("home",),
        invariants_held_at=("home",),
    )


def _mutable_parts(value: object, path: str, found: dict[int, str]) -> dict[int, str]:
    """Every mutable object reachable from `value` (by id), with where it was found."""
    if isinstance(value, dict | list | set) or (
        is_dataclass(value) and not type(value).__dataclass_params__.frozen
    ):
        found[id(value)] = path
    if isinstance(value, dict):
        for key, item in value.items():
            _mutable_parts(item, f"{path}[{key!r}]", found)
    elif isinstance(value, list | tuple | set | frozenset):
        for k, item in enumerate(value):
            _mutable_parts(item, f"{path}<{k}>", found)
    elif is_dataclass(value) and not isinstance(value, type):
        for f in fields(value):
            _mutable_parts(getattr(value, f.name), f"{path}.{f.name}", found)
    return found


def test_the_filled_state_gives_every_field_a_value_of_its_own() -> None:
    state = _filled()
    for f in fields(RunnerState):
        if f.default is not MISSING:
            default: object = f.default
        elif f.default_factory is not MISSING:
            default = f.default_factory()
        else:
            continue  # required: given anyway
        assert getattr(state, f.name) != default, f"give {f.name} a value in _filled()"


def test_a_copy_shares_no_mutable_part_with_the_state_it_was_made_from() -> None:
    state = _filled()
    copy = state.copy()
    assert copy == state
    original = _mutable_parts(state, "state", {})
    copied = _mutable_parts(copy, "state", {})
    shared = sorted(original[i] for i in original.keys() & copied.keys())
    assert not shared, f"RunnerState.copy() shares {', '.join(shared)}: copy it in copy()"


def test_changing_a_copy_leaves_the_state_as_it_was() -> None:
    state = _filled()
    copy = state.copy()
    copy.values["r1.pos"] = "bp1"
    copy.blamed_on_timeouts["tighten"].append(frozenset())
    assert copy.transition_plan is not None
    copy.transition_plan.remaining[0].clear()
    copy.unavailable.clear()
    assert state == _filled()
