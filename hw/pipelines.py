"""Pipelines: from device readings to model variables and back (seed 001 section V).

A driver speaks its device's language (joint vectors in radians, Modbus registers); the
model speaks in finite domains (`r1.pos == scan`, `nr.torque_reached`).  The pipelines
between them are small typed functions that compose, so that each is tested on its own:

- measured: joint vectors to a named pose within a tolerance (`unknown` off every pose, the
  last named pose kept for `last`), register bits to booleans, register words to values of
  an enumeration;
- commanded: a named pose to a moveJ with its joint vector, a TCP name to set-TCP and
  set-payload;
- timing: a rate limit for commands, and heartbeats from the data's own timestamps (a
  device that keeps a connection open but sends stale data is not answering).

A reading no pipeline can explain (a value out of range, a word outside the enumeration, a
vector of the wrong length) raises `Nonsense`: the driver marks its device unavailable
instead of trusting it.  Nothing here does I/O or reads a clock: times come in as values.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from planner.model.expressions import Value

A = TypeVar("A")
B = TypeVar("B")
C = TypeVar("C")

UNKNOWN = "unknown"


class Nonsense(ValueError):
    """A reading that cannot be what the device says it is: the device is not trusted."""


@dataclass(frozen=True)
class Pipe(Generic[A, B]):
    """A named step from `A` to `B`; `then` composes steps into a pipeline."""

    name: str
    step: Callable[[A], B]

    def __call__(self, reading: A) -> B:
        return self.step(reading)

    def then(self, after: Pipe[B, C]) -> Pipe[A, C]:
        return Pipe(f"{self.name} | {after.name}", lambda reading: after(self(reading)))


Joints = tuple[float, ...]


@dataclass(frozen=True)
class NamedPoses:
    """Named joint poses of one robot, and how close (radians, per joint) counts as there."""

    poses: Mapping[str, Joints]
    tolerance: float = 0.01

    def __post_init__(self) -> None:
        sizes = {len(joints) for joints in self.poses.values()}
        if len(sizes) > 1:
            raise ValueError(f"named poses of different lengths: {sorted(sizes)}")
        if not self.tolerance > 0:
            raise ValueError(f"tolerance must be positive, not {self.tolerance}")
        names = sorted(self.poses)
        for k, first in enumerate(names):
            for second in names[k + 1 :]:
                if _distance(self.poses[first], self.poses[second]) <= 2 * self.tolerance:
                    raise ValueError(
                        f"poses '{first}' and '{second}' are within twice the tolerance: "
                        "a reading could be both"
                    )

    @property
    def size(self) -> int:
        return len(next(iter(self.poses.values()))) if self.poses else 0

    def pose_of(self, joints: Sequence[float]) -> str:
        """The named pose `joints` is at, or `unknown` when it is at none of them."""
        vector = checked_joints(joints, self.size)
        for name, pose in self.poses.items():
            if _distance(vector, pose) <= self.tolerance:
                return name
        return UNKNOWN

    def joints_of(self, name: str) -> Joints:
        if name not in self.poses:
            raise KeyError(f"no named pose '{name}'; known: {', '.join(sorted(self.poses))}")
        return self.poses[name]


def checked_joints(joints: Sequence[float], size: int) -> Joints:
    """A joint vector as floats; `Nonsense` for the wrong length, NaN or infinity."""
    if size and len(joints) != size:
        raise Nonsense(f"{len(joints)} joint values, expected {size}")
    vector = tuple(float(j) for j in joints)
    if not all(math.isfinite(j) for j in vector):
        raise Nonsense(f"joint values that are not numbers: {vector}")
    return vector


def _distance(a: Sequence[float], b: Sequence[float]) -> float:
    return max((abs(x - y) for x, y in zip(a, b, strict=True)), default=0.0)


@dataclass(frozen=True)
class PoseAndLast:
    """`pos` and `last` of a robot: the named pose it is at (or `unknown`), and the last
    named pose it was at, kept while it moves between poses (restart mode moves it back)."""

    pos: str
    last: str


def track_pose(poses: NamedPoses, joints: Sequence[float], before: PoseAndLast) -> PoseAndLast:
    pos = poses.pose_of(joints)
    return PoseAndLast(pos, before.last if pos == UNKNOWN else pos)


def track_move(
    poses: NamedPoses, joints: Sequence[float], before: PoseAndLast, target: str | None
) -> PoseAndLast:
    """`track_pose` for a robot that may be on a commanded move to `target`.

    In the model a move is under way while `pos != ref`, and `pos` becomes the target when it
    arrives (seed 003 Table IV).  So on the way the robot is still where it left, even when
    its path crosses another named pose (bp1 to bp4 passes bp2 and bp3) or no pose at all;
    only without a move under way is a robot off every pose `unknown` (pushed, stopped).
    """
    if target is None:
        return track_pose(poses, joints, before)
    if poses.pose_of(joints) == target:
        return PoseAndLast(target, target)
    return before


def bit(index: int) -> Pipe[int, bool]:
    """Bit `index` of a 16-bit register."""
    if not 0 <= index < 16:
        raise ValueError(f"bit {index} is not in a 16-bit register")

    def step(word: int) -> bool:
        return bool(checked_word(word) >> index & 1)

    return Pipe(f"bit {index}", step)


def checked_word(word: int) -> int:
    if isinstance(word, bool) or not isinstance(word, int) or not 0 <= word <= 0xFFFF:
        raise Nonsense(f"{word!r} is not a 16-bit register value")
    return word


def enumeration(values: Mapping[int, Value]) -> Pipe[int, Value]:
    """A register word that codes an enumeration: each known code to its value."""
    shown = ", ".join(f"{code}: {value}" for code, value in sorted(values.items()))

    def step(word: int) -> Value:
        code = checked_word(word)
        if code not in values:
            raise Nonsense(f"code {code} is none of {shown}")
        return values[code]

    return Pipe(f"enumeration {{{shown}}}", step)


@dataclass(frozen=True)
class MoveJ:
    joints: Joints
    speed: float
    acceleration: float


@dataclass(frozen=True)
class SetTcp:
    pose: tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class SetPayload:
    mass: float  # kg
    centre_of_gravity: tuple[float, float, float]


@dataclass(frozen=True)
class Tool:
    """What a robot carries: its TCP (x, y, z, rx, ry, rz) and its payload."""

    tcp: tuple[float, float, float, float, float, float]
    mass: float
    centre_of_gravity: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class RobotPrograms:
    """The model's command values of one robot (`ref`, `tcp`) as robot commands."""

    poses: NamedPoses
    tools: Mapping[str, Tool] = field(default_factory=dict)
    speed: float = 1.05  # rad/s, ur_rtde's default for moveJ
    acceleration: float = 1.4  # rad/s^2

    def goto(self, ref: str) -> MoveJ:
        return MoveJ(self.poses.joints_of(ref), self.speed, self.acceleration)

    def tool(self, tcp: str) -> tuple[SetTcp, SetPayload]:
        if tcp not in self.tools:
            raise KeyError(f"no tool '{tcp}'; known: {', '.join(sorted(self.tools))}")
        tool = self.tools[tcp]
        return SetTcp(tool.tcp), SetPayload(tool.mass, tool.centre_of_gravity)


@dataclass
class RateLimit:
    """At most one command per `interval` seconds (the caller keeps the newest one that had
    to wait, and offers it again)."""

    interval: float
    sent_at: float | None = None

    def allows(self, now: float) -> bool:
        if self.sent_at is not None and now - self.sent_at < self.interval:
            return False
        self.sent_at = now
        return True


@dataclass
class Heartbeat:
    """Does a device answer?  Judged by its data's own timestamps: a stream that keeps
    coming but no longer advances (a frozen controller) stops the heartbeat as surely as a
    cut cable.  A timestamp that goes backwards is nonsense."""

    timeout: float
    stamp: float | None = None  # the newest data timestamp seen
    advanced_at: float | None = None  # when (our clock) it last advanced

    def saw(self, stamp: float, now: float) -> None:
        if not math.isfinite(stamp):
            raise Nonsense(f"data timestamp {stamp!r}")
        if self.stamp is not None and stamp < self.stamp:
            raise Nonsense(f"data timestamp went back from {self.stamp} to {stamp}")
        if self.stamp is None or stamp > self.stamp:
            self.stamp, self.advanced_at = stamp, now

    def alive(self, now: float) -> bool:
        return self.advanced_at is not None and now - self.advanced_at <= self.timeout
