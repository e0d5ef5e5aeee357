"""One device of the device file as the runner sees it: model values in and out.

An adapter (one per protocol: `hw.ur.adapter`, `hw.modbus.adapter`, `hw.watch`) puts a
driver or a watch behind the model's variables with
the pipelines of `hw.pipelines`: `read` gives the device's measured values (and observed
product states), `write` takes the runner's command values, `alive` says whether the runner
may trust the device this round.  Nothing here blocks: drivers do their I/O on their own
threads and processes, and adapters only look at their newest reading.

A reading no pipeline can explain makes the device not alive (the runner marks its resource
unavailable after its heartbeat time-out), and its values are not passed on.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

from hw.device_file.spec import DeviceSpec
from hw.link import LinkStatus
from planner.model.expressions import Value


@dataclass
class AdapterReport:
    """`cannot_act`: the device answers and its values are trusted, but it cannot act now
    (a robot in a protective stop, powered off): what a person must do, naming things by
    their model names ("release r1's protective stop on its teach pendant")."""

    measured: dict[str, Value] = field(default_factory=dict)
    observed: dict[str, Value] = field(default_factory=dict)
    alive: bool = False
    cannot_act: str = ""


class Adapter(Protocol):
    spec: DeviceSpec

    def start(self) -> None: ...

    def restart(self, start: Mapping[str, Value], now: float) -> None: ...

    def close(self) -> None: ...

    def read(self) -> AdapterReport: ...

    def write(self, commands: Mapping[str, Value]) -> None: ...

    def status(self) -> LinkStatus: ...


class Driver(Protocol):
    """The life cycle and link every driver has."""

    def start(self) -> None: ...

    def close(self) -> None: ...

    @property
    def available(self) -> bool: ...

    def status(self) -> LinkStatus: ...
