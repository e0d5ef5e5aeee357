"""A robot arm's joints in motion: a pure, clock-free model advanced by `step(dt)`.

A move is synchronised like a UR `movej`: every joint starts and arrives together.  When a
target is set, each joint's speed and acceleration limits are the commanded ones scaled by its
share of the longest distance, so every joint runs the same trapezoid shape in the same time.
Each step a joint accelerates (within its acceleration limit) toward the fastest speed from
which it can still brake to its target in discrete steps of `dt`, capped at its speed limit;
it lands exactly on the target once it is slow enough to stop within one step.  The profile
holds for steps of one length only: a joint braked for short steps can pass its target in a
long one, so the emulated controller steps its arm at its own fixed period
(`Controller.step_arm`).  A new target interrupts the old one from the current velocity;
`stop(deceleration)` brakes every joint to rest where it is.  Nothing here reads a clock:
time is the `dt` passed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

Joints = tuple[float, ...]

ARRIVED = 1e-9
"""Radians within which a joint counts as on its target."""


def _brake_speed(distance: float, acceleration: float, dt: float) -> float:
    """The highest speed from which a joint stops within `distance` in steps of `dt`."""
    half = acceleration * dt / 2
    return -half + math.sqrt(half * half + 2 * acceleration * distance)


@dataclass
class Arm:
    """Joint positions `q` and velocities `qd`, and the move in progress if any."""

    q: list[float]
    qd: list[float] = field(default_factory=list)
    target: Joints | None = None
    speed: Joints = ()
    acceleration: Joints = ()
    braking: float = 0.0

    def __post_init__(self) -> None:
        if not self.qd:
            self.qd = [0.0] * len(self.q)

    @property
    def moving(self) -> bool:
        if any(v != 0.0 for v in self.qd):
            return True
        target = self.target
        return target is not None and any(
            abs(t - p) > ARRIVED for t, p in zip(target, self.q, strict=True)
        )

    @property
    def steady(self) -> bool:
        """At rest: no velocity and no move left to do."""
        return not self.moving

    def move_to(self, target: Sequence[float], speed: float, acceleration: float) -> None:
        """Starts a synchronised move to `target` with the given joint speed and acceleration."""
        if len(target) != len(self.q):
            raise ValueError(f"a target of {len(self.q)} joints, not {len(target)}")
        if not (speed > 0 and acceleration > 0):
            raise ValueError("speed and acceleration must be positive")
        if not all(math.isfinite(x) for x in target):
            raise ValueError("a target must be finite")
        distances = [abs(t - p) for t, p in zip(target, self.q, strict=True)]
        longest = max(distances, default=0.0)
        if longest > 0 and not any(self.qd):
            shares = [d / longest for d in distances]
        else:  # interrupting a move: every joint may use the full limits to turn around
            shares = [1.0] * len(distances)
        self.target = tuple(float(x) for x in target)
        self.speed = tuple(speed * s for s in shares)
        self.acceleration = tuple(acceleration * s for s in shares)
        self.braking = 0.0

    def stop(self, deceleration: float) -> None:
        """Drops the move and brakes every joint to rest with `deceleration` (rad/s²)."""
        if not deceleration > 0:
            raise ValueError("deceleration must be positive")
        self.target = None
        self.braking = deceleration

    def hold(self) -> None:
        """Stands still at once where it is (a protective stop, a hand that moved it)."""
        self.target = None
        self.braking = 0.0
        self.qd = [0.0] * len(self.q)

    def step(self, dt: float) -> None:
        """Advances the motion by `dt` seconds."""
        if dt <= 0:
            return
        if self.target is None:
            self._brake(dt)
            return
        for j, goal in enumerate(self.target):
            self._track(j, goal, dt)

    def _brake(self, dt: float) -> None:
        for j, v in enumerate(self.qd):
            if v == 0.0:
                continue
            slower = max(abs(v) - self.braking * dt, 0.0) if self.braking > 0 else 0.0
            new = math.copysign(slower, v)
            self.q[j] += new * dt
            self.qd[j] = new

    def _track(self, j: int, goal: float, dt: float) -> None:
        limit_v, limit_a = self.speed[j], self.acceleration[j]
        distance = goal - self.q[j]
        v = self.qd[j]
        step_a = limit_a * dt
        if abs(distance) <= ARRIVED and abs(v) <= step_a:
            self.q[j], self.qd[j] = goal, 0.0
            return
        landing = distance / dt  # the speed that lands on the goal in this step
        if abs(landing) <= min(limit_v, step_a) and abs(landing - v) <= step_a:
            self.q[j], self.qd[j] = goal, landing  # and brakes from ≤ a·dt next step
            return
        # the continuous braking curve overshoots discrete steps by at most a·dt²/8
        room = max(abs(distance) - limit_a * dt * dt / 8, 0.0)
        wanted = math.copysign(
            min(limit_v, _brake_speed(room, limit_a, dt), abs(distance) / dt), distance
        )
        new = v + max(-step_a, min(step_a, wanted - v))
        self.q[j] += new * dt
        self.qd[j] = new
