"""Runs of a station's intentions, the engines it builds one by one: the one definition.

A *run* begins in the round an intention begins executing while production was idle (no
intention executing or in error), whoever started it: a person, an intention that starts by
itself, or a start accepted earlier whose precondition came later.  It lasts while
production is busy (some intention executing, or in error waiting for a way out, so that an
intention started again after its error goes on in the same run) and ends in the round
none is: *finished* when every intention of the run finished, *cancelled* otherwise.
Putting the station back to a start (an experiment) *interrupts* a run; `sp run` *stops*
one at its time limit.

`RunTracker` follows the rounds and says each beginning and end as a `run` event
(`EventKind.RUN`, subject `started` or `ended`, with `why` in people's words, the run's
`intentions` and, at the end, its `outcome`).  The live station commits them with their
round, `sp run` prints them, and the timeline, "done today" and the alarm book read them.
Pure: the time comes in as `now`, and nothing is read or written.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from enum import StrEnum

from planner.runner import Action, Event, EventKind, IntentionState, RunnerState, StartIntention
from planner.words import Wording


class Outcome(StrEnum):
    """How a run ended (RUNNING: it has not)."""

    FINISHED = "finished"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"  # an experiment put the station back to a start
    STOPPED = "stopped"  # `sp run` ran out of time
    RUNNING = "running"


class RunBoundary(StrEnum):
    """The subject of a `run` event."""

    STARTED = "started"
    ENDED = "ended"


class RunTracker:
    """Follows a station's rounds and says where runs begin and end (module docstring).

    `state`: the runner's state when tracking begins; a station started again in the middle
    of a run goes on with that run (its beginning is in the log already).
    """

    def __init__(self, words: Wording, state: RunnerState | None = None) -> None:
        self.words = words
        self.intentions: list[str] = [] if state is None else state.busy_intentions()
        self.open = bool(self.intentions)

    def around(
        self, now: float, state: RunnerState, events: Sequence[Event], actions: Sequence[Action]
    ) -> list[Event]:
        """A round's tick `events` with its run events around them, in the order a reader
        of the log wants: a run that begins first, a run that ends last.  `state` is the
        runner's after the tick, `actions` the people's actions it took."""
        found = self.observe(now, state, events, actions)
        begins = [e for e in found if e.subject == RunBoundary.STARTED]
        ends = [e for e in found if e.subject == RunBoundary.ENDED]
        return [*begins, *events, *ends]

    def observe(
        self, now: float, state: RunnerState, events: Sequence[Event], actions: Sequence[Action]
    ) -> list[Event]:
        """The run events of a round: `state` after its tick, its `events` (an intention may
        begin and finish in one tick) and the people's `actions` it took."""
        started = [
            e.subject
            for e in events
            if e.kind is EventKind.INTENTION and e.detail.get("after") == IntentionState.EXECUTING
        ]
        busy = state.busy_intentions()
        out: list[Event] = []
        if not self.open and (started or busy):
            self.open = True
            self.intentions = _unique([*started, *busy])
            why = self._why_started(self.intentions, actions)
            out.append(self._event(now, RunBoundary.STARTED, why))
        elif self.open:
            self.intentions = _unique([*self.intentions, *started, *busy])
        if self.open and not busy:
            out.append(self._end(now, state))
        return out

    def interrupt(self, now: float, why: str) -> list[Event]:
        """The station was put back to a start: an open run ends, interrupted."""
        return self._close(now, Outcome.INTERRUPTED, why)

    def stop(self, now: float, why: str) -> list[Event]:
        """`sp run` stops: an open run ends, stopped."""
        return self._close(now, Outcome.STOPPED, why)

    def _end(self, now: float, state: RunnerState) -> Event:
        finished = [
            n for n in self.intentions if state.intentions.get(n) == IntentionState.FINISHED
        ]
        cancelled = [n for n in self.intentions if n not in finished]
        said = [f"{self.words.names(sorted(finished))} finished"] if finished else []
        said += [f"{self.words.names(sorted(cancelled))} stopped"] if cancelled else []
        outcome = Outcome.CANCELLED if cancelled else Outcome.FINISHED
        return self._close(now, outcome, "; ".join(said))[0]

    def _close(self, now: float, outcome: Outcome, why: str) -> list[Event]:
        if not self.open:
            return []
        event = self._event(now, RunBoundary.ENDED, why, outcome=outcome.value)
        self.open, self.intentions = False, []
        return [event]

    def _event(self, now: float, boundary: RunBoundary, why: str, **more: str) -> Event:
        detail = {"why": why, "intentions": list(self.intentions), **more}
        return Event(now, EventKind.RUN, boundary.value, detail)

    def _why_started(self, intentions: Sequence[str], actions: Iterable[Action]) -> str:
        """ "ada started assemble the engine on an idle station", or without a person's
        start in this round "assemble the engine started on an idle station"."""
        for action in actions:
            if isinstance(action, StartIntention) and action.name in intentions:
                return (
                    f"{action.user} started {self.words.intention(action.name)} on an idle station"
                )
        return f"{self.words.names(list(intentions))} started on an idle station"


def _unique(names: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(names))
