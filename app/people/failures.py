"""Failures of people nobody has signed in yet (a wrong password, a throttled sign-in, a bad
bearer token), counted for the audit log: one record per window per address block, with how
many, never one per attempt.

Someone guessing from rotating addresses used to write an fsync'd audit record per attempt,
and every name they typed joined the auditor's choice of users.  Here an attempt only counts
in memory (`note`, on the request's thread: no I/O); a `FailureWriter` thread writes each
block's summary once its window is over (`due`), off every request's path.  Addresses are
grouped by block (IPv4 /24, IPv6 /64: what one attacker rotates through), a record names a
user only when the name is a real one (the caller says so), and what was typed is kept as a
few sample names in the record's detail.

Memory is bounded: at most `max_blocks` summaries are open; failures from further blocks
are counted together under "other addresses" until a window ends.
"""

from __future__ import annotations

import ipaddress
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

log = logging.getLogger(__name__)

OTHERS = "other addresses"  # the block of failures past `max_blocks`
SAMPLE_NAMES = 5  # typed names kept per summary
NAME_CHARS = 64


def address_block(address: str) -> str:
    """The block an address is counted in: its IPv4 /24 or IPv6 /64 ("10.1.2.0/24"), or the
    text itself (cut short) when it is no address."""
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return address[:NAME_CHARS]
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    prefix = 24 if ip.version == 4 else 64
    return str(ipaddress.ip_network(f"{ip}/{prefix}", strict=False))


@dataclass
class Summary:
    """The failures of one kind (`subject`) from one block in one window, for one real user
    (`user`, "" for names that are no user's)."""

    subject: str
    block: str
    user: str
    opened: float  # monotonic: when the window began
    first: float  # wall clock: the first failure, for the record
    last: float = 0.0
    count: int = 0
    names: list[str] = field(default_factory=list)
    why: dict[str, int] = field(default_factory=dict)

    def detail(self) -> dict[str, object]:
        found: dict[str, object] = {"addresses": self.block, "count": self.count}
        found.update(first=self.first, last=self.last)
        if self.names:
            found["names"] = list(self.names)
        if self.why:
            found["why"] = dict(self.why)
        return found


@dataclass
class FailureLog:
    window: float = 60.0
    max_blocks: int = 1000
    clock: Callable[[], float] = time.monotonic

    def __post_init__(self) -> None:
        self._lock = threading.Lock()
        self._open: dict[tuple[str, str, str], Summary] = {}

    def note(self, subject: str, address: str, wall: float, user: str = "", **seen: str) -> None:
        """One failure: `subject` ("failed", "throttled", "bad token") from `address`, for
        the real user `user` if any; `seen` may hold the `name` typed and `why`."""
        block = address_block(address)
        with self._lock:
            key = (subject, block, user)
            summary = self._open.get(key)
            if summary is None:
                if len(self._open) >= self.max_blocks:
                    key = (subject, OTHERS, user)
                    summary = self._open.get(key)
                if summary is None:
                    summary = Summary(subject, key[1], user, self.clock(), wall)
                    self._open[key] = summary
            summary.count += 1
            summary.last = wall
            name = seen.get("name", "")[:NAME_CHARS]
            if name and name not in summary.names and len(summary.names) < SAMPLE_NAMES:
                summary.names.append(name)
            why = seen.get("why", "")
            if why and (why in summary.why or len(summary.why) < SAMPLE_NAMES):
                summary.why[why] = summary.why.get(why, 0) + 1

    def due(self, everything: bool = False) -> list[Summary]:
        """The summaries whose window is over (every one with `everything`), taken out."""
        now = self.clock()
        with self._lock:
            keys = [k for k, s in self._open.items() if everything or now - s.opened >= self.window]
            return [self._open.pop(k) for k in keys]

    def open_summaries(self) -> int:
        """Summaries held now (for the memory bound's test)."""
        return len(self._open)


class FailureWriter:
    """The thread that hands finished summaries to `write` (the audit log) every `period`
    seconds, and the rest when stopped."""

    def __init__(
        self, failures: FailureLog, write: Callable[[list[Summary]], None], period: float = 5.0
    ) -> None:
        self.failures, self.write, self.period = failures, write, period
        self.stopping = threading.Event()
        self.thread: threading.Thread | None = None

    def start(self) -> None:
        self.thread = threading.Thread(target=self._run, name="failure-summaries", daemon=True)
        self.thread.start()

    def flush(self, everything: bool = False) -> None:
        found = self.failures.due(everything)
        if found:
            self.write(found)

    def _run(self) -> None:
        while not self.stopping.wait(self.period):
            try:
                self.flush()
            except Exception:  # a full disk must not end the summaries for good
                log.exception("writing the failed sign-ins' summary failed")

    def stop(self) -> None:
        self.stopping.set()
        if self.thread is not None:
            self.thread.join(timeout=5)
        try:
            self.flush(everything=True)
        except Exception:
            log.exception("writing the last failed sign-ins' summary failed")
