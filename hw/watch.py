"""A person's watch behind the model's card and done variables."""

from __future__ import annotations

from collections.abc import Mapping

from hw.adapter import AdapterReport
from hw.device_file.spec import DeviceSpec
from hw.link import LinkStatus
from planner.model.expressions import Value


class WatchAdapter:
    """A person's watch: the card the runner shows, and Done when the person taps it.

    `answer_after`: seconds after which a simulated person taps Done by themselves (headless
    runs on emulated devices); None for people at the web HMI.
    """

    def __init__(
        self,
        spec: DeviceSpec,
        card: str,
        done: str,
        start: Mapping[str, Value],
        answer_after: float | None = None,
    ) -> None:
        self.spec = spec
        self.card_name, self.done_name = card, done
        self.card = start.get(card, "idle")
        self.done = start.get(done, "idle")
        self.answer_after = answer_after
        self.shown_at: float | None = None
        self.now = 0.0

    def restart(self, start: Mapping[str, Value], now: float) -> None:
        self.card = start.get(self.card_name, "idle")
        self.done = start.get(self.done_name, "idle")
        self.shown_at = None

    def start(self) -> None:
        """In the station process: nothing to connect."""

    def close(self) -> None:
        """Nothing to stop."""

    def advance(self, now: float) -> None:
        self.now = now
        if self.card == "idle" and self.done != "idle":
            self.done = "idle"  # the watch clears a confirmed card once the station takes it
        waiting = self.card != "idle" and self.done == "idle"
        if not waiting:
            self.shown_at = None
        elif self.shown_at is None:
            self.shown_at = now
        elif self.answer_after is not None and now - self.shown_at >= self.answer_after:
            self.tap()

    def tap(self) -> bool:
        """The person tapped Done: the card shown is confirmed."""
        if self.card == "idle" or self.done != "idle":
            return False
        self.done = self.card
        return True

    def read(self) -> AdapterReport:
        return AdapterReport({self.done_name: self.done}, alive=True)

    def write(self, commands: Mapping[str, Value]) -> None:
        if self.card_name in commands:
            self.card = commands[self.card_name]

    def status(self) -> LinkStatus:
        return LinkStatus(True, 0.0)
