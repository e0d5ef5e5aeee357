"""Alarm rationalisation (ISA-18.2): one fault, one alarm.

`conditions` says everything that is wrong; most of it follows from one cause.  A robot that
stops answering puts the operations that need it in error, then the intention they serve:
four conditions, one fault.  Here the conditions become alarms:

- a *root* condition is a cause: the station halted, a forbidden state, a resource not
  answering or unable to act, stale values, an effect that did not happen in time, a person
  waited for far too long, the station's own notices;
- a *consequential* one follows from a cause: an operation or an intention in error, and an
  effect of a resource that is not answering (of course it does not happen).  It does not
  raise its own alarm: it is listed under the root it follows from (state-based suppression),
  the root taking the highest priority of its group;
- which root: the one of the consequence's own resource if there is one, else the first-out
  (the earliest raised root still active);
- with no root at all (a camera that keeps missing: the operation in error is all there is),
  the first consequence out is the root, and the rest are listed under it; an alarm raised
  that way stays the root while it holds, so a group does not change its name halfway.

`StartUp` keeps a resource that has not answered since the station (re)started from raising
an alarm until its grace is over: a station that starts is not a fault.

Pure: no I/O, no clock (times are passed in).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace

from app.station.alarm_conditions import Condition, Priority
from app.station.alarms import Alarm
from planner.runner import RunnerState

STARTUP_GRACE = 30.0  # seconds a device may take to answer first (robots power on first)

_CONSEQUENTIAL = ("intention:", "operation:")


def rationalise(
    found: Mapping[str, Condition],
    active: Mapping[str, Alarm],
    quiet: Iterable[str] = (),
) -> dict[str, Condition]:
    """The alarms to raise for `found`: its roots, each with its consequences' words and keys
    and the highest priority of its group.  `active` are the book's active alarms (first-out
    order, who already is a root and what it gathered); `quiet` are resources in their
    start-up grace: their `resource:` conditions are held back with what follows from them."""
    roots, following = _split(found, active)
    for alarm in active.values():  # a root whose consequences outlive it stays their root
        if alarm.key not in roots and set(alarm.grouped) & {c.key for c in following}:
            roots[alarm.key] = Condition(alarm.key, alarm.priority, alarm.message, alarm.resource)
    if following and not roots:
        first = min(following, key=lambda c: _out(c, active))
        roots, following = {first.key: first}, [c for c in following if c is not first]
    grouped: dict[str, list[Condition]] = {key: [] for key in roots}
    for condition in following:
        grouped[_root_of(condition, roots, active)].append(condition)
    held = {f"resource:{name}" for name in quiet}
    return {key: _with(roots[key], members) for key, members in grouped.items() if key not in held}


def _split(
    found: Mapping[str, Condition], active: Mapping[str, Alarm]
) -> tuple[dict[str, Condition], list[Condition]]:
    """Roots and consequences (module docstring); an alarm already raised as a root stays one."""
    roots: dict[str, Condition] = {}
    following: list[Condition] = []
    for key in sorted(found):
        condition = found[key]
        silent = key.startswith("effect:") and f"resource:{condition.resource}" in found
        if (key.startswith(_CONSEQUENTIAL) or silent) and key not in active:
            following.append(condition)
        else:
            roots[key] = condition
    return roots, following


def _out(condition: Condition, active: Mapping[str, Alarm]) -> tuple[float, int, str]:
    """First-out order: raised earlier; new ones after, an operation (the nearer cause)
    before an intention, then by key."""
    nearer = 0 if condition.key.startswith("operation:") else 1
    known = active.get(condition.key)
    return (known.raised_at if known else float("inf"), nearer, condition.key)


def _root_of(
    condition: Condition, roots: Mapping[str, Condition], active: Mapping[str, Alarm]
) -> str:
    """The root it was listed under before, else its own resource's, else the first out."""
    before = [k for k in roots if k in active and condition.key in active[k].grouped]
    if before:
        return before[0]
    own = [r for r in roots.values() if condition.resource and r.resource == condition.resource]
    candidates = own or list(roots.values())
    return min(candidates, key=lambda r: (_out(r, active)[0], r.priority.rank, r.key)).key


def _with(root: Condition, members: list[Condition]) -> Condition:
    if not members:
        return root
    priority = min((root.priority, *(m.priority for m in members)), key=lambda p: p.rank)
    words = tuple(dict.fromkeys(m.message for m in members))
    keys = tuple(m.key for m in members)
    return replace(root, priority=priority, consequences=words, grouped=keys)


@dataclass
class StartUp:
    """Which resources are still starting: not heard since the station (re)started at
    `since` (station time), while the grace lasts."""

    since: float | None = None
    grace: float = STARTUP_GRACE
    answered: set[str] = field(default_factory=set)

    def restart(self, now: float) -> None:
        """The station started, or was put back to a start (an experiment): all start again."""
        self.since = now
        self.answered.clear()

    def quiet(self, state: RunnerState, now: float) -> frozenset[str]:
        """The resources whose silence is start-up, not a fault, at `now`."""
        if self.since is None:
            self.restart(now)
        since = self.since if self.since is not None else now
        self.answered |= {r for r, heard in state.last_heard.items() if heard > since}
        if now - since >= self.grace:
            return frozenset()
        return frozenset(state.unavailable - self.answered)


__all__ = ["STARTUP_GRACE", "Priority", "StartUp", "rationalise"]
