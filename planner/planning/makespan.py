"""The expected cycle of an operation plan: how long it takes in its partial order.

Operations that share no variable run at once (`partial_order.independent_operations`), so
a plan's length in operations says little about its time: two plans of ten operations can
differ by a robot idling while the other does everything.  Given how long each operation
takes, an operation starts when the last one it waits for has finished, and the plan's
makespan is when its last operation finishes.  Nothing in the seeds does this; the station
learns the durations from its own runs (`app.history.durations`).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence

from planner.planning.partial_order import independent_operations


def makespan(
    plan: Sequence[str],
    after: Sequence[frozenset[int]],
    durations: Mapping[str, float],
    default: float,
) -> float:
    """When the last operation of `plan` finishes, each starting once those it comes
    `after` have finished; an operation without a duration takes `default`."""
    finish: list[float] = []
    for k, name in enumerate(plan):
        start = max((finish[j] for j in after[k]), default=0.0)
        finish.append(start + durations.get(name, default))
    return max(finish, default=0.0)


def expected_makespan(
    variables: Mapping[str, frozenset[str]], plan: Sequence[str], durations: Mapping[str, float]
) -> float:
    """`makespan` in the plan's partial order (operations that share a variable wait for
    each other); an operation never timed is given the median of those that were, so that
    neither the known nor the unknown is preferred for being unknown."""
    default = statistics.median(durations.values()) if durations else 1.0
    after = independent_operations(variables, plan)
    return makespan(plan, after, durations, default)
