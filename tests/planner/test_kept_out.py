"""What a resource stopped where it is keeps the others out of (`planner.model.kept_out`):
the demo's shared zone and hanging positions, a value forbidden anyway (not a consequence),
a specification that forbids nothing whatever else holds, and one too big to judge."""

from __future__ import annotations

import pytest

from planner.model import kept_out as module
from planner.model.expressions import And, BoolVar, Equals, Implies, Not, Or
from planner.model.flat import Model, Specification, Variable
from planner.model.kept_out import kept_out
from planner.reading import load_station
from tests.support.paths import REPOSITORY

POSES = ("home", "scan", "bp1", "hang")
ZONE = ("scan", "bp1")


def in_zone(robot: str) -> Or:
    return Or(tuple(Equals(f"{robot}.pos", p) for p in ZONE))


def model(*specs: Specification, extra: tuple[Variable, ...] = ()) -> Model:
    robots = tuple(Variable(f"{r}.pos", POSES, "home") for r in ("r1", "r2"))
    return Model(robots + extra, (), specs)


ONE_IN_ZONE = Specification("one_in_zone", Not(And((in_zone("r1"), in_zone("r2")))))


def test_a_robot_stopped_in_the_shared_zone_keeps_the_other_out_of_all_of_it() -> None:
    found = kept_out(model(ONE_IN_ZONE), {"r2.pos": "bp1"}, ["r1.pos"])
    assert found == {"r1.pos": ZONE}
    assert kept_out(model(ONE_IN_ZONE), {"r2.pos": "home"}, ["r1.pos"]) == {}


def test_a_value_forbidden_anyway_is_not_a_consequence_of_the_stop() -> None:
    never_hang = Specification("never_hang", Not(Equals("r1.pos", "hang")))
    found = kept_out(model(ONE_IN_ZONE, never_hang), {"r2.pos": "scan"}, ["r1.pos"])
    assert found == {"r1.pos": ZONE}  # not "hang": the stop is not why


def test_what_depends_on_other_variables_is_not_kept_out() -> None:
    """`r2 at bp1 and the nutrunner off -> r1 not at bp1`: the nutrunner may run, so robot 1
    is not kept out of bp1 by robot 2 alone."""
    running = Variable("nr.running", (False, True), False)
    spec = Specification(
        "runs_first",
        Implies(And((Equals("r2.pos", "bp1"), Not(BoolVar("nr.running")))), Not(in_zone("r1"))),
    )
    assert kept_out(model(spec, extra=(running,)), {"r2.pos": "bp1"}, ["r1.pos"]) == {}
    stopped = {"r2.pos": "bp1", "nr.running": False}  # both pinned: now it is kept out
    assert kept_out(model(spec, extra=(running,)), stopped, ["r1.pos"]) == {"r1.pos": ZONE}


def test_a_specification_with_too_many_assignments_is_not_judged(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    flags = tuple(Variable(f"f{k}", (False, True), False) for k in range(4))
    guard = And(tuple(Not(BoolVar(f.name)) for f in flags))
    spec = Specification("big", Implies(guard, Not(And((in_zone("r1"), in_zone("r2"))))))
    pinned = {"r2.pos": "scan", **{f.name: False for f in flags[:2]}}
    assert kept_out(model(spec, extra=flags), pinned, ["r1.pos"]) == {}  # f2, f3 free
    pinned = {"r2.pos": "scan", **{f.name: False for f in flags}}
    assert kept_out(model(spec, extra=flags), pinned, ["r1.pos"]) == {"r1.pos": ZONE}
    # whether it is forbidden anyway (r2.pos and the flags free: 64 assignments) is not
    # judged under a limit of 16: then nothing is claimed
    monkeypatch.setattr(module, "LIMIT", 16)
    assert kept_out(model(spec, extra=flags), pinned, ["r1.pos"]) == {}


def test_the_demo_robot_2_silent_above_the_engine_keeps_robot_1_out_of_the_zone() -> None:
    path = REPOSITORY / "models" / "demo_station.yaml"
    station = load_station(path.read_text(), str(path))
    initial = {v.name: v.initial for v in station.model.variables}
    r2 = {name: initial[name] for name in initial if name.startswith("r2.")}
    zone = ("scan", "frame", "bp1", "bp2", "bp3", "bp4", "oil_filters")
    found = kept_out(station.model, {**r2, "r2.pos": "scan"}, ["r1.pos"])
    assert set(found["r1.pos"]) == set(zone)
    found = kept_out(station.model, {**r2, "r2.pos": "nr_hang"}, ["r1.pos"])
    assert found == {"r1.pos": ("nr_hang",)}
    assert kept_out(station.model, {**r2, "r2.pos": "home"}, ["r1.pos"]) == {}
