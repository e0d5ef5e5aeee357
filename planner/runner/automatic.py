"""Phase 2: automatic transitions, and whether the state violates a specification.

Automatic transitions are taken whenever enabled, before any controlled one (DESIGN.md
section 3.1), to a fixpoint.  The fixpoint is bounded: more steps in a row than the
configuration allows is a cycle in the model, reported once, after which automatic steps
are halted (and, since they have priority, so is every controlled step) until the model is
fixed.
"""

from __future__ import annotations

from itertools import product
from math import prod

from planner.model.semantics import State
from planner.runner.observing import happened
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind

MAX_UNKNOWN = 4096  # value combinations of stale variables an automatic guard is tried on


def settle(tick: Tick) -> None:
    """Automatic transitions to a fixpoint, the first enabled in model order each time.

    Only those whose guard reads a variable changed since the last fixpoint can be enabled,
    so only they are looked at."""
    state = tick.state
    if state.halted:
        return
    automatics = tick.index.semantics.automatic
    current = tick.current()
    candidates = candidate_automatics(tick, current)
    fired = False
    for _ in range(tick.config.max_automatic_steps):
        chosen = next((k for k in sorted(candidates) if may_fire(tick, k, current)), None)
        if chosen is None:
            if fired:
                tick.set_values(current)
            state.automatics_settled_at = current
            return
        candidates = {k for k in candidates if k >= chosen}  # those before: disabled
        for position in tick.index.automatic_writes[chosen]:
            candidates.update(tick.index.automatics_reading[position])
        current = automatics[chosen].apply(current)
        fired = True
        tick.emit(EventKind.TAKEN, automatics[chosen].name, type="automatic")
        happened(tick, automatics[chosen].name)
    state.halted = "automatic transitions cycle"
    tick.set_values(current)
    tick.emit(
        EventKind.ERROR,
        "automatic cycle",
        why=f"more than {tick.config.max_automatic_steps} automatic steps in a row; "
        "automatic steps are halted until the model is fixed",
    )


def may_fire(tick: Tick, k: int, current: State) -> bool:
    """Whether automatic transition k fires: its guard holds whatever the values it reads
    that nobody vouches for now are (the measured variables of a resource that does not
    answer, the variables of a silent device without one).  Those are what the station saw
    last, not what is: a frozen robot stream still says "on bolt pair 1" while the robot
    stands on pair 2, and finishing pair 1 there would stop the nutrunner on pair 2's bolts.
    A guard that does not read them is taken as it is (a robot's silence does not stop the
    other robot's tightening)."""
    guard = tick.index.semantics.automatic[k].guard
    if not guard(current):
        return False
    unknown = stale_reads(tick, k)
    if not unknown:
        return True
    domains = [tick.index.model.variables[p].domain for p in unknown]
    if prod(len(d) for d in domains) > MAX_UNKNOWN:
        return False  # too many to look at: wait until they are known again
    varied = list(current)
    for values in product(*domains):
        for position, value in zip(unknown, values, strict=True):
            varied[position] = value
        if not guard(tuple(varied)):
            return False
    return True


def stale_reads(tick: Tick, k: int) -> list[int]:
    """The positions of the variables automatic k's guard reads whose values are stale."""
    state = tick.state
    if not state.stale and not state.unavailable:
        return []
    index = tick.index
    stale = set(state.stale)
    for resource in state.unavailable - state.cannot_act.keys():  # those that answer: trusted
        stale |= index.resource_measured.get(resource, frozenset())
    position = index.model.variable_index
    return sorted(position[n] for n in index.automatic_reads[k] & stale)


def candidate_automatics(tick: Tick, current: State) -> set[int]:
    found = touched(tick.index.automatics_reading, tick.state.automatics_settled_at, current)
    return set(range(len(tick.index.semantics.automatic))) if found is None else found


def automatic_enabled(tick: Tick, current: State) -> bool:
    """Is an automatic transition enabled (so that no controlled step may go first)?"""
    automatics = tick.index.semantics.automatic
    return any(automatics[k].guard(current) for k in candidate_automatics(tick, current))


def violates_specifications(tick: Tick) -> bool:
    """Does the state violate a specification?  Since the last state seen to violate none,
    only invariants reading a changed variable can have become false."""
    state = tick.state
    current = tick.current()
    invariants = tick.index.semantics.invariants
    found = touched(tick.index.invariants_reading, state.invariants_held_at, current)
    look = range(len(invariants)) if found is None else sorted(found)
    if any(not invariants[k][1](current) for k in look):
        return True
    state.invariants_held_at = current
    return False


def touched(readers: list[list[int]], before: State | None, now: State) -> set[int] | None:
    """What reads a variable that differs between the two states (None: no `before`, so
    everything may have changed); `readers[position]` lists what reads that variable."""
    if before is None:
        return None
    out: set[int] = set()
    for position, (old, new) in enumerate(zip(before, now, strict=True)):
        if old != new:
            out.update(readers[position])
    return out
