"""How a driver's connection to its device is doing, in one shape for every driver.

The station view shows it per device (connected, latency, last data time) and the runner
gets a heartbeat only from a driver whose link is up and whose data is fresh.  Times are
`time.monotonic()` seconds of the station process.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LinkStatus:
    """A driver's link: `connected` means the device answers and its data makes sense.

    `latency_ms`: the last request's round trip (or the data's age on arrival for streams);
    `last_data`: when the last good data arrived; `error`: why it is not connected, in plain
    words ("" when it is); `restarts`: how often the driver had to start its link again;
    `device_restarts`: how often the device restarted behind an open link (every command
    was then sent again), the last time because of `device_restart`.
    """

    connected: bool
    latency_ms: float | None = None
    last_data: float | None = None
    error: str = ""
    restarts: int = 0
    device_restarts: int = 0
    device_restart: str = ""
