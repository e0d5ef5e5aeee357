"""Phase 7: effect monitoring (DESIGN.md section 4.7, seed 000 sec. 4.1).

An effect whose guard has held longer than its time-out without happening is timed out:
disabled in planning queries (the "w/ETO" of a label) and the transition plan is made
again.  It is re-enabled when its guard stops holding or a person re-enables it.  The
effects of a person's resource (`kind: person`: an operator confirming a card) have no
time-out unless the configuration gives one: a reminder after `reminder` seconds instead.
"""

from __future__ import annotations

from planner.runner.automatic import touched
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind, ReplanReason


def monitor_effects(tick: Tick) -> None:
    """Watch enabled effects for time-outs.  Only effects whose guard reads a variable
    changed in this tick, or whose resource came or went, can have become enabled or
    disabled; the enabled and timed-out ones are looked at every tick."""
    state = tick.state
    index = tick.index
    current = tick.current()
    look = touched(index.effects_reading, state.effects_watched_at, current)
    state.effects_watched_at = current
    if look is not None:
        look |= {index.effect_position[n] for n in state.effect_enabled_since}
        look |= {index.effect_position[n] for n in state.timed_out | tick.reenabled_by_people}
        for resource in tick.availability_changed:
            look |= {
                index.effect_position[n]
                for n in index.resource_transitions.get(resource, ())
                if n in index.effect_position
            }
    effects = index.effects if look is None else [index.effects[k] for k in sorted(look)]
    for effect in effects:
        name = effect.name
        enabled = effect.guard(current) and index.station.owner_of(name) not in state.unavailable
        if not enabled:
            state.effect_enabled_since.pop(name, None)
            state.reminded.pop(name, None)
            if name in state.timed_out:
                state.timed_out.discard(name)
                tick.emit(EventKind.REENABLED, name, why="its guard no longer holds")
                # usable again, but nothing says what stopped it is mended: failures stay
                tick.errors_may_clear = True
            continue
        since = state.effect_enabled_since.setdefault(name, tick.now)
        person = name in index.person_effects
        if person:
            remind(tick, name, tick.now - since)
        timeout = tick.config.timeout_of(name, person=person)
        if timeout is not None and name not in state.timed_out and tick.now - since > timeout:
            state.timed_out.add(name)
            tick.emit(EventKind.TIMEOUT, name, waited=round(tick.now - since, 3))
            tick.replan_transitions(ReplanReason.TIMEOUT)


def remind(tick: Tick, name: str, waited: float) -> None:
    """A person's step that has waited `reminder` seconds (and each as long again) gets a
    reminder: no time-out, no failure counted, the plan waits."""
    every = tick.config.reminder
    if every is None or every <= 0:
        return
    due = int(waited // every)
    if due > tick.state.reminded.get(name, 0):
        tick.state.reminded[name] = due
        tick.emit(EventKind.REMINDER, name, waited=round(waited, 3), what=tick.index.describe(name))
