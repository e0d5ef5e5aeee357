"""A robot's tool-changer connector (`r1_tc`, `r2_tc`): locks onto a tool and lets it go
(the model's `lock` and `unlock`, seed 003 Table III).

Commands are levels: lock = `lock` and not `unlock`; unlock = `unlock` and not `lock`; any
other combination keeps what it does.  `lock` seconds after a lock command the connected
sensor rises and not_connected falls together; `unlock` seconds after an unlock command
they swap back.  Faults: a lock that never completes, a release that never completes, a
lock that ends with the failure bit (which blocks locking until a reset: the `reset` coil
rising, or the control channel's reset), and any sensor stuck at a value
(`DeviceLogic.stick`).
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from typing import Any, ClassVar

from hw.modbus.emulator.logic import DeviceLogic, Shots
from hw.modbus.maps import CONNECTOR


class Phase(enum.Enum):
    UNLOCKED = "unlocked"
    LOCKING = "locking"
    LOCKED = "locked"
    UNLOCKING = "unlocking"


class LockFault(enum.Enum):
    NEVER = "never"  # the lock never completes: no sensor changes, no failure
    FAILURE = "failure"  # the lock ends with the failure bit, still not connected


class Connector(DeviceLogic):
    register_map = CONNECTOR
    timing_defaults: ClassVar[Mapping[str, float]] = {"lock": 1.0, "unlock": 1.0}

    def __init__(self, now: float, timing: Mapping[str, float] | None = None) -> None:
        super().__init__(now, timing)
        self.phase = Phase.UNLOCKED
        self.since = now
        self.lock_fault = Shots()
        self.lock_fault_mode = LockFault.NEVER
        self.doomed: LockFault | None = None  # how the current lock attempt ends, if it fails
        self.unlock_fault = Shots()
        self.stuck_on = False  # the current release never completes
        self._reset_coil = False

    def advance(self, now: float) -> bool:
        if self["reset"] and not self._reset_coil and self.truth("failure"):
            self.flag("failure", False)
        self._reset_coil = bool(self["reset"])
        lock = bool(self["lock"]) and not self["unlock"]
        unlock = bool(self["unlock"]) and not self["lock"]
        if self.phase is Phase.UNLOCKED and lock and not self.truth("failure"):
            self._enter(Phase.LOCKING, self.noticed())
            self.doomed = self.lock_fault_mode if self.lock_fault.take() else None
        elif self.phase is Phase.LOCKING and unlock:
            self._enter(Phase.UNLOCKED, self.noticed())  # the sensors never changed
        elif self.phase is Phase.LOCKING and now >= self.since + self.timing["lock"]:
            due = self.since + self.timing["lock"]
            if self.doomed is LockFault.NEVER:
                return False
            if self.doomed is LockFault.FAILURE:
                self._enter(Phase.UNLOCKED, due)
                self.flag("failure", True)
            else:
                self._enter(Phase.LOCKED, due)
                self.flag("connected", True)
                self.flag("not_connected", False)
        elif self.phase is Phase.LOCKED and unlock:
            self._enter(Phase.UNLOCKING, self.noticed())
            self.stuck_on = self.unlock_fault.take()
        elif self.phase is Phase.UNLOCKING and lock:
            self._enter(Phase.LOCKED, self.noticed())  # still locked on
        elif self.phase is Phase.UNLOCKING and now >= self.since + self.timing["unlock"]:
            if self.stuck_on:
                return False
            self._enter(Phase.UNLOCKED, self.since + self.timing["unlock"])
            self.flag("connected", False)
            self.flag("not_connected", True)
        else:
            return False
        return True

    def _enter(self, phase: Phase, at: float) -> None:
        self.phase, self.since = phase, at

    def fail_locks(self, shots: Shots, mode: LockFault) -> None:
        """The next locks (or all) fail as `mode` says; no more (`times` 0) ends the fault,
        and a lock hanging on it then completes."""
        self.lock_fault, self.lock_fault_mode = shots, mode
        if not (shots.always or shots.times) and self.doomed is LockFault.NEVER:
            self.doomed = None

    def fail_unlocks(self, shots: Shots) -> None:
        """The next releases (or all) never complete; no more ends the fault, and a release
        hanging on it then completes."""
        self.unlock_fault = shots
        if not (shots.always or shots.times):
            self.stuck_on = False

    def reset(self) -> None:
        """Clears the faults and the failure bit; a lock that hung goes on."""
        super().reset()
        self.lock_fault = Shots()
        self.doomed = None
        self.unlock_fault = Shots()
        self.stuck_on = False
        self.flag("failure", False)

    def faults(self) -> dict[str, Any]:
        return {
            **super().faults(),
            "lock_fails": {**self.lock_fault.as_json(), "mode": self.lock_fault_mode.value},
            "unlock_fails": self.unlock_fault.as_json(),
            "phase": self.phase.value,
        }
