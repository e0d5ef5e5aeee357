"""Phase 2: automatic transitions, and whether the state violates a specification.

Automatic transitions are taken whenever enabled, before any controlled one (DESIGN.md
section 3.1), to a fixpoint.  The fixpoint is bounded: more steps in a row than the
configuration allows is a cycle in the model, reported once, after which automatic steps
are halted (and, since they have priority, so is every controlled step) until the model is
fixed.
"""

from __future__ import annotations

from planner.model.semantics import State
from planner.runner.observing import happened
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind


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
        chosen = next((k for k in sorted(candidates) if automatics[k].guard(current)), None)
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
