"""Why a robot that answers cannot move, for every RTDE state the emulator cannot show
(emergency and safeguard stops, safety faults, backdrive, a paused program): the most
urgent cause is named, with what a person does; a running, playing robot has none."""

from __future__ import annotations

import pytest

from hw.ur.robot_state import Mode, Runtime, Safety, cannot_move
from hw.ur.sample import PROTECTIVE_STOP_BIT, URReading


def reading(
    mode: int = Mode.RUNNING, safety: tuple[int, ...] = (), runtime: int = Runtime.PLAYING
) -> URReading:
    bits = sum(1 << b for b in safety) | 1  # bit 0: normal mode
    return URReading(
        stamp=1.0,
        received=1.0,
        q=(0.0,) * 6,
        robot_mode=mode,
        safety_bits=bits,
        runtime_state=runtime,
        protective_stop=bool(bits & PROTECTIVE_STOP_BIT),
        steady=True,
    )


@pytest.mark.parametrize(
    ("sample", "says"),
    [
        (reading(safety=(Safety.EMERGENCY_STOPPED,)), "emergency-stopped: release"),
        (reading(safety=(Safety.ROBOT_EMERGENCY_STOPPED,)), "emergency-stopped"),
        (reading(safety=(Safety.SAFEGUARD_STOPPED,)), "safeguard-stopped: close its guard"),
        (reading(safety=(Safety.FAULT,)), "safety fault: clear it on r2's teach pendant"),
        (reading(safety=(Safety.PROTECTIVE_STOPPED,)), "protective stop: release it"),
        (reading(mode=Mode.POWER_OFF, runtime=Runtime.STOPPED), "has no power"),
        (reading(mode=Mode.BOOTING, runtime=Runtime.STOPPED), "has no power"),
        (reading(mode=Mode.IDLE, runtime=Runtime.STOPPED), "brakes are on"),
        (reading(mode=Mode.BACKDRIVE), "backdrive"),
        (reading(runtime=Runtime.PAUSED), "program is paused: the station starts it again"),
        (reading(runtime=Runtime.STOPPED), "program is stopped"),
        # the most urgent first: an emergency stop of a robot that is also without power
        (
            reading(
                mode=Mode.POWER_OFF,
                safety=(Safety.EMERGENCY_STOPPED, Safety.PROTECTIVE_STOPPED),
                runtime=Runtime.STOPPED,
            ),
            "emergency-stopped",
        ),
    ],
)
def test_each_cause_is_named_with_what_a_person_does(sample: URReading, says: str) -> None:
    text = cannot_move("r2", sample)
    assert text.startswith("r2") and says in text, text


def test_a_running_playing_robot_can_move() -> None:
    assert cannot_move("r2", reading()) == ""
    assert cannot_move("r2", reading(safety=(1,))) == ""  # reduced mode still moves
