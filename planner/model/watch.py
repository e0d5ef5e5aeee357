"""A person's watch, declared in the model: which card it shows and what a tap does.

A person resource (an operator) may carry a smartwatch (seed 001 section VI-A).  The model
says which of the person's variables is the card the station shows (a command variable),
which is the card the person confirmed (a measured variable over the same values, `idle`
among them), and which of the person's effects a tap on "Done" performs.  The pages and the
devices read this declaration instead of knowing the demo's names:

    - name: operator
      kind: person
      watch: {card: card, done: done, confirm: confirm}
"""

from __future__ import annotations

from dataclasses import dataclass

IDLE = "idle"


@dataclass(frozen=True)
class Watch:
    """Qualified names: `card` (command), `done` (measured), `confirm` (an effect)."""

    card: str
    done: str
    confirm: str
