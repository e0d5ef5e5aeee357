"""Carrying a station's state over to another version of its model.

An engineer activates a new model version while the station is idle or in restart mode.
What both versions know is kept: values still in their variable's domain, restart mode and
its reason, intentions that had finished or failed (with why).  Plans, operations and
time-outs start afresh: they were made for the old model.
"""

from __future__ import annotations

from planner.runner.runner import Runner
from planner.runner.state import RunnerState
from planner.runner.vocabulary import IntentionState


def carry_over(old: RunnerState, runner: Runner, now: float) -> RunnerState:
    """`old` (a state of the previous version) as a state of `runner`'s model."""
    model = runner.model
    kept = {
        name: value
        for name, value in old.values.items()
        if name in model.variable_index and value in model.variable(name).domain
    }
    state = runner.initial(now, kept)
    state.restart_mode = old.restart_mode
    state.restart_reason, state.restart_user = old.restart_reason, old.restart_user
    for name, value in old.intentions.items():
        if name in state.intentions and value in (IntentionState.FINISHED, IntentionState.ERROR):
            state.intentions[name] = value
            if name in old.intention_causes:
                state.intention_causes[name] = old.intention_causes[name]
    return state
