"""Phase 1: what the devices report (DESIGN.md section 4.1).

Heartbeats decide which resources are available: one that has not answered within the
heartbeat time-out is unavailable and all its transitions are disabled, until it answers
again.  Measured changes are explained by effect transitions, which advances the plans that
expect them; a change no enabled effect explains is `unexpected`, and an effect other than
the one the plans expected is an error event too (section 4.7).  Observed values (a product
tracker's report of decision variables) are taken as they are.
"""

from __future__ import annotations

from collections.abc import Mapping

from planner.model.expressions import Value
from planner.runner.retries import failed_attempt, late_effect
from planner.runner.tick import Tick
from planner.runner.tick_io import Inputs
from planner.runner.vocabulary import EventKind, ReplanReason


def take_inputs(tick: Tick, inputs: Inputs) -> None:
    take_heartbeats(tick, inputs.heartbeats, inputs.cannot_act)
    take_silence(tick, inputs.silent, inputs.stale)
    values = tick.state.values
    changed = {
        name: value
        for name, value in sorted(inputs.measured.items())
        if name in values and values[name] != value
    }
    explain(tick, changed)
    for name, value in sorted(inputs.observed.items()):
        if name in values and values[name] != value:
            before = values[name]
            values[name] = value
            tick.errors_may_clear = True
            tick.emit(EventKind.OBSERVED, name, before=before, after=value)


def take_heartbeats(
    tick: Tick, heartbeats: frozenset[str], cannot_act: Mapping[str, str] | None = None
) -> None:
    """A resource is available while it answers within the heartbeat time-out and its
    devices do not say it cannot act; one that says so (a robot in a protective stop) is
    unavailable at once, with what a person must do, and available again in the first
    round it answers without it."""
    state = tick.state
    cannot_act = cannot_act or {}
    for resource, why in sorted(cannot_act.items()):
        state.last_heard[resource] = tick.now  # it answers
        if state.cannot_act.get(resource) == why:
            continue
        state.cannot_act[resource] = why
        if resource not in state.unavailable:
            unavailable(tick, resource)
        tick.emit(EventKind.UNAVAILABLE, resource, why=why)
    for resource in sorted(heartbeats - cannot_act.keys()):
        state.last_heard[resource] = tick.now
        state.cannot_act.pop(resource, None)
        if resource in state.unavailable:
            state.unavailable.discard(resource)
            state.automatics_settled_at = None  # those that waited for its values: look again
            tick.availability_changed.add(resource)
            tick.cause_gone()
            tick.emit(EventKind.AVAILABLE, resource)
            tick.replan_transitions(ReplanReason.AVAILABILITY)
    for resource, heard in sorted(state.last_heard.items()):
        late = tick.now - heard > tick.config.heartbeat_timeout
        if late:
            state.cannot_act.pop(resource, None)  # silent now: it is not answering at all
        if late and resource not in state.unavailable:
            unavailable(tick, resource)
            tick.emit(EventKind.UNAVAILABLE, resource, silent_for=round(tick.now - heard, 3))


def take_silence(tick: Tick, silent: Mapping[str, str], stale: Mapping[str, str]) -> None:
    """Devices whose drivers judged their link (no fresh data, nonsense): a resource's is
    unavailable at once, since its values are stale now and waiting the heartbeat time-out
    too would let the runner act on them (a frozen robot stream: the pose of a second ago);
    a device without a resource (a PLC) makes its variables stale (`RunnerState.stale`)
    until it answers again."""
    state = tick.state
    for resource, why in sorted(silent.items()):
        halted = state.cannot_act.pop(resource, None)  # silent now: its values are stale too
        if resource not in state.unavailable or halted is not None:
            if resource not in state.unavailable:
                unavailable(tick, resource)
            tick.emit(EventKind.UNAVAILABLE, resource, why=why)
    if dict(stale) == state.stale:
        return
    fresh = sorted(state.stale.keys() - stale.keys())
    if fresh:
        tick.emit(EventKind.FRESH, ", ".join(fresh))
        tick.errors_may_clear = True
        state.automatics_settled_at = None  # those that waited for their values: look again
    said = state.stale
    state.stale = dict(stale)
    for why, names in state.stale_by_why().items():
        newly = [name for name in names if said.get(name) != why]
        if newly:
            tick.emit(EventKind.STALE, ", ".join(newly), why=why)


def unavailable(tick: Tick, resource: str) -> None:
    """The resource is unavailable from now: its transitions leave planning (replanned)."""
    tick.state.unavailable.add(resource)
    tick.availability_changed.add(resource)
    tick.replan_transitions(ReplanReason.AVAILABILITY)


def explain(tick: Tick, changed: dict[str, Value]) -> None:
    """Match measured changes to enabled effects; what no effect explains is unexpected."""
    index = tick.index
    values = tick.state.values
    remaining = dict(changed)
    progress = True
    while remaining and progress:
        progress = False
        state = tick.current()
        candidates = sorted({k for n in remaining for k in index.effects_writing.get(n, ())})
        for effect in (index.effects[k] for k in candidates):
            targets = [a.target for a in effect.transition.actions]
            if not remaining.keys() & set(targets) or not effect.guard(state):
                continue
            after = index.semantics.values(effect.apply(state))
            if all(remaining.get(t, values[t]) == after[t] for t in targets):
                for target in targets:
                    values[target] = after[target]
                    remaining.pop(target, None)
                if effect.name in tick.state.timed_out:
                    tick.emit(EventKind.EFFECT, effect.name, late=True)
                    late_effect(tick, effect.name)
                else:
                    tick.emit(EventKind.EFFECT, effect.name)
                report_a_different_effect(tick, effect.name)
                happened(tick, effect.name)
                progress = True
                break
    if remaining:
        values.update(remaining)
        tick.emit(
            EventKind.UNEXPECTED,
            ", ".join(sorted(remaining)),
            values=dict(sorted(remaining.items())),
        )


def report_a_different_effect(tick: Tick, name: str) -> None:
    """An effect of the same ability as one the plans expect, instead of it (E8, E9)."""
    expected = expected_effects(tick)
    if name in expected:
        return
    instead_of = sorted(tick.index.alternatives.get(name, frozenset()) & expected)
    if instead_of:
        tick.emit(EventKind.UNEXPECTED, name, instead_of=instead_of, why="a different effect")
        plan = tick.state.transition_plan
        if plan is not None and plan.expected() & set(instead_of):
            failed_attempt(tick, f"{name} happened instead of {', '.join(instead_of)}", instead_of)


def expected_effects(tick: Tick) -> set[str]:
    return {name for plan in tick.state.plans_followed() for name in plan.expected()}


def happened(tick: Tick, name: str) -> None:
    """An effect or automatic step happened: the plans waiting for it move on."""
    for plan in tick.state.plans_followed():
        plan.happened(name)
