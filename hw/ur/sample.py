"""What the station learns from a UR robot each time: `URReading`, and when to distrust it.

`reading_from` turns the raw values the driver's child process sends into a `URReading`, or
raises `hw.pipelines.Nonsense` for values no robot could report (a joint vector of the wrong
length, NaN or infinity, a joint beyond its ±2 turns, a mode outside its enumeration).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from hw.pipelines import Nonsense

JOINT_LIMIT = 2 * math.tau
"""A UR joint turns at most ±360° (±2π); beyond twice that a reading is absurd."""
ROBOT_MODES = range(-1, 9)
RUNTIME_STATES = range(0, 6)
SAFETY_BITS = 1 << 11
PROTECTIVE_STOP_BIT = 1 << 2
RUNNING = 7
PLAYING = 2
STEADY_SPEED = 1e-4
"""rad/s below which every joint counts as standing still."""


@dataclass(frozen=True, slots=True)
class URReading:
    """One sample of the robot.

    `stamp`: the controller's own timestamp (s since it booted); `received`: the station's
    `time.monotonic()` when the sample arrived; `q`: joint positions (rad); `robot_mode`,
    `safety_bits` (`safety_status_bits`), `runtime_state`: as RTDE reports them.
    """

    stamp: float
    received: float
    q: tuple[float, ...]
    robot_mode: int
    safety_bits: int
    runtime_state: int
    protective_stop: bool
    steady: bool

    @property
    def running(self) -> bool:
        """Powered, brakes released and the control script playing: commands can work."""
        return self.robot_mode == RUNNING and self.runtime_state == PLAYING


def _number(raw: Mapping[str, Any], name: str) -> float:
    value = raw.get(name)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise Nonsense(f"{name} is not a number: {value!r}")
    if not math.isfinite(value):
        raise Nonsense(f"{name} is not finite: {value}")
    return float(value)


def _integer(raw: Mapping[str, Any], name: str, allowed: range) -> int:
    value = _number(raw, name)
    if value != int(value) or int(value) not in allowed:
        raise Nonsense(f"{name} {value} is outside {allowed.start}..{allowed.stop - 1}")
    return int(value)


def _joints(raw: Mapping[str, Any], name: str) -> tuple[float, ...]:
    values = raw.get(name)
    if not isinstance(values, list | tuple) or len(values) != 6:
        size = len(values) if isinstance(values, list | tuple) else "no"
        raise Nonsense(f"{name} has {size} values, not 6")
    joints = tuple(_number({"joint": v}, "joint") for v in values)
    if any(abs(q) > JOINT_LIMIT for q in joints):
        raise Nonsense(f"{name} {joints} is beyond any UR joint's range")
    return joints


def reading_from(raw: Mapping[str, Any], received: float) -> URReading:
    """A trusted reading from the child's raw sample, or `Nonsense`."""
    stamp = _number(raw, "stamp")
    if stamp < 0:
        raise Nonsense(f"controller timestamp {stamp} is negative")
    q = _joints(raw, "q")
    qd = _joints(raw, "qd")
    safety_bits = _integer(raw, "safety_bits", range(SAFETY_BITS))
    return URReading(
        stamp=stamp,
        received=received,
        q=q,
        robot_mode=_integer(raw, "robot_mode", ROBOT_MODES),
        safety_bits=safety_bits,
        runtime_state=_integer(raw, "runtime_state", RUNTIME_STATES),
        protective_stop=bool(safety_bits & PROTECTIVE_STOP_BIT),
        steady=all(abs(v) < STEADY_SPEED for v in qd),
    )
