"""A UR robot behind the model's variables: joints to named poses, named poses to moveJ."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

from hw.adapter import AdapterReport, Driver
from hw.device_file.spec import DeviceSpec, RobotRole
from hw.link import LinkStatus
from hw.pipelines import UNKNOWN, Nonsense, PoseAndLast, RobotPrograms, track_move
from hw.ur.robot_state import cannot_move
from hw.ur.sample import URReading
from planner.model.expressions import Value


class RobotDriver(Driver, Protocol):
    """What a robot adapter needs of its driver (hw.ur.driver.URDriver)."""

    def latest(self) -> URReading | None: ...

    def move_j(self, q: tuple[float, ...], speed: float, acceleration: float) -> None: ...

    def set_tool(self, tcp: tuple[float, ...], payload_kg: float) -> None: ...

    def forget_move(self) -> None: ...


class RobotAdapter:
    """A UR robot: joints to named poses (`pose`, `last_pose`), named poses to moveJ
    (`move_to`), tool names to TCP and payload (`tool`)."""

    def __init__(self, spec: DeviceSpec, driver: RobotDriver, start: Mapping[str, Value]) -> None:
        assert spec.programs is not None
        self.spec = spec
        self.driver = driver
        self.programs: RobotPrograms = spec.programs
        self.roles = {w.role: w.variable for w in spec.wires if w.role is not None}
        pos = str(start.get(self.roles.get(RobotRole.POSE, ""), UNKNOWN))
        last = str(start.get(self.roles.get(RobotRole.LAST_POSE, ""), pos))
        self.pose = PoseAndLast(pos, last)
        self.target: str | None = None  # the named pose a commanded move is heading for
        # a move the robot stopped (a protective stop, power): sent again only when the
        # robot can move, in the first write after the runner saw that (its tick replanned
        # and still commands it), never while it cannot
        self.interrupted: str | None = None
        self.can_move = False
        self.sent: dict[RobotRole, Value] = {}
        self.nonsense = ""
        self.not_before = 0.0  # readings older than this are from before a restart

    def restart(self, start: Mapping[str, Value], now: float) -> None:
        """The world was put back to `start` at `now` (time.monotonic()): forget the rest."""
        pos = str(start.get(self.roles.get(RobotRole.POSE, ""), UNKNOWN))
        self.pose = PoseAndLast(pos, str(start.get(self.roles.get(RobotRole.LAST_POSE, ""), pos)))
        self.target, self.sent, self.not_before = None, {}, now
        self.interrupted = None

    def start(self) -> None:
        self.driver.start()

    def close(self) -> None:
        self.driver.close()

    def read(self) -> AdapterReport:
        sample = self.driver.latest()
        if sample is None or not self.driver.available or sample.received < self.not_before:
            return AdapterReport()
        if self.target is not None and (sample.protective_stop or not sample.running):
            # the move was aborted: wherever it stopped is where it is
            self.interrupted, self.target = self.target, None
        try:
            self.pose = track_move(self.programs.poses, sample.q, self.pose, self.target)
        except Nonsense as problem:
            self.nonsense = f"nonsense from the robot: {problem}"
            return AdapterReport()
        self.nonsense = ""
        if self.pose.pos == self.target:
            self.target = None
        measured: dict[str, Value] = {}
        if RobotRole.POSE in self.roles:
            measured[self.roles[RobotRole.POSE]] = self.pose.pos
        if RobotRole.LAST_POSE in self.roles:
            measured[self.roles[RobotRole.LAST_POSE]] = self.pose.last
        resource = self.spec.resource or self.spec.name
        why = cannot_move(resource, sample)
        self.can_move = not why
        return AdapterReport(measured, alive=True, cannot_act=why)

    def write(self, commands: Mapping[str, Value]) -> None:
        for role in (RobotRole.TOOL, RobotRole.MOVE_TO):
            name = self.roles.get(role)
            if name is None or name not in commands:
                continue
            value = commands[name]
            first = role not in self.sent
            if role is RobotRole.MOVE_TO and self._resumes(value):
                self.driver.forget_move()  # the driver sends a move only when it changed
            elif not first and self.sent[role] == value:
                continue
            self.sent[role] = value
            if role is RobotRole.TOOL and str(value) in self.programs.tools:
                tcp, payload = self.programs.tool(str(value))
                self.driver.set_tool(tcp.pose, payload.mass)
            elif (
                role is RobotRole.MOVE_TO and not first and str(value) in self.programs.poses.poses
            ):
                # the first value is where the runner believes the robot is: no move
                move = self.programs.goto(str(value))
                self.target = str(value)
                self.driver.move_j(move.joints, move.speed, move.acceleration)

    def _resumes(self, value: Value) -> bool:
        """Whether to send the interrupted move again: the robot can move (the runner's tick
        saw that before this write) and the runner still commands that pose."""
        if self.interrupted is None or not self.can_move:
            return False
        resume = value == self.interrupted and self.pose.pos != value
        self.interrupted = None
        return resume

    def status(self) -> LinkStatus:
        status = self.driver.status()
        if self.nonsense:
            return LinkStatus(
                False, status.latency_ms, status.last_data, self.nonsense, status.restarts
            )
        return status
