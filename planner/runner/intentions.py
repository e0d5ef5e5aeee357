"""Phase 4: intentions start when their precondition holds and finish when their goal does.

An intention starts by itself only when it is allowed to (`RunnerState.auto_start`: every
intention unless the configuration names some; a person's start allows it again) and never
in restart mode.  Finishing applies its actions.  Its life cycle is in
`planner.runner.vocabulary.IntentionState`.
"""

from __future__ import annotations

from planner.model.expressions import assigned
from planner.runner.tick import Tick
from planner.runner.vocabulary import IntentionState


def start_and_finish(tick: Tick) -> None:
    state = tick.state
    index = tick.index
    current = tick.current()
    for name in index.intentions:
        now = state.intentions[name]
        if now == IntentionState.EXECUTING and index.intention_goal[name](current):
            tick.set_intention(name, IntentionState.FINISHED, "goal reached")
            state.values.update(assigned(index.intentions[name].actions, state.values))
            state.auto_start.discard(name)
        elif (
            now == IntentionState.INITIAL
            and name in state.auto_start
            and not state.restart_mode
            and index.intention_precondition[name](current)
        ):
            if not state.busy_intentions():  # production starts: a new run's progress
                state.run_finished = ()
            tick.set_intention(name, IntentionState.EXECUTING, "precondition holds")
