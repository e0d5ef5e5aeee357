"""Pipelines between device readings and model variables (seed 001 section V), each on its
own: unit tests for the cases people name, properties for everything in between."""

from __future__ import annotations

import math
from itertools import pairwise

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hw.pipelines import (
    UNKNOWN,
    Heartbeat,
    MoveJ,
    NamedPoses,
    Nonsense,
    Pipe,
    PoseAndLast,
    RateLimit,
    RobotPrograms,
    SetPayload,
    SetTcp,
    Tool,
    bit,
    enumeration,
    track_move,
    track_pose,
)

# three poses of a six-joint robot, each joint at least 0.5 rad from the others' somewhere
POSES = NamedPoses(
    {
        "home": (0.0, -1.57, 1.57, -1.57, -1.57, 0.0),
        "scan": (0.5, -1.2, 1.2, -1.57, -1.57, 0.0),
        "bp1": (1.0, -0.9, 1.4, -2.0, -1.57, 0.3),
    },
    tolerance=0.02,
)
words = st.integers(min_value=0, max_value=0xFFFF)
offsets = st.lists(st.floats(-0.99, 0.99), min_size=6, max_size=6)  # inside, past rounding


@given(name=st.sampled_from(sorted(POSES.poses)), offset=offsets)
def test_a_reading_within_the_tolerance_of_a_pose_is_that_pose(
    name: str, offset: list[float]
) -> None:
    pose = POSES.poses[name]
    near = [j + o * POSES.tolerance for j, o in zip(pose, offset, strict=True)]
    assert POSES.pose_of(near) == name


@given(joints=st.lists(st.floats(-6.3, 6.3), min_size=6, max_size=6))
def test_a_reading_is_a_pose_exactly_when_every_joint_is_within_the_tolerance(
    joints: list[float],
) -> None:
    """Brute force against the definition: off every pose is `unknown`."""
    near = [
        n
        for n, pose in POSES.poses.items()
        if all(abs(a - b) <= POSES.tolerance for a, b in zip(joints, pose, strict=True))
    ]
    assert POSES.pose_of(joints) == (near[0] if near else UNKNOWN)


def test_between_poses_a_robot_is_unknown_and_keeps_its_last_pose() -> None:
    at_home = track_pose(POSES, POSES.poses["home"], PoseAndLast(UNKNOWN, "home"))
    assert at_home == PoseAndLast("home", "home")
    halfway = [(a + b) / 2 for a, b in zip(POSES.poses["home"], POSES.poses["scan"], strict=True)]
    moving = track_pose(POSES, halfway, at_home)
    assert moving == PoseAndLast(UNKNOWN, "home")
    arrived = track_pose(POSES, POSES.poses["scan"], moving)
    assert arrived == PoseAndLast("scan", "scan")


@given(
    path=st.lists(st.tuples(st.sampled_from(sorted(POSES.poses)), st.floats(0, 1)), max_size=8),
    target=st.sampled_from(sorted(POSES.poses)),
)
def test_on_a_commanded_move_the_robot_is_where_it_left_until_it_arrives(
    path: list[tuple[str, float]], target: str
) -> None:
    """Whatever the path crosses (other poses, nothing), `pos` and `last` change only on
    arrival at the target: a move's only effect is `arrive` (seed 003 Table IV)."""
    before = PoseAndLast("home", "home")
    for name, share in path:
        between = [
            a + share * (b - a) for a, b in zip(POSES.poses["home"], POSES.poses[name], strict=True)
        ]
        now = track_move(POSES, between, before, target)
        at_target = POSES.pose_of(between) == target
        assert now == (PoseAndLast(target, target) if at_target else before)
        before = now


def test_without_a_move_a_robot_off_every_pose_is_unknown() -> None:
    pushed = [j + 0.3 for j in POSES.poses["scan"]]
    assert track_move(POSES, pushed, PoseAndLast("scan", "scan"), None) == PoseAndLast(
        UNKNOWN, "scan"
    )


@pytest.mark.parametrize(
    "joints",
    [(0.0,) * 5, (0.0,) * 7, (math.nan, 0, 0, 0, 0, 0), (math.inf, 0, 0, 0, 0, 0)],
)
def test_a_joint_vector_that_cannot_be_is_nonsense(joints: tuple[float, ...]) -> None:
    with pytest.raises(Nonsense):
        POSES.pose_of(joints)


def test_named_poses_that_a_reading_could_confuse_are_refused() -> None:
    with pytest.raises(ValueError, match="within twice the tolerance"):
        NamedPoses({"a": (0.0, 0.0), "b": (0.0, 0.03)}, tolerance=0.02)
    with pytest.raises(ValueError, match="different lengths"):
        NamedPoses({"a": (0.0, 0.0), "b": (1.0,)})
    with pytest.raises(ValueError, match="positive"):
        NamedPoses({"a": (0.0,)}, tolerance=0.0)


@given(word=words)
def test_the_bits_of_a_register_make_up_its_word(word: int) -> None:
    assert sum(int(bit(k)(word)) << k for k in range(16)) == word


@pytest.mark.parametrize("word", [-1, 0x10000, True, 3.0, "1"])
def test_a_register_value_that_cannot_be_is_nonsense(word: object) -> None:
    with pytest.raises(Nonsense):
        bit(0)(word)  # type: ignore[arg-type]


def test_an_enumeration_knows_its_codes_and_refuses_the_rest() -> None:
    state = enumeration({0: "idle", 1: "running", 2: "torque", 3: "nok"})
    assert [state(code) for code in range(4)] == ["idle", "running", "torque", "nok"]
    with pytest.raises(Nonsense, match="code 7 is none of"):
        state(7)


@given(word=words)
def test_pipes_compose_left_to_right(word: int) -> None:
    running = bit(3).then(Pipe("as text", lambda on: "running" if on else "idle"))
    assert running(word) == ("running" if word & 8 else "idle")
    assert running.name == "bit 3 | as text"


@given(name=st.sampled_from(sorted(POSES.poses)))
def test_a_named_pose_commanded_is_the_pose_measured_when_the_robot_gets_there(
    name: str,
) -> None:
    programs = RobotPrograms(POSES)
    move = programs.goto(name)
    assert isinstance(move, MoveJ) and POSES.pose_of(move.joints) == name
    assert move.speed > 0 and move.acceleration > 0


def test_a_tool_becomes_set_tcp_and_set_payload() -> None:
    nutrunner = Tool((0.0, 0.0, 0.25, 0.0, 0.0, 0.0), 3.2, (0.0, 0.0, 0.1))
    programs = RobotPrograms(POSES, {"nr": nutrunner})
    assert programs.tool("nr") == (
        SetTcp((0.0, 0.0, 0.25, 0.0, 0.0, 0.0)),
        SetPayload(3.2, (0.0, 0.0, 0.1)),
    )
    with pytest.raises(KeyError, match="no tool 'oil_ee'"):
        programs.tool("oil_ee")
    with pytest.raises(KeyError, match="no named pose 'bp9'"):
        programs.goto("bp9")


@given(times=st.lists(st.floats(0, 100), min_size=1, max_size=50).map(sorted))
def test_commands_let_through_are_never_closer_than_the_interval(times: list[float]) -> None:
    limit = RateLimit(interval=0.5)
    sent = [t for t in times if limit.allows(t)]
    assert sent[0] == times[0]
    assert all(b - a >= 0.5 for a, b in pairwise(sent))
    # and a command was held back only within the interval after one that was sent
    assert all(any(s <= t < s + 0.5 for s in sent) for t in times)


def test_a_stream_whose_timestamps_stop_advancing_is_a_device_that_does_not_answer() -> None:
    beat = Heartbeat(timeout=0.5)
    assert not beat.alive(0.0)  # nothing heard yet
    for k in range(10):
        beat.saw(stamp=100.0 + k * 0.1, now=k * 0.1)
    assert beat.alive(0.95)
    for k in range(10, 20):
        beat.saw(stamp=100.9, now=k * 0.1)  # the controller froze: same data, again and again
    assert not beat.alive(1.5)
    beat.saw(stamp=101.0, now=1.6)  # it moves again
    assert beat.alive(1.6)
    with pytest.raises(Nonsense, match="went back"):
        beat.saw(stamp=50.0, now=1.7)
    with pytest.raises(Nonsense):
        beat.saw(stamp=math.nan, now=1.8)
