"""Sign-in throttling: slow guessing down without locking the real user out.

Three counters of failed sign-ins in a sliding `window`:

- per user name *and* address: after `pair_limit` failures that address may not try that
  name again until the oldest failure leaves the window (the usual lock of one attacker);
- per address: after `address_limit` failures, whatever the names (one address spraying);
- per user name, from anywhere: after `name_limit` failures each further attempt must wait
  twice as long as the one before, at most `max_delay` seconds, and only one is checked at a
  time (many addresses guessing one password).  An address the user has signed in from
  before is not slowed by this counter, so a real user on their own device is not locked out
  by someone guessing elsewhere.

An attempt is reserved before its password is checked (`begin`) and counted as failed until
`end` says otherwise, so concurrent guesses cannot all pass a check that each made alone.
Memory is bounded: counters older than the window are dropped, and at most `max_keys` are
kept (the least recently used go first).  Nothing here does I/O.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Attempt:
    """A reserved sign-in attempt; hand it back to `end`."""

    name: str
    address: str


@dataclass(frozen=True)
class Refused:
    """Not now: `wait` seconds, and whether this refusal should be audited (the first of
    each window per name and address), with how many were not audited since."""

    wait: float
    audit: bool
    unaudited: int


@dataclass
class _Counter:
    failures: deque[float] = field(default_factory=deque)
    in_flight: int = 0
    last_attempt: float = -math.inf
    refusals_unaudited: int = 0
    audited_refusal: float = -math.inf
    touched: float = -math.inf


@dataclass
class SignInThrottle:
    pair_limit: int = 5
    address_limit: int = 30
    name_limit: int = 10
    window: float = 300.0
    max_delay: float = 30.0
    max_keys: int = 50_000
    clock: Callable[[], float] = time.monotonic

    def __post_init__(self) -> None:
        self._lock = threading.Lock()
        self._counters: OrderedDict[str, _Counter] = OrderedDict()
        self._known: OrderedDict[str, set[str]] = OrderedDict()  # name -> addresses signed in

    def begin(self, name: str, address: str) -> Attempt | Refused:
        name = name.lower()
        with self._lock:
            now = self.clock()
            pair = self._counter(f"pair:{name}\n{address}", now)
            by_address = self._counter(f"address:{address}", now)
            by_name = self._counter(f"name:{name}", now)
            wait = max(
                self._over(pair, self.pair_limit, now),
                self._over(by_address, self.address_limit, now),
                0.0 if address in self._known.get(name, ()) else self._slowed(by_name, now),
            )
            if wait > 0:
                audit = now - pair.audited_refusal >= self.window
                unaudited = pair.refusals_unaudited
                if audit:
                    pair.audited_refusal, pair.refusals_unaudited = now, 0
                else:
                    pair.refusals_unaudited += 1
                return Refused(wait, audit, unaudited)
            for counter in (pair, by_address, by_name):
                counter.in_flight += 1
            by_name.last_attempt = now
            return Attempt(name, address)

    def end(self, attempt: Attempt, succeeded: bool) -> None:
        with self._lock:
            now = self.clock()
            keys = (f"pair:{attempt.name}\n{attempt.address}", f"address:{attempt.address}")
            counters = [self._counter(k, now) for k in (*keys, f"name:{attempt.name}")]
            for counter in counters:
                counter.in_flight = max(0, counter.in_flight - 1)
                if not succeeded:
                    counter.failures.append(now)
            if succeeded:
                counters[0].failures.clear()
                known = self._known.setdefault(attempt.name, set())
                if len(known) < 16:
                    known.add(attempt.address)
                self._known.move_to_end(attempt.name)
                while len(self._known) > self.max_keys:
                    self._known.popitem(last=False)

    def keys(self) -> int:
        """Counters held now (for the memory bound's test)."""
        return len(self._counters)

    def _counter(self, key: str, now: float) -> _Counter:
        counter = self._counters.get(key)
        if counter is None:
            self._sweep(now)
            counter = self._counters[key] = _Counter()
        else:
            self._counters.move_to_end(key)
        counter.touched = now
        while counter.failures and counter.failures[0] <= now - self.window:
            counter.failures.popleft()
        return counter

    def _sweep(self, now: float) -> None:
        """Drop counters untouched for a window from the old end (a few per new counter:
        amortised, never a full scan); at `max_keys`, the least recently used regardless."""
        for key in list(itertools.islice(self._counters, 8)):
            counter = self._counters[key]
            if counter.in_flight or counter.touched > now - self.window:
                break  # ordered by last use: the rest are newer
            del self._counters[key]
        while len(self._counters) >= self.max_keys:
            self._counters.popitem(last=False)

    def _over(self, counter: _Counter, limit: int, now: float) -> float:
        if len(counter.failures) + counter.in_flight < limit:
            return 0.0
        if not counter.failures:  # only attempts in flight: wait for them
            return 1.0
        return max(counter.failures[0] + self.window - now, 0.001)

    def _slowed(self, counter: _Counter, now: float) -> float:
        over = len(counter.failures) + counter.in_flight - self.name_limit
        if over < 0:
            return 0.0
        if counter.in_flight:
            return 1.0  # one check at a time for a name under attack
        delay = min(self.max_delay, 2.0**over)
        return max(counter.last_attempt + delay - now, 0.0)
