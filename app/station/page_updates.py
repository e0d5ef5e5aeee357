"""Telling the open pages what changed, by server-sent events (`app.web.routes.events`).

The station loop announces after each committed round which areas changed ("station",
"alarm", or an area a page registered); each browser's event stream gets the names on its
own asyncio loop.  An area registered with `watch` is announced only when what it shows
changed, so that a page is not re-rendered under a person's finger on every tick.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from typing import Generic, TypeVar

View = TypeVar("View")


class PageUpdates(Generic[View]):
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.subscribers: list[tuple[asyncio.AbstractEventLoop, asyncio.Queue[str]]] = []
        self.areas: dict[str, Callable[[View], object]] = {}
        self.shown: dict[str, object] = {}

    def watch(self, name: str, shows: Callable[[View], object], view: View) -> None:
        """Announce `name` only when `shows(view)` changes."""
        self.areas[name] = shows
        self.shown[name] = shows(view)

    def changed_areas(self, view: View) -> set[str]:
        changed = set()
        for name, shows in self.areas.items():
            now = shows(view)
            if now != self.shown.get(name):
                self.shown[name] = now
                changed.add(name)
        return changed

    def subscribe(self) -> asyncio.Queue[str]:
        """A queue, on the caller's event loop, that receives the names of what changed."""
        changes: asyncio.Queue[str] = asyncio.Queue(maxsize=100)
        with self.lock:
            self.subscribers.append((asyncio.get_running_loop(), changes))
        return changes

    def unsubscribe(self, changes: asyncio.Queue[str]) -> None:
        with self.lock:
            self.subscribers = [(lp, q) for lp, q in self.subscribers if q is not changes]

    def notify(self, kinds: set[str]) -> None:
        with self.lock:
            subscribers = list(self.subscribers)
        for loop, changes in subscribers:
            for kind in sorted(kinds):
                try:
                    loop.call_soon_threadsafe(_offer, changes, kind)
                except RuntimeError:  # that client's event loop is closed
                    self.unsubscribe(changes)


def _offer(changes: asyncio.Queue[str], kind: str) -> None:
    if not changes.full():  # a slow client misses names, not the newest state
        changes.put_nowait(kind)
