"""The `sp` command's contract (DESIGN.md section 8), through a real subprocess."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.paths import MINI_STATION, REPOSITORY

EXAMPLE = REPOSITORY / "models" / "examples" / "bolt_and_nutrunner.yaml"


def sp(*args: str) -> subprocess.CompletedProcess[str]:
    command = shutil.which("sp")
    prefix = [command] if command else [sys.executable, "-m", "app.cli.main"]
    return subprocess.run([*prefix, *args], capture_output=True, text=True, timeout=60)


def test_plan_found_prints_exactly_the_contract_json() -> None:
    result = sp("plan", str(EXAMPLE), "--goal", "r1.pos == bp1", "--json")
    assert result.returncode == 0, result.stderr
    answer = json.loads(result.stdout)
    assert list(answer) == ["status", "length", "plan", "millis"]
    assert answer["status"] == "found"
    # the supervisor guard makes the nutrunner run before the robot may head for the bolt
    assert answer["plan"] == ["nr.start", "nr.spin_up", "r1.goto_bp1", "r1.arrive"]
    assert answer["length"] == 4
    assert isinstance(answer["millis"], float) and answer["millis"] > 0


def test_unreachable_within_max_steps(tmp_path: Path) -> None:
    result = sp("plan", str(EXAMPLE), "--goal", "r1.pos == bp1", "--max-steps", "3", "--json")
    assert result.returncode == 1
    answer = json.loads(result.stdout)
    assert list(answer) == ["status", "max_steps", "millis"]
    assert answer["status"] == "unreachable" and answer["max_steps"] == 3


def test_bad_start_names_the_violated_specifications(tmp_path: Path) -> None:
    state = tmp_path / "state.json"
    state.write_text(
        json.dumps({"r1.pos": "bp1", "r1.ref": "bp1", "nr.running": False, "nr.run": False})
    )
    result = sp("plan", str(EXAMPLE), "--goal", "r1.pos == home", "--state", str(state), "--json")
    assert result.returncode == 1
    assert json.loads(result.stdout) == {
        "status": "bad_start",
        "violated": ["nutrunner_runs_at_bolt"],
    }


def test_plan_from_a_given_state(tmp_path: Path) -> None:
    state = tmp_path / "state.json"
    state.write_text(
        json.dumps({"r1.pos": "home", "r1.ref": "home", "nr.running": True, "nr.run": True})
    )
    result = sp("plan", str(EXAMPLE), "--goal", "r1.pos == bp1", "--state", str(state), "--json")
    assert result.returncode == 0
    assert json.loads(result.stdout)["plan"] == ["r1.goto_bp1", "r1.arrive"]


def test_human_readable_plan() -> None:
    result = sp("plan", str(EXAMPLE), "--goal", "r1.pos == bp1")
    assert result.returncode == 0
    assert result.stdout.startswith("found a plan of 4 steps")
    assert "   4. r1.arrive" in result.stdout


@pytest.mark.parametrize(
    ("goal", "location", "problem"),
    [
        ("r1.pos == bp9", "--goal:1:11:", "'bp9' is not a value of 'r1.pos'"),
        ("r1.poss == bp1", "--goal:1:1:", "did you mean 'r1.pos'?"),
        ("r1.pos == (", "--goal:1:11:", "expected a value or variable"),
    ],
)
def test_bad_goal_exits_2_with_a_located_message(goal: str, location: str, problem: str) -> None:
    result = sp("plan", str(EXAMPLE), "--goal", goal, "--json")
    assert result.returncode == 2
    assert result.stdout == ""
    assert location in result.stderr and problem in result.stderr


def test_invalid_model_exits_2_naming_file_line_column(tmp_path: Path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text(EXAMPLE.read_text().replace("r1.ref := bp1", "r1.ref := bp2"))
    for command in (["plan", str(broken), "--goal", "true"], ["check", str(broken)]):
        result = sp(*command)
        assert result.returncode == 2
        assert f"{broken}:9:" in result.stderr
        assert "'bp2' is not a value of 'r1.ref'" in result.stderr
        assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        ('{"r1.pos": "home"', "invalid JSON"),
        ('{"r1.pos": "home"}', "missing: r1.ref, nr.running, nr.run"),
        (
            '{"r1.pos": "moon", "r1.ref": "home", "nr.running": false, "nr.run": false}',
            "value \"moon\" of 'r1.pos' is outside its domain [home, tool, bp1]",
        ),
        (
            '{"r1.poz": "home", "r1.ref": "home", "nr.running": false, "nr.run": false}',
            "unknown variable 'r1.poz' (did you mean 'r1.pos'?)",
        ),
    ],
)
def test_bad_state_file_exits_2(tmp_path: Path, content: str, problem: str) -> None:
    state = tmp_path / "state.json"
    state.write_text(content)
    result = sp("plan", str(EXAMPLE), "--goal", "true", "--state", str(state))
    assert result.returncode == 2
    assert str(state) in result.stderr and problem in result.stderr


def test_bad_arguments_exit_2() -> None:
    assert sp("plan", str(EXAMPLE)).returncode == 2  # no --goal
    assert sp("plan", str(EXAMPLE), "--goal", "true", "--max-steps", "-1").returncode == 2
    missing = sp("plan", "no/such/model.yaml", "--goal", "true")
    assert missing.returncode == 2 and "cannot read the model" in missing.stderr


def test_check_prints_the_size_and_the_added_guards() -> None:
    result = sp("check", str(EXAMPLE))
    assert result.returncode == 0
    assert "variables: 4 (2 measured, 2 command)" in result.stdout
    assert "flattened boolean variables: 6" in result.stdout
    assert "transitions: 5 (3 controlled, 0 automatic, 2 effect, 0 maintenance)" in result.stdout
    assert "specifications: 1" in result.stdout
    assert "r1.goto_bp1: nr.running" in result.stdout
    report = json.loads(sp("check", str(EXAMPLE), "--json").stdout)
    assert report["bad_states"] == 10
    assert [g["transition"] for g in report["supervisor_guards"]] == ["r1.goto_bp1"]
    assert "reachable_states" not in report  # exploring every state is asked for
    counted = json.loads(sp("check", str(EXAMPLE), "--json", "--reachable").stdout)
    assert 0 < counted["reachable_states"] <= counted["states"] - counted["bad_states"]


def test_both_engines_give_the_same_minimal_length() -> None:
    lengths = {
        engine: json.loads(
            sp(
                "plan",
                str(EXAMPLE),
                "--goal",
                "r1.pos == bp1 && r1.ref == home",
                "--engine",
                engine,
                "--json",
            ).stdout
        )["length"]
        for engine in ("bdd", "sat")
    }
    assert lengths == {"bdd": 5, "sat": 5}


def test_restart_abilities_only_in_restart_mode(tmp_path: Path) -> None:
    station = MINI_STATION
    state = tmp_path / "state.json"
    state.write_text(
        json.dumps(
            {
                "bp1.state": "placed",
                "nr.run": False,
                "nr.running": True,
                "nr.torque": False,
                "r1.ref": "bp1",
                "r1.pos": "bp1",
            }
        )
    )
    args = ["plan", str(station), "--goal", "r1.pos == home", "--state", str(state), "--json"]
    normal = json.loads(sp(*args).stdout)
    restart = json.loads(sp(*args, "--restart").stdout)
    assert normal["plan"] == ["nr.run_nut.spin_down", "r1.goto_home", "r1.goto.arrive"]
    assert restart["plan"] == ["r1.back_home", "r1.goto.arrive"]


DEMO = REPOSITORY / "models" / "demo_station.yaml"
SCENARIOS = sorted((DEMO.parent / "scenarios").glob("e*.yaml"))


def test_run_plays_each_table_1_experiment_to_the_end() -> None:
    assert len(SCENARIOS) == 9
    for scenario in SCENARIOS:
        done = sp("run", str(DEMO), "--scenario", str(scenario), "--speed", "0", "--json")
        assert done.returncode == 0, (scenario.name, done.stderr[-2000:])
        events = [json.loads(line) for line in done.stdout.splitlines()]
        assert any(e["kind"] == "fault" for e in events)
        assert events[-1]["kind"] == "done", (scenario.name, events[-5:])
        plans = [e for e in events if e["kind"] == "plan"]
        assert plans and all("millis" in e for e in plans)  # planning is timed in the log


def test_run_with_a_bad_scenario_exits_2_naming_file_line_column(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("intentions: [tighten_bolts]\nfaults:\n  - {at: soon, kind: set}\n")
    done = sp("run", str(DEMO), "--scenario", str(bad), "--speed", "0")
    assert done.returncode == 2
    assert f"{bad}:3:10: faults[0].at: 'soon' is not a number" in done.stderr


def test_run_refuses_device_faults_without_devices_and_speed_with_them(tmp_path: Path) -> None:
    stop = tmp_path / "stop.yaml"
    stop.write_text("faults:\n  - {at: 1, kind: protective_stop, resource: r1}\n")
    done = sp("run", str(DEMO), "--scenario", str(stop), "--speed", "0")
    assert done.returncode == 2
    assert f"{stop}:2:19: faults[0].kind: 'protective_stop' is a device-level fault" in done.stderr
    devices = DEMO.parent / "demo_station.devices.yaml"
    done = sp("run", str(DEMO), "--devices", str(devices), "--speed", "0")
    assert done.returncode == 2
    assert "--speed: emulated devices run in real time" in done.stderr
