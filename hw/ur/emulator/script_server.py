"""The script port (30003): programs sent as URScript text.

A program is a `def NAME():` line at column 0 up to the `end` line at column 0; a line outside
any `def` is a one-line program.  Each replaces whatever program runs (as on a real controller,
where anything sent raw to 30002/30003 replaces the running control script).  `Programs`
is the pure part: text in, complete programs out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

MAX_PROGRAM = 1 << 20


@dataclass
class Programs:
    """Collects script text and yields each program once it is complete."""

    pending: list[str] = field(default_factory=list)
    partial: str = ""

    def feed(self, text: str) -> list[str]:
        done: list[str] = []
        lines = (self.partial + text).split("\n")
        self.partial = lines.pop()
        for line in lines:
            if self.pending:
                self.pending.append(line)
                if line.rstrip() == "end":
                    done.append("\n".join(self.pending) + "\n")
                    self.pending = []
            elif line.startswith("def ") or line.startswith("sec "):
                self.pending = [line]
            elif line.strip():
                done.append(line + "\n")
        if sum(len(x) for x in self.pending) + len(self.partial) > MAX_PROGRAM:
            self.pending, self.partial = [], ""
        return done
