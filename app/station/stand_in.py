"""The station's stand-in for its people, as a scenario describes them.

Headless plays (`app.station.player`) need someone to answer approvals and maintenance
steps; a hands-free play of an experiment on the web station (the simulation panel's
"the station plays the operator too") needs the same, and also someone to tap Done on the
watches' command cards, which the live station leaves to people.  The stand-in does what
the scenario's `operator` says (approve or not, do maintenance or not, reject the first
recovery steps it is asked), each after the scenario's delay, in the name of `user`, so
that the audit log never shows a person's decision that no person made.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from planner.model.expressions import Value
from planner.model.flat import TransitionKind
from planner.model.station import Station
from planner.runner import Action, Approve, Event, EventKind, MaintenanceDone, Reject

if TYPE_CHECKING:  # a scenario's cycle has a stand-in: only the type, no import cycle
    from app.station.scenario import Scenario

STAND_IN = "simulated operator"  # the user its actions carry on the web station


class StandIn:
    """Answers what the runner asks of people, and (with `taps`) taps the watches' cards."""

    def __init__(
        self,
        scenario: Scenario,
        station: Station,
        *,
        user: str = "operator",
        taps: bool = False,
    ) -> None:
        self.scenario, self.station, self.user, self.taps = scenario, station, user, taps
        self.answers: list[tuple[float, Action]] = []
        self.rejects_left = scenario.rejects
        # card variable -> (the card shown, since when, tapped yet)
        self.shown: dict[str, tuple[Value, float, bool]] = {}

    def due(self, now: float) -> tuple[Action, ...]:
        """The answers due now, in their order."""
        actions = tuple(a for t, a in self.answers if t <= now)
        self.answers = [(t, a) for t, a in self.answers if t > now]
        return actions

    def answer(self, event: Event, now: float) -> None:
        """Plan the answer to `event`, if it asks something of people."""
        scenario, user, later = self.scenario, self.user, now + self.scenario.operator_delay
        asked = event.kind is EventKind.APPROVAL or (
            event.kind is EventKind.INSTRUCTION and event.detail.get("recovery") is True
        )
        if asked and self.rejects_left > 0:  # "I cannot do this", after the usual delay
            self.rejects_left -= 1
            self.answers.append((later, Reject(user=user, step=int(event.detail["step"]))))
            return
        done = MaintenanceDone(user=user, transition=event.subject)
        if event.kind is EventKind.APPROVAL and scenario.approve:
            self.answers.append((later, Approve(user=user, step=int(event.detail["step"]))))
            maintenance = event.detail.get("type") == TransitionKind.MAINTENANCE.value
            if maintenance and scenario.maintenance:  # done once approved, a delay later
                self.answers.append((now + 2 * scenario.operator_delay, done))
        elif event.kind is EventKind.INSTRUCTION and scenario.maintenance:
            self.answers.append((later, done))

    def cards_to_tap(self, now: float, values: Mapping[str, Value]) -> list[tuple[str, Value]]:
        """The watches' confirm effects to do now, each with its card: each card shown is
        tapped once, after the delay the scenario gives its effect (as a simulated world
        would play it)."""
        if not self.taps:
            return []
        due = []
        for _, watch in self.station.watches:
            card = values.get(watch.card, "idle")
            if card == "idle":
                self.shown.pop(watch.card, None)
                continue
            shown, since, tapped = self.shown.get(watch.card, (None, now, False))
            if shown != card:
                since, tapped = now, False
            if not tapped and now - since >= self._delay(watch.confirm):
                tapped = True
                due.append((watch.confirm, card))
            self.shown[watch.card] = (card, since, tapped)
        return due

    def _delay(self, effect: str) -> float:
        delays = self.scenario.delays
        if effect in delays:
            return delays[effect]
        return delays.get(self.station.owner_of(effect), self.scenario.default_delay)
