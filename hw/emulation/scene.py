"""What ties the emulated devices together, as the physical world does.

Each emulator knows only its own device; in the station the devices act on each other: a
nutrunner tightens only when the robot carrying it holds it down on a bolt pair.  The scene
watches the robot emulators (their joints, through the control channel) and tells the
devices what that means for them (`engage` on a nutrunner whose device file lists the poses
where it bites, `emulation.engaged_at`).  It runs beside the emulators, in the process that
started them, never in the station's loop.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Mapping

from hw.device_file.spec import DeviceFile, DriverKind
from hw.emulator_kit.control import ControlError, control
from hw.pipelines import UNKNOWN, Nonsense

log = logging.getLogger(__name__)
PERIOD = 0.05


class Scene:
    def __init__(
        self, devices: DeviceFile, controls: Mapping[str, tuple[str, int]], period: float = PERIOD
    ) -> None:
        self.robots = [
            d for d in devices.devices if d.driver is DriverKind.UR and d.name in controls
        ]
        self.tools = [d for d in devices.devices if d.emulation.engaged_at and d.name in controls]
        self.controls = dict(controls)
        self.period = period
        self.engaged: dict[str, bool] = {}
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self._watch, name="emulated-scene", daemon=True)
        if self.tools:
            self.thread.start()

    def poses(self) -> dict[str, str]:
        """The named pose each robot's emulator stands at (`unknown` between poses)."""
        found = {}
        for robot in self.robots:
            assert robot.programs is not None
            try:
                joints = control(*self.controls[robot.name], {"op": "state"}, timeout=1.0)["joints"]
                found[robot.name] = robot.programs.poses.pose_of(joints)
            except (ControlError, KeyError, Nonsense):
                found[robot.name] = UNKNOWN
        return found

    def step(self) -> None:
        at = set(self.poses().values())
        for tool in self.tools:
            engaged = bool(at & set(tool.emulation.engaged_at))
            if self.engaged.get(tool.name) is engaged:
                continue
            try:
                control(
                    *self.controls[tool.name], {"op": "engage", "device": tool.name, "on": engaged}
                )
                self.engaged[tool.name] = engaged
            except ControlError as problem:
                log.warning("scene: %s could not be told: %s", tool.name, problem)

    def _watch(self) -> None:
        while not self.stopping.wait(self.period):
            self.step()

    def stop(self) -> None:
        self.stopping.set()
        if self.thread.is_alive():
            self.thread.join(timeout=2)
