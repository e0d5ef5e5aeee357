"""The smart nutrunner `nr`: spins up when told to run, tightens to its target torque (or
reports NOK), and stops when told to idle (the model's `run_nut`, seed 003 Tables I, II).

Commands are levels: run = `run_forward` and not `set_idle`; idle = `set_idle` and not
`run_forward`; any other combination keeps what it does.  After run: `spin_up` seconds later
is_idle falls and is_running rises, the torque climbs for `tighten` seconds, then
torque_reached rises, or nok when the NOK fault strikes (torque stays at 60 % of target).
After idle: `stop` seconds later is_running, torque_reached and nok fall and is_idle rises.

A nut tightens only against a bolt: while the tool is not `engaged` (no robot holds it down
on a bolt pair: the emulated scene says so, `hw.emulation.scene`) it spins freely and the
tightening starts over once it is.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from typing import Any, ClassVar

from hw.modbus.emulator.logic import DeviceLogic, Shots
from hw.modbus.maps import NUTRUNNER, NUTRUNNER_STATUS_BITS

NOK_TORQUE = 0.6  # share of the target torque where a NOK tightening stops


class Phase(enum.Enum):
    IDLE = "idle"
    STARTING = "starting"  # told to run, not spinning yet
    TIGHTENING = "tightening"
    DONE = "done"  # torque reached or NOK, still spinning
    STOPPING = "stopping"


class Nutrunner(DeviceLogic):
    register_map = NUTRUNNER
    timing_defaults: ClassVar[Mapping[str, float]] = {"spin_up": 0.5, "tighten": 2.0, "stop": 0.5}

    def __init__(self, now: float, timing: Mapping[str, float] | None = None) -> None:
        super().__init__(now, timing)
        self.phase = Phase.IDLE
        self.since = now  # when the phase began
        self.nok_fault = Shots()
        self.engaged = True  # on a bolt (the scene tells; alone, a nutrunner is on one)

    def advance(self, now: float) -> bool:
        run = bool(self["run_forward"]) and not self["set_idle"]
        idle = bool(self["set_idle"]) and not self["run_forward"]
        due = self.since + self.timing[_DELAY.get(self.phase, "stop")]
        if self.phase is Phase.IDLE and run:
            self._enter(Phase.STARTING, self.noticed())
        elif self.phase is Phase.STARTING and idle:
            self._enter(Phase.IDLE, self.noticed())  # it never spun up
        elif self.phase is Phase.STARTING and now >= due:
            self._enter(Phase.TIGHTENING, due)
            self.flag("is_idle", False)
            self.flag("is_running", True)
        elif self.phase in (Phase.TIGHTENING, Phase.DONE) and idle:
            self._enter(Phase.STOPPING, self.noticed())
        elif self.phase is Phase.TIGHTENING and not self.engaged:
            self.since = now  # spinning freely: the tightening has not begun
            self._torque(0.0)
            return False
        elif self.phase is Phase.TIGHTENING and now >= due:
            self._enter(Phase.DONE, due)
            failed = self.nok_fault.take()
            self._torque(NOK_TORQUE if failed else 1.0)
            self.flag("nok" if failed else "torque_reached", True)
        elif self.phase is Phase.STOPPING and now >= due:
            self._enter(Phase.IDLE, due)
            self._torque(0.0)
            for name, on in zip(NUTRUNNER_STATUS_BITS, (True, False, False, False), strict=True):
                self.flag(name, on)
        else:
            if self.phase is Phase.TIGHTENING:
                tighten = self.timing["tighten"]
                self._torque(min(1.0, (now - self.since) / tighten) if tighten else 1.0)
            return False
        return True

    def _enter(self, phase: Phase, at: float) -> None:
        self.phase, self.since = phase, at

    def _torque(self, share: float) -> None:
        target = self["target_torque"]
        self.put("torque", min(0xFFFF, math.floor(target * share)))

    def reset(self) -> None:
        super().reset()
        self.nok_fault = Shots()

    def faults(self) -> dict[str, Any]:
        return {
            **super().faults(),
            "nok": self.nok_fault.as_json(),
            "phase": self.phase.value,
            "engaged": self.engaged,
        }


_DELAY = {Phase.STARTING: "spin_up", Phase.TIGHTENING: "tighten", Phase.STOPPING: "stop"}
