"""A robot's 3D camera (`r1_cam`, `r2_cam`): locates the hanging tool when triggered (the
model's `locate_tool`, seed 000 Figure 6, experiment E8).

The trigger is a level: when it is on and no result is shown, the camera scans (busy) for
`process` seconds, then shows a result: located with the tool's pose, or missed when the
miss fault strikes.  The result stays while the trigger stays on; `clear` seconds after the
trigger goes off the result is gone (located, missed and the pose back to 0).  The pose it
reports is the scene's (`Camera.scene`, set on the control channel), in the camera's frame.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from typing import Any, ClassVar

from hw.modbus.emulator.logic import DeviceLogic, Shots
from hw.modbus.maps import CAMERA, CAMERA_POSE

Pose = tuple[float, float, float, float, float, float]
DEFAULT_SCENE: Pose = (412.5, -120.0, 305.2, 0.0, 3.1416, 0.0)


class Phase(enum.Enum):
    READY = "ready"
    SCANNING = "scanning"
    SHOWING = "showing"  # a result, while the trigger stays on
    CLEARING = "clearing"


class Camera(DeviceLogic):
    register_map = CAMERA
    timing_defaults: ClassVar[Mapping[str, float]] = {"process": 0.8, "clear": 0.2}

    def __init__(self, now: float, timing: Mapping[str, float] | None = None) -> None:
        super().__init__(now, timing)
        self.phase = Phase.READY
        self.since = now
        self.miss_fault = Shots()
        self.scene: Pose = DEFAULT_SCENE

    def advance(self, now: float) -> bool:
        trigger = bool(self["trigger"])
        if self.phase is Phase.READY and trigger:
            self._enter(Phase.SCANNING, self.noticed())
            self.flag("busy", True)
        elif self.phase is Phase.SCANNING and not trigger:
            self._enter(Phase.READY, self.noticed())  # abandoned: no result
            self.flag("busy", False)
        elif self.phase is Phase.SCANNING and now >= self.since + self.timing["process"]:
            self._enter(Phase.SHOWING, self.since + self.timing["process"])
            missed = self.miss_fault.take()
            if not missed:
                self._show(self.scene)
            self.put("scans", (self.truth("scans") + 1) & 0xFFFF)
            self.flag("busy", False)
            self.flag("missed" if missed else "located", True)
        elif self.phase is Phase.SHOWING and not trigger:
            self._enter(Phase.CLEARING, self.noticed())
        elif self.phase is Phase.CLEARING and now >= self.since + self.timing["clear"]:
            self._enter(Phase.READY, self.since + self.timing["clear"])
            self._show((0.0,) * 6)
            self.flag("located", False)
            self.flag("missed", False)
        else:
            return False
        return True

    def _enter(self, phase: Phase, at: float) -> None:
        self.phase, self.since = phase, at

    def _show(self, pose: tuple[float, ...]) -> None:
        for name, value in zip(CAMERA_POSE, pose, strict=True):
            register = self.register_map[name]
            self.put(name, round(value / register.scale) & 0xFFFF)

    def see(self, pose: Pose) -> None:
        """Where the tool is, for the next scans (checked against the registers' range)."""
        for name, value in zip(CAMERA_POSE, pose, strict=True):
            low, high = self.register_map[name].range()
            if not low <= value <= high:
                raise ValueError(f"pose {name} {value} is outside {low:g}..{high:g}")
        self.scene = pose

    def reset(self) -> None:
        super().reset()
        self.miss_fault = Shots()

    def faults(self) -> dict[str, Any]:
        return {
            **super().faults(),
            "miss": self.miss_fault.as_json(),
            "scene": list(self.scene),
            "phase": self.phase.value,
        }
