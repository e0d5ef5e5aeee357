"""The emulated arm's joint motion: limits kept, targets reached, stops obeyed."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hw.ur.emulator.arm import Arm

DT = 0.008
TOLERANCE = 1e-9

joint = st.floats(-6.0, 6.0, allow_nan=False)
joints = st.lists(joint, min_size=6, max_size=6)
speeds = st.floats(0.05, 3.14)
accelerations = st.floats(0.1, 40.0)


def run(arm: Arm, seconds: float) -> list[tuple[list[float], list[float]]]:
    trace = []
    for _ in range(round(seconds / DT)):
        arm.step(DT)
        trace.append((list(arm.q), list(arm.qd)))
    return trace


def limit_steps(start: list[float], goal: list[float], speed: float, acceleration: float) -> float:
    longest = max(abs(a - b) for a, b in zip(start, goal, strict=True))
    return longest / speed + speed / acceleration + 3 * DT


def test_a_move_arrives_exactly_and_the_arm_is_steady() -> None:
    arm = Arm([0.0] * 6)
    arm.move_to([1.0, -0.5, 0.2, 0.0, 0.0, 0.3], 1.0, 2.0)
    assert not arm.steady
    run(arm, 2.0)
    assert arm.q == [1.0, -0.5, 0.2, 0.0, 0.0, 0.3]
    assert arm.steady


def test_a_move_takes_the_trapezoid_time() -> None:
    arm = Arm([0.0] * 6)
    arm.move_to([1.0] + [0.0] * 5, 0.5, 1.0)  # 0.5 s up, 1.5 s cruise, 0.5 s down
    steps = 0
    while not arm.steady:
        arm.step(DT)
        steps += 1
    assert steps * DT == pytest.approx(2.5, abs=0.05)


def test_joints_are_synchronised() -> None:
    arm = Arm([0.0] * 6)
    arm.move_to([1.0, 0.5, 0, 0, 0, 0], 1.0, 2.0)
    for _ in range(50):
        arm.step(DT)
        assert arm.q[1] == pytest.approx(arm.q[0] / 2, abs=1e-6)


@settings(max_examples=150, deadline=None)
@given(joints, joints, speeds, accelerations)
def test_never_exceeds_limits_and_always_arrives(
    start: list[float], goal: list[float], speed: float, acceleration: float
) -> None:
    arm = Arm(list(start))
    arm.move_to(goal, speed, acceleration)
    previous = [0.0] * 6
    before = list(start)
    for q, qd in run(arm, limit_steps(start, goal, speed, acceleration)):
        for j in range(6):
            assert abs(qd[j]) <= speed + TOLERANCE
            assert abs(qd[j] - previous[j]) <= acceleration * DT + TOLERANCE
            assert abs(q[j] - before[j]) <= speed * DT + TOLERANCE
            lo, hi = sorted((start[j], goal[j]))
            assert lo - TOLERANCE <= q[j] <= hi + TOLERANCE  # never overshoots
        previous, before = qd, q
    assert arm.q == [float(g) for g in goal]
    assert arm.steady


@settings(max_examples=100, deadline=None)
@given(joints, joints, joints, speeds, accelerations, st.integers(1, 200))
def test_a_new_target_interrupts_within_limits(
    start: list[float],
    first: list[float],
    second: list[float],
    speed: float,
    acceleration: float,
    after: int,
) -> None:
    arm = Arm(list(start))
    arm.move_to(first, speed, acceleration)
    for _ in range(after):
        arm.step(DT)
    arm.move_to(second, speed, acceleration)
    previous = list(arm.qd)
    seconds = limit_steps(arm.q, second, speed, acceleration) + 2 * speed / acceleration
    for _, qd in run(arm, seconds):
        for j in range(6):
            assert abs(qd[j]) <= speed + TOLERANCE
            assert abs(qd[j] - previous[j]) <= acceleration * DT + TOLERANCE
        previous = qd
    assert arm.q == [float(g) for g in second]


@settings(max_examples=100, deadline=None)
@given(joints, joints, speeds, accelerations, st.floats(0.1, 40.0), st.integers(1, 300))
def test_stop_brakes_to_rest_with_the_deceleration(
    start: list[float],
    goal: list[float],
    speed: float,
    acceleration: float,
    deceleration: float,
    after: int,
) -> None:
    arm = Arm(list(start))
    arm.move_to(goal, speed, acceleration)
    for _ in range(after):
        arm.step(DT)
    arm.stop(deceleration)
    previous = list(arm.qd)
    for _, qd in run(arm, speed / deceleration + 2 * DT):
        for j in range(6):
            assert abs(qd[j]) <= abs(previous[j]) + TOLERANCE  # only slower
            assert abs(qd[j] - previous[j]) <= deceleration * DT + TOLERANCE
        previous = qd
    assert arm.steady
    held = list(arm.q)
    run(arm, 0.5)
    assert arm.q == held


def test_hold_stands_still_at_once() -> None:
    arm = Arm([0.0] * 6)
    arm.move_to([1.0] * 6, 1.0, 5.0)
    run(arm, 0.3)
    arm.hold()
    assert arm.steady
    held = list(arm.q)
    run(arm, 0.2)
    assert arm.q == held


@pytest.mark.parametrize(
    ("target", "speed", "acceleration"),
    [([0.0] * 5, 1.0, 1.0), ([0.0] * 6, 0.0, 1.0), ([0.0] * 6, 1.0, -1.0), ([math.nan] * 6, 1, 1)],
)
def test_a_bad_move_is_refused(target: list[float], speed: float, acceleration: float) -> None:
    with pytest.raises(ValueError):
        Arm([0.0] * 6).move_to(target, speed, acceleration)
