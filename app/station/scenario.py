"""Scenarios as data, and the headless station loop that plays them (`sp run`).

A scenario is a YAML file: the start state, the intentions to run, runner settings, device
delays, faults injected at given times or when a condition first holds, and how the
simulated operator answers (approvals, maintenance work).  `play` runs the runner against the
simulated world on a virtual clock and yields every event as it happens.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import yaml

from app.station.cycle import ScheduledAction, ScheduledFault
from app.station.scenario_faults import read_faults
from app.station.scenario_fields import (
    Path,
    Problem,
    after_of,
    known,
    mapping,
    number,
    sequence,
    when_of,
)
from planner.model.expressions import Value
from planner.model.station import Station
from planner.reading.yaml_reader import scope_for
from planner.runner import (
    Action,
    Approve,
    CancelIntention,
    EnterRestart,
    LeaveRestart,
    MaintenanceDone,
    ReenableEffect,
    Reject,
    ResetOperation,
    RunnerConfig,
    SetEstimated,
    StartIntention,
)

_KEYS = (
    "description",
    "start",
    "intentions",
    "config",
    "delays",
    "faults",
    "actions",
    "operator",
    "until",
    "expect",
    "planning",
)
_CONFIG_KEYS = (
    "effect_timeout",
    "effect_timeouts",
    "heartbeat_timeout",
    "reminder",
    "retries",
    "recheck_period",
    "max_steps",
    "sequential",
)
# what people do at given times: (action, the keys it takes besides at/when/do/user)
_ACTIONS: dict[str, tuple[type[Action], tuple[str, ...]]] = {
    "start_intention": (StartIntention, ("name",)),
    "cancel_intention": (CancelIntention, ("name",)),
    "approve": (Approve, ("step",)),
    "reject": (Reject, ("step",)),
    "maintenance_done": (MaintenanceDone, ("transition",)),
    "enter_restart": (EnterRestart, ("reason",)),
    "leave_restart": (LeaveRestart, ()),
    "set_estimated": (SetEstimated, ("variable", "value", "reason")),
    "reset_operation": (ResetOperation, ("name",)),
    "reenable_effect": (ReenableEffect, ("name",)),
}


class ScenarioError(Exception):
    """A scenario file that cannot be used; the message names the file and the entry."""


@dataclass(frozen=True)
class Scenario:
    file: str
    description: str = ""
    start: Mapping[str, Value] = field(default_factory=dict)
    intentions: tuple[str, ...] | None = None
    config: RunnerConfig = field(default_factory=RunnerConfig)
    delays: Mapping[str, float] = field(default_factory=dict)
    default_delay: float = 1.0
    faults: tuple[ScheduledFault, ...] = ()
    actions: tuple[ScheduledAction, ...] = ()
    operator_delay: float = 2.0
    approve: bool = True
    maintenance: bool = True
    rejects: int = 0  # the operator rejects the first this many recovery steps asked of it
    until: float = 900.0
    expect: Mapping[str, Any] = field(default_factory=dict)
    # every planning query takes this many simulated seconds (0: answered at once), and one
    # past the budget is answered over budget, as the live station's worker does
    planning_delay: float = 0.0
    planning_budget: float = 10.0

    @property
    def started(self) -> tuple[str, ...]:
        """The intentions the scenario runs: those that start by themselves (all, when it
        does not say) and those its people start."""
        by_people = [a.action.name for a in self.actions if isinstance(a.action, StartIntention)]
        return tuple(dict.fromkeys([*(self.intentions or ()), *by_people]))


def load_scenario(text: str, file: str, station: Station, *, devices: bool = False) -> Scenario:
    """Read a scenario; a problem is reported as `file:line:column: entry: what is wrong`.

    `devices`: it is played on emulated devices, where device-level faults (a protective
    stop, a power cycle, ...) can be played; without, such a fault is a located error."""
    try:
        root = yaml.compose(text)
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{file}:{mark.line + 1}:{mark.column + 1}" if mark is not None else file
        problem = getattr(exc, "problem", None) or str(exc)
        raise ScenarioError(f"{where}: not valid YAML: {problem}") from None
    try:
        return _read(data, file, station, devices)
    except Problem as problem:
        line, column = _locate(root, problem.path)
        entry = "".join(
            f"[{p}]" if isinstance(p, int) or "." in p else f".{p}" for p in problem.path
        )
        raise ScenarioError(
            f"{file}:{line}:{column}: {entry.lstrip('.') or 'scenario'}: {problem.text}"
        ) from None


def _locate(node: yaml.Node | None, path: Path) -> tuple[int, int]:
    """Line and column (1-based) of the deepest node along `path` that exists."""
    if node is None:
        return 1, 1
    for step in path:
        child = None
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                if key.value == step:
                    child = value
                    break
        elif isinstance(node, yaml.SequenceNode) and isinstance(step, int) and step >= 0:
            child = node.value[step] if step < len(node.value) else None
        if child is None:
            break
        node = child
    return node.start_mark.line + 1, node.start_mark.column + 1


def _read(data: Any, file: str, station: Station, devices: bool = False) -> Scenario:
    if not isinstance(data, dict):
        raise Problem((), f"a scenario is a mapping with keys {', '.join(_KEYS)}")
    known((), "scenario", data, _KEYS)
    start = _read_start(data.get("start"), station)
    intentions = _read_intentions(data.get("intentions"), station)
    config = _read_config(data.get("config"), station, intentions)
    delays, default_delay = _read_delays(data.get("delays"), station)
    scope = scope_for(station.model.domains, station.predicates)
    faults = read_faults(data.get("faults"), station, scope, devices)
    actions = tuple(
        _read_action(("actions", k), entry, scope)
        for k, entry in enumerate(sequence(data.get("actions"), ("actions",), "actions"))
    )
    planning = mapping(data.get("planning"), ("planning",), "planning")
    known(("planning",), "planning", planning, ("delay", "budget"))
    operator = mapping(data.get("operator"), ("operator",), "operator")
    known(("operator",), "operator", operator, ("delay", "approve", "maintenance", "reject"))
    return Scenario(
        file=file,
        description=str(data.get("description", "")),
        start=start,
        intentions=intentions,
        config=config,
        delays=delays,
        default_delay=default_delay,
        faults=faults,
        actions=actions,
        operator_delay=number(operator.get("delay", 2.0), ("operator", "delay")),
        approve=bool(operator.get("approve", True)),
        maintenance=bool(operator.get("maintenance", True)),
        rejects=int(number(operator.get("reject", 0), ("operator", "reject"), integer=True)),
        until=number(data.get("until", 900.0), ("until",)),
        expect=mapping(data.get("expect"), ("expect",), "expect"),
        planning_delay=number(planning.get("delay", 0.0), ("planning", "delay")),
        planning_budget=number(planning.get("budget", 10.0), ("planning", "budget")),
    )


def _read_start(raw: Any, station: Station) -> dict[str, Value]:
    """`start`: values that replace the model's initial ones."""
    model = station.model
    start: dict[str, Value] = {}
    for name, value in mapping(raw, ("start",), "start").items():
        if name not in model.variable_index:
            raise Problem(("start", name), f"unknown variable '{name}'")
        domain = model.variable(name)
        if value not in domain.domain:
            raise Problem(("start", name), f"{value!r} is not in {domain.describe_domain()}")
        start[name] = value
    return start


def _read_intentions(raw: Any, station: Station) -> tuple[str, ...] | None:
    """`intentions`: the ones that start by themselves (None: all of them)."""
    if raw is None:
        return None
    known = {i.name for i in station.intentions}
    for k, name in enumerate(sequence(raw, ("intentions",), "intentions")):
        if name not in known:
            raise Problem(("intentions", k), f"unknown intention '{name}'")
    return tuple(raw)


def _read_config(raw: Any, station: Station, intentions: tuple[str, ...] | None) -> RunnerConfig:
    """`config`: the runner's settings, the effects' own time-outs among them."""
    config = mapping(raw, ("config",), "config")
    known(("config",), "config", config, _CONFIG_KEYS)
    transitions = station.model.transition_index
    timeouts = mapping(config.get("effect_timeouts"), ("config", "effect_timeouts"), "it")
    for effect, seconds in timeouts.items():
        if effect not in transitions:
            raise Problem(("config", "effect_timeouts", effect), f"unknown transition '{effect}'")
        if seconds is not None:
            number(seconds, ("config", "effect_timeouts", effect))
    numbers = ("effect_timeout", "heartbeat_timeout", "reminder", "recheck_period")
    for key in (*numbers, "retries", "max_steps"):
        if key in config:
            number(config[key], ("config", key), integer=key in ("retries", "max_steps"))
    if "sequential" in config and not isinstance(config["sequential"], bool):
        raise Problem(("config", "sequential"), f"{config['sequential']!r} is not true or false")
    return RunnerConfig(
        auto_intentions=frozenset(intentions) if intentions is not None else None,
        **{k: v for k, v in config.items()},
    )


def _read_delays(raw: Any, station: Station) -> tuple[dict[str, float], float]:
    """`delays`: seconds per resource or effect, and the `default` for the others."""
    delays = dict(mapping(raw, ("delays",), "delays"))
    resources = {r.name for r in station.resources}
    for name, seconds in delays.items():
        number(seconds, ("delays", name))
        if (
            name != "default"
            and name not in station.model.transition_index
            and name not in resources
        ):
            raise Problem(("delays", name), f"'{name}' is neither a resource nor an effect")
    return delays, float(delays.pop("default", 1.0))


def _read_action(where: Path, entry: Any, scope: Any) -> ScheduledAction:
    if not isinstance(entry, dict):
        raise Problem(where, "an action is a mapping with keys at/when, do, ...")
    do = entry.get("do")
    if do not in _ACTIONS:
        raise Problem((*where, "do"), f"do must be one of {', '.join(_ACTIONS)}, not {do!r}")
    kind, keys = _ACTIONS[do]
    known(where, "action", entry, ("at", "when", "after", "do", "user", *keys))
    when = when_of(entry, where, scope)
    after = after_of(entry, where, when)
    missing = [key for key in keys if key not in entry and key != "reason"]
    if missing:
        raise Problem(where, f"{do} needs {', '.join(missing)}")
    arguments = {key: entry[key] for key in keys if key in entry}
    action = kind(user=str(entry.get("user", "engineer")), **arguments)
    at = number(entry["at"], (*where, "at")) if "at" in entry else None
    return ScheduledAction(action, at, when, after)


def person_delay_of(scenario: Scenario, station: Station) -> float:
    """How long the scenario's people take to tap Done on their watch: the delay of the
    watch's confirm effect, or of the person, or the default (as the simulated world has it)."""
    for person, watch in station.watches:
        if watch.confirm in scenario.delays:
            return scenario.delays[watch.confirm]
        if person.name in scenario.delays:
            return scenario.delays[person.name]
    return scenario.default_delay
