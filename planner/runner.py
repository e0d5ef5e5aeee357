"""The runner: the one place live state changes (DESIGN.md section 4, seed 000 sec. 4).

A deterministic state machine with an injected clock: `tick(state, inputs, now)` returns the
next state, the command values to publish and the events of the tick.  It keeps the live
values, the intentions and operations with their states, both plans, the effect time-outs
and the resources' availability, and handles errors by replanning (seed 000 Figure 6):

    TP finds no plan -> the executing operations that cannot reach their goals go to error
    -> OP replans without them -> no plan -> the intentions that fail go to error
    -> TP with maintenance transitions for the failed operations -> instructions for the
    operator -> the background check clears the errors once they can be completed again.

A violated specification starts forbidden-state recovery: a plan that may use maintenance
transitions back to a good state, each of whose steps waits for an operator's approval.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import TypeVar

from planner.expressions import (
    TRUE,
    Assign,
    Expr,
    Value,
    conjunction,
    conjuncts,
    negation,
    variables_of,
)
from planner.model import UNCONTROLLABLE, TransitionKind, VariableKind
from planner.operation_planner import OperationPlanner
from planner.partial_order import Block, blocks, independent_operations
from planner.planning import PlanQuery, PlanResult, PlanStatus
from planner.runner_io import (
    Action,
    Approve,
    CancelIntention,
    EnterRestart,
    Event,
    Inputs,
    LeaveRestart,
    MaintenanceDone,
    ReenableEffect,
    Reject,
    ResetOperation,
    RunnerConfig,
    SetEstimated,
    StartIntention,
)
from planner.semantics import Semantics, State, compile_expr
from planner.station import Station, effect_as_goal
from planner.transition_planner import TransitionPlanner

# a maintenance step (a person's work, planned in recovery) weighs as much as this many of
# the station's own steps: a robot that can move itself is not moved by hand
MAINTENANCE_COST = 10

Stopwatch = Callable[[], float]


@dataclass
class TransitionPlan:
    """A transition plan being followed: its blocks and which of them have been started."""

    goal: Expr
    steps: tuple[str, ...]
    blocks: tuple[Block, ...]
    taken: set[int] = field(default_factory=set)
    # for each taken block, its effects and automatics that have not happened yet
    remaining: dict[int, list[str]] = field(default_factory=dict)
    approved: set[int] = field(default_factory=set)  # recovery: blocks an operator approved
    asked: set[int] = field(default_factory=set)  # recovery: blocks shown for approval

    @property
    def done(self) -> set[int]:
        return {k for k in self.taken if not self.remaining.get(k)}

    def start(self, k: int) -> None:
        self.taken.add(k)
        self.remaining[k] = list(self.blocks[k].steps[1:])

    def copy(self) -> TransitionPlan:
        return replace(
            self,
            taken=set(self.taken),
            remaining={k: list(v) for k, v in self.remaining.items()},
            approved=set(self.approved),
            asked=set(self.asked),
        )

    def happened(self, name: str) -> None:
        """An effect or automatic step happened: it completes the earliest block expecting it."""
        for k in sorted(self.remaining):
            if name in self.remaining[k]:
                self.remaining[k].remove(name)
                return


@dataclass
class OperationPlan:
    steps: tuple[str, ...]
    after: tuple[frozenset[int], ...]
    started: set[int] = field(default_factory=set)
    finished: set[int] = field(default_factory=set)

    def copy(self) -> OperationPlan:
        return replace(self, started=set(self.started), finished=set(self.finished))


@dataclass
class RunnerState:
    """Everything live; a tick works on a copy and returns it."""

    values: dict[str, Value]
    intentions: dict[str, str]  # i, e, f, error
    operations: dict[str, str]  # i, e, error
    goals: dict[str, Expr] = field(default_factory=dict)  # executing operations' planning goals
    failures: dict[str, int] = field(default_factory=dict)
    operation_plan: OperationPlan | None = None
    transition_plan: TransitionPlan | None = None
    recovery: TransitionPlan | None = None  # forbidden-state recovery in progress
    relaxed: frozenset[str] = frozenset()
    rejected: set[str] = field(default_factory=set)  # recovery steps an operator rejected
    # after errors: the plan with maintenance transitions being followed, and the operation
    # in error it was made for (seed 000 sec. 4.5)
    maintenance: TransitionPlan | None = None
    maintained: str = ""
    heard: dict[str, float] = field(default_factory=dict)
    unavailable: set[str] = field(default_factory=set)
    effect_since: dict[str, float] = field(default_factory=dict)
    timed_out: set[str] = field(default_factory=set)
    restart: bool = False
    # restart mode: operations being reset, planned to reach their precondition
    resets: set[str] = field(default_factory=set)
    armed: set[str] = field(default_factory=set)  # intentions allowed to start by themselves
    next_recheck: float = 0.0
    replan_operations: str = ""  # why the operation plan must be made again ("" if not)
    replan_transitions: str = ""
    halted: str = ""  # a model error stopped automatic steps
    # what the incremental checks last looked at (None: look at everything): effects were
    # watched for time-outs, automatics were at a fixpoint, no invariant was violated
    watched: State | None = None
    settled: State | None = None
    consistent: State | None = None

    def copy(self) -> RunnerState:
        """A copy a tick may change without touching this one (expressions, tuples and
        values are immutable and shared; a deepcopy cost more than the rest of a tick)."""
        return replace(
            self,
            values=dict(self.values),
            intentions=dict(self.intentions),
            operations=dict(self.operations),
            goals=dict(self.goals),
            failures=dict(self.failures),
            operation_plan=_copied(self.operation_plan),
            transition_plan=_copied(self.transition_plan),
            recovery=_copied(self.recovery),
            rejected=set(self.rejected),
            maintenance=_copied(self.maintenance),
            heard=dict(self.heard),
            unavailable=set(self.unavailable),
            effect_since=dict(self.effect_since),
            timed_out=set(self.timed_out),
            resets=set(self.resets),
            armed=set(self.armed),
        )


_Plan = TypeVar("_Plan", TransitionPlan, OperationPlan)


def _copied(plan: _Plan | None) -> _Plan | None:
    return None if plan is None else plan.copy()


def touched(readers: list[list[int]], before: State | None, now: State) -> set[int] | None:
    """What reads a variable that differs between the two states (None: no `before`, so
    everything may have changed); `readers[position]` lists what reads that variable."""
    if before is None:
        return None
    out: set[int] = set()
    for position, (old, new) in enumerate(zip(before, now, strict=True)):
        if old != new:
            out.update(readers[position])
    return out


def assigned(actions: Iterable[Assign], values: Mapping[str, Value]) -> dict[str, Value]:
    """The values `actions` assign, every one reading `values` (the state before them)."""
    out: dict[str, Value] = {}
    for action in actions:
        value = values[action.source] if action.source is not None else action.value
        assert value is not None
        out[action.target] = value
    return out


class Runner:
    """Runs one station model; built once, ticked forever."""

    def __init__(
        self,
        station: Station,
        transition_planner: TransitionPlanner,
        operation_planner: OperationPlanner,
        config: RunnerConfig | None = None,
        stopwatch: Stopwatch | None = None,
    ) -> None:
        self.station = station
        self.model = station.model
        self.config = config or RunnerConfig()
        self.tp = transition_planner
        self.op = operation_planner
        self.semantics = Semantics(self.model)
        self.stopwatch = stopwatch
        index = self.model.variable_index
        self.kind = {v.name: v.kind for v in self.model.variables}
        self.measured = {v.name for v in self.model.variables if v.kind is VariableKind.MEASURED}
        self.decisions = [v.name for v in self.model.variables if v.kind is VariableKind.DECISION]
        self.effects = [c for c in self.semantics.transitions if c.kind is TransitionKind.EFFECT]
        self.effect_index = {e.name: k for k, e in enumerate(self.effects)}
        # for each variable (by position), the invariants that read it
        self.invariants_reading: list[list[int]] = [[] for _ in self.model.variables]
        for k, spec in enumerate(self.model.specifications):
            for name in variables_of(spec.invariant):
                self.invariants_reading[index[name]].append(k)
        # for each variable (by position), the automatic transitions whose guard reads it
        self.automatics_reading: list[list[int]] = [[] for _ in self.model.variables]
        self.automatic_writes: list[list[int]] = []
        for k, auto in enumerate(self.semantics.automatic):
            for name in variables_of(auto.transition.guard):
                self.automatics_reading[index[name]].append(k)
            self.automatic_writes.append(sorted({index[a.target] for a in auto.transition.actions}))
        # the other effects of the same ability: what may happen instead of an expected one
        self.alternatives: dict[str, frozenset[str]] = {}
        for ability in station.abilities:
            own = {n for n in ability.transitions if n in self.effect_index}
            for name in own:
                self.alternatives[name] = self.alternatives.get(name, frozenset()) | (own - {name})
        # which effects a changed variable concerns: those whose guard reads it (to watch
        # them for time-outs) and those that write it (to explain a measured change)
        self.effects_reading: list[list[int]] = [[] for _ in self.model.variables]
        self.effects_writing: dict[str, list[int]] = {}
        for k, effect in enumerate(self.effects):
            for name in variables_of(effect.transition.guard):
                self.effects_reading[index[name]].append(k)
            for action in effect.transition.actions:
                self.effects_writing.setdefault(action.target, []).append(k)
        self.owner: dict[str, str] = {}
        for resource in station.resources:
            for name in resource.transitions:
                self.owner[name] = resource.name
        self.resource_transitions = {r.name: frozenset(r.transitions) for r in station.resources}
        self.intention_pre = {
            i.name: compile_expr(i.precondition, index) for i in station.intentions
        }
        self.intention_goal = {i.name: compile_expr(i.goal, index) for i in station.intentions}
        # each intention's goal as its conjuncts: how much of it a state satisfies
        self.goal_parts = {
            i.name: [compile_expr(part, index) for part in conjuncts(i.goal)]
            for i in station.intentions
        }
        self.operation_pre = {
            o.name: compile_expr(o.precondition, index) for o in station.operations
        }
        self.operations = {o.name: o for o in station.operations}
        self.intentions = {i.name: i for i in station.intentions}
        self.op_variables = {
            o.name: frozenset(
                variables_of(o.precondition)
                | variables_of(o.goal)
                | {a.target for a in o.effects}
                | {a.source for a in o.effects if a.source is not None}
            )
            for o in station.operations
        }
        self._goal_cache: dict[Expr, Callable[[State], bool]] = {}

    # -- state ---------------------------------------------------------------------------------

    def initial(self, now: float = 0.0, values: Mapping[str, Value] | None = None) -> RunnerState:
        start = {v.name: v.initial for v in self.model.variables}
        start.update(values or {})
        auto = self.config.auto_intentions
        armed = set(self.intentions) if auto is None else set(auto)
        return RunnerState(
            values=start,
            intentions={name: "i" for name in self.intentions},
            operations={name: "i" for name in self.operations},
            heard={r.name: now for r in self.station.resources},
            armed=armed,
            next_recheck=now,
        )

    def tick(
        self, state: RunnerState, inputs: Inputs, now: float
    ) -> tuple[RunnerState, dict[str, Value], list[Event]]:
        work = _Tick(self, state.copy(), now)
        work.run(inputs)
        commands = {
            name: value
            for name, value in work.state.values.items()
            if self.kind[name] is VariableKind.COMMAND
        }
        return work.state, commands, work.events

    # -- helpers shared with the tick ----------------------------------------------------------

    def as_state(self, values: Mapping[str, Value]) -> State:
        return tuple(values[v.name] for v in self.model.variables)

    def holds(self, expr: Expr, values: Mapping[str, Value]) -> bool:
        return self.compiled(expr)(self.as_state(values))

    def compiled(self, expr: Expr) -> Callable[[State], bool]:
        check = self._goal_cache.get(expr)
        if check is None:
            check = compile_expr(expr, self.model.variable_index)
            self._goal_cache[expr] = check
        return check

    def is_bad(self, values: Mapping[str, Value]) -> bool:
        return self.tp.sym.contains(self.tp.bad, self.as_state(values))


class _Tick:
    """One tick's work on a private copy of the state."""

    def __init__(self, runner: Runner, state: RunnerState, now: float) -> None:
        self.r = runner
        self.state = state
        self.now = now
        self.events: list[Event] = []
        self.availability_changed: set[str] = set()
        self.look_again: set[str] = set()  # effects an action re-enabled

    def emit(self, kind: str, subject: str, millis: float | None = None, **detail: object) -> None:
        self.events.append(Event(self.now, kind, subject, detail, millis))

    # -- the tick, in the order of DESIGN.md section 4 -----------------------------------------

    def run(self, inputs: Inputs) -> None:
        # maintenance work reported done happened before the measurements that show it
        done = [a for a in inputs.actions if isinstance(a, MaintenanceDone)]
        for action in done:
            self.act(action)
        self.take_inputs(inputs)
        for other in inputs.actions:
            if not isinstance(other, MaintenanceDone):
                self.act(other)
        self.automatic()
        if self.state.recovery is not None or self.newly_violated():
            self.recover()
        else:
            self.intentions()
            self.operations()
            self.transitions()
            self.maintain()
        self.monitor_effects()
        if self.now >= self.state.next_recheck:
            self.recheck()
            self.state.next_recheck = self.now + self.r.config.recheck_period

    # -- 1. inputs -----------------------------------------------------------------------------

    def take_inputs(self, inputs: Inputs) -> None:
        s = self.state
        for resource in sorted(inputs.heartbeats):
            s.heard[resource] = self.now
            if resource in s.unavailable:
                s.unavailable.discard(resource)
                self.availability_changed.add(resource)
                self.emit("available", resource)
                s.replan_transitions = s.replan_transitions or "availability"
        for resource, heard in sorted(s.heard.items()):
            late = self.now - heard > self.r.config.heartbeat_timeout
            if late and resource not in s.unavailable:
                s.unavailable.add(resource)
                self.availability_changed.add(resource)
                self.emit("unavailable", resource, silent_for=round(self.now - heard, 3))
                s.replan_transitions = s.replan_transitions or "availability"
        changed = {
            name: value
            for name, value in sorted(inputs.measured.items())
            if name in s.values and s.values[name] != value
        }
        self.explain(changed)
        for name, value in sorted(inputs.observed.items()):
            if name in s.values and s.values[name] != value:
                before = s.values[name]
                s.values[name] = value
                self.emit("observed", name, before=before, after=value)

    def explain(self, changed: dict[str, Value]) -> None:
        """Match measured changes to enabled effects; what no effect explains is unexpected."""
        s = self.state
        remaining = dict(changed)
        progress = True
        while remaining and progress:
            progress = False
            state = self.r.as_state(s.values)
            candidates = sorted({k for n in remaining for k in self.r.effects_writing.get(n, ())})
            for effect in (self.r.effects[k] for k in candidates):
                targets = {a.target: a for a in effect.transition.actions}
                if not targets.keys() & remaining.keys() or not effect.guard(state):
                    continue
                after = self.r.semantics.values(effect.apply(state))
                if all(remaining.get(t, s.values[t]) == after[t] for t in targets):
                    for target in targets:
                        s.values[target] = after[target]
                        remaining.pop(target, None)
                    self.emit("effect", effect.name)
                    self.instead(effect.name)
                    self.happened(effect.name)
                    progress = True
                    break
        if remaining:
            for name, value in remaining.items():
                s.values[name] = value
            self.emit(
                "unexpected", ", ".join(sorted(remaining)), values=dict(sorted(remaining.items()))
            )

    def instead(self, name: str) -> None:
        """A different effect than the plans expected is an error event (DESIGN.md 4.7)."""
        expected = self.expected_effects()
        if name in expected:
            return
        instead_of = sorted(self.r.alternatives.get(name, frozenset()) & expected)
        if instead_of:
            self.emit("unexpected", name, instead_of=instead_of, why="a different effect")

    def expected_effects(self) -> set[str]:
        s = self.state
        expected: set[str] = set()
        for plan in (s.transition_plan, s.recovery, s.maintenance):
            if plan is not None:
                for waiting in plan.remaining.values():
                    expected.update(waiting)
        return expected

    # -- operator and engineer actions ---------------------------------------------------------

    def act(self, action: Action) -> None:
        s = self.state
        who = action.user
        if isinstance(action, StartIntention | CancelIntention) and action.name not in s.intentions:
            self.emit("refused", action.name, user=who, why="there is no such intention")
            return
        match action:
            case StartIntention(name=name):
                s.armed.add(name)
                if s.intentions[name] in ("f", "error"):
                    s.intentions[name] = "i"
                self.emit("operator", "start intention", user=who, intention=name)
            case CancelIntention(name=name):
                s.armed.discard(name)
                if s.intentions[name] in ("e", "error"):
                    self.set_intention(name, "i", "cancelled")
                self.emit("operator", "cancel intention", user=who, intention=name)
            case Approve(step=step) | Reject(step=step):
                self.approve(action, step)
            case MaintenanceDone(transition=name):
                self.maintenance_done(name, who)
            case EnterRestart(reason=reason):
                s.restart = True
                self.emit("restart", "entered", user=who, reason=reason)
                s.replan_transitions = s.replan_transitions or "restart"
            case LeaveRestart():
                s.restart = False
                for name in sorted(s.resets):
                    self.emit("reset", name, done=False, why="restart mode left before it")
                s.resets.clear()
                self.emit("restart", "left", user=who)
                s.replan_operations = s.replan_operations or "restart"
                s.replan_transitions = s.replan_transitions or "restart"
            case SetEstimated(variable=name, value=value, reason=reason):
                self.set_estimated(name, value, reason, who)
            case ResetOperation(name=name):
                if name not in s.operations:
                    self.emit("refused", name, user=who, why="there is no such operation")
                    return
                if not s.restart:
                    self.emit("refused", name, user=who, why="operations are reset in restart mode")
                    return
                s.failures.pop(name, None)
                s.goals.pop(name, None)
                self.unstart(name)
                if s.operations[name] != "i":
                    self.set_operation(name, "i", "reset by " + who)
                s.replan_operations = s.replan_operations or "reset"
                self.emit("operator", "reset operation", user=who, operation=name)
                # seed 001 VIII-A: plan to reach its precondition, to start it again
                s.resets.add(name)
            case ReenableEffect(name=name):
                if name not in s.timed_out:
                    self.emit("refused", name, user=who, why="the effect is not timed out")
                    return
                s.timed_out.discard(name)
                s.effect_since.pop(name, None)
                self.look_again.add(name)
                self.emit("reenabled", name, user=who)
                s.replan_transitions = s.replan_transitions or "reenabled"

    def set_estimated(self, name: str, value: Value, reason: str, who: str) -> None:
        s = self.state
        kind = self.r.kind.get(name)
        if kind not in (VariableKind.ESTIMATED, VariableKind.DECISION):
            why = "no such variable" if kind is None else f"'{name}' is {kind.value}, not estimated"
            self.emit("refused", name, user=who, why=why)
            return
        if value not in self.r.model.variable(name).domain:
            self.emit("refused", name, user=who, why=f"{value!r} is outside the domain")
            return
        if not s.restart:
            self.emit("refused", name, user=who, why="estimated variables are set in restart mode")
            return
        if not reason.strip():
            self.emit("refused", name, user=who, why="a reason is required")
            return
        before = s.values[name]
        s.values[name] = value
        self.emit(
            "operator",
            "set estimated",
            user=who,
            variable=name,
            before=before,
            after=value,
            reason=reason,
        )
        s.replan_operations = s.replan_operations or "estimated"

    def maintenance_done(self, name: str, who: str) -> None:
        s = self.state
        pending = self.pending_maintenance()
        if name not in pending:
            self.emit("refused", name, user=who, why="not a maintenance step asked for now")
            return
        chosen = self.r.semantics.by_name[name]
        state = self.r.as_state(s.values)
        if not chosen.guard(state):
            self.emit("refused", name, user=who, why="its guard does not hold")
            return
        # measured values included: the devices will report what the operator did (a robot
        # moved by hand, a connector reset), and a disconnected one cannot
        s.values = self.r.semantics.values(chosen.apply(state))
        self.emit("operator", "maintenance done", user=who, transition=name)
        if s.recovery is not None:
            self.mark_taken(s.recovery, name)
        elif s.maintenance is not None:
            self.mark_taken(s.maintenance, name)

    def pending_maintenance(self) -> list[str]:
        s = self.state
        if s.recovery is not None:
            return [
                s.recovery.blocks[k].transition
                for k in self.startable(s.recovery)
                if k in s.recovery.approved
                and self.r.model.transition(s.recovery.blocks[k].transition).kind
                is TransitionKind.MAINTENANCE
            ]
        plan = s.maintenance
        if plan is None:
            return []
        return [plan.blocks[k].transition for k in self.startable(plan) if k in plan.asked]

    def approve(self, action: Action, step: int) -> None:
        s = self.state
        plan = s.recovery
        if plan is None or not 0 <= step < len(plan.blocks):
            self.emit("refused", f"step {step}", user=action.user, why="no such recovery step")
            return
        if isinstance(action, Reject):
            self.emit(
                "operator",
                "reject",
                user=action.user,
                step=step,
                transition=plan.blocks[step].transition,
            )
            s.recovery = None  # plan again, without the rejected step
            s.relaxed = frozenset()
            s.rejected.add(plan.blocks[step].transition)
            return
        plan.approved.add(step)
        self.emit(
            "operator",
            "approve",
            user=action.user,
            step=step,
            transition=plan.blocks[step].transition,
        )

    def happened(self, name: str) -> None:
        for plan in (self.state.transition_plan, self.state.recovery, self.state.maintenance):
            if plan is not None:
                plan.happened(name)

    @staticmethod
    def mark_taken(plan: TransitionPlan, name: str) -> None:
        for k, block in enumerate(plan.blocks):
            if k not in plan.taken and block.transition == name:
                plan.start(k)
                return

    # -- 2. automatic transitions --------------------------------------------------------------

    def automatic(self) -> None:
        """Automatic transitions to a fixpoint, the first enabled in model order each time.

        Only those whose guard reads a variable changed since the last fixpoint can be
        enabled, so only they are looked at."""
        s = self.state
        if s.halted:
            return
        autos = self.r.semantics.automatic
        state = self.r.as_state(s.values)
        candidates = self.automatic_candidates(state)
        fired = False
        for _ in range(self.r.config.max_automatic_steps):
            chosen = next((k for k in sorted(candidates) if autos[k].guard(state)), None)
            if chosen is None:
                if fired:
                    s.values = self.r.semantics.values(state)
                s.settled = state
                return
            candidates = {k for k in candidates if k >= chosen}  # those before: disabled
            for position in self.r.automatic_writes[chosen]:
                candidates.update(self.r.automatics_reading[position])
            state = autos[chosen].apply(state)
            fired = True
            self.emit("taken", autos[chosen].name, type="automatic")
            self.happened(autos[chosen].name)
        s.halted = "automatic transitions cycle"
        s.values = self.r.semantics.values(state)
        self.emit(
            "error",
            "automatic cycle",
            why=f"more than {self.r.config.max_automatic_steps} automatic steps in a row; "
            "automatic steps are halted until the model is fixed",
        )

    def automatic_candidates(self, state: State) -> set[int]:
        found = touched(self.r.automatics_reading, self.state.settled, state)
        return set(range(len(self.r.semantics.automatic))) if found is None else found

    def automatic_enabled(self, state: State) -> bool:
        autos = self.r.semantics.automatic
        return any(autos[k].guard(state) for k in self.automatic_candidates(state))

    def newly_violated(self) -> bool:
        """Does the state violate a specification?  Since the last state seen to violate
        none, only invariants reading a changed variable can have become false."""
        s = self.state
        state = self.r.as_state(s.values)
        invariants = self.r.semantics.invariants
        found = touched(self.r.invariants_reading, s.consistent, state)
        look = range(len(invariants)) if found is None else sorted(found)
        if any(not invariants[k][1](state) for k in look):
            return True
        s.consistent = state
        return False

    def violated(self) -> list[str]:
        return self.r.semantics.violated(self.r.as_state(self.state.values))

    # -- 3. forbidden-state recovery -----------------------------------------------------------

    def recover(self) -> None:
        s = self.state
        violated = self.violated()
        if s.recovery is None:
            if not violated:
                return
            s.relaxed = frozenset(violated)
            self.emit("forbidden", ", ".join(violated), violated=violated)
            disabled = self.disabled() | s.rejected
            query = PlanQuery(
                self.r.as_state(s.values),
                TRUE,
                self.r.config.max_steps,
                maintenance=True,
                disabled=frozenset(disabled),
                relaxed=s.relaxed,
            )
            result, millis = self.timed(self.r.tp.plan, query)
            self.emit_plan("TP", ("MT",), "forbidden state", result, millis)
            if not result.found:
                return
            s.recovery = self.follow(TRUE, result)
            if not s.recovery.blocks:
                s.recovery = None
        plan = s.recovery
        if plan is None:
            return
        if not violated and not self.r.is_bad(s.values):
            self.emit("recovered", "all specifications hold", relaxed=sorted(s.relaxed))
            s.recovery = None
            s.relaxed = frozenset()
            s.rejected.clear()
            s.replan_operations = s.replan_operations or "recovered"
            s.replan_transitions = s.replan_transitions or "recovered"
            return
        for k in self.startable(plan):
            name = plan.blocks[k].transition
            kind = self.r.model.transition(name).kind
            if k not in plan.approved:
                if k not in plan.asked:
                    plan.asked.add(k)
                    self.emit("approval", name, step=k, type=kind.value, what=self.describe(name))
                continue
            if kind is TransitionKind.MAINTENANCE:
                continue  # the operator does it and reports MaintenanceDone
            self.take(plan, k, supervised=False)

    def describe(self, name: str) -> str:
        t = self.r.model.transition(name)
        return t.description or ", ".join(
            f"{a.target} := {a.source if a.source else a.value}" for a in t.actions
        )

    # -- 4. intentions -------------------------------------------------------------------------

    def intentions(self) -> None:
        s = self.state
        state = self.r.as_state(s.values)
        for name in self.r.intentions:
            current = s.intentions[name]
            if current == "e" and self.r.intention_goal[name](state):
                self.set_intention(name, "f", "goal reached")
                s.values.update(assigned(self.r.intentions[name].actions, s.values))
                s.armed.discard(name)
            elif (
                current == "i"
                and name in s.armed
                and not s.restart
                and self.r.intention_pre[name](state)
            ):
                self.set_intention(name, "e", "precondition holds")

    def set_intention(self, name: str, new: str, why: str) -> None:
        s = self.state
        before = s.intentions[name]
        s.intentions[name] = new
        self.emit("intention", name, before=before, after=new, why=why)
        s.replan_operations = s.replan_operations or "intentions"

    def set_operation(self, name: str, new: str, why: str) -> None:
        s = self.state
        before = s.operations[name]
        s.operations[name] = new
        self.emit("operation", name, before=before, after=new, why=why)

    # -- 5. operations -------------------------------------------------------------------------

    def operations(self) -> None:
        s = self.state
        for name in list(s.goals):  # finish those whose goal holds
            if s.operations[name] == "e" and self.r.holds(s.goals[name], s.values):
                self.finish_operation(name)
        active = [n for n, st in s.intentions.items() if st == "e"]
        if not active:
            if s.operation_plan is not None:
                s.operation_plan = None
            s.replan_operations = ""
            return
        if not s.replan_operations and not self.operation_plan_reaches(active):
            s.replan_operations = "deviation"
        if s.replan_operations:
            self.plan_operations(active, s.replan_operations)
            s.replan_operations = ""
        self.start_operations()

    def finish_operation(self, name: str) -> None:
        s = self.state
        s.values.update(assigned(self.r.operations[name].actions, s.values))
        s.goals.pop(name)
        s.failures.pop(name, None)
        self.set_operation(name, "i", "goal reached")
        plan = s.operation_plan
        if plan is not None:
            for k in sorted(plan.started - plan.finished):
                if plan.steps[k] == name:
                    plan.finished.add(k)
                    break
        s.replan_transitions = s.replan_transitions or "goals"

    def predicted(self) -> dict[str, Value]:
        """The decision state once the executing operations have finished."""
        values = dict(self.state.values)
        for name in self.state.goals:
            if self.state.operations[name] != "e":
                continue  # an operation in error keeps its goal for maintenance planning only
            values.update(assigned(self.r.operations[name].effects, self.state.values))
        return values

    def operation_plan_reaches(self, active: list[str]) -> bool:
        """Simulate the rest of the operation plan: does it still reach the intentions' goals?

        Repairs the plan in place where that needs no planning, so that robots moving about
        (their positions are measured, and in the goals) do not make the planner thrash
        between equally short plans: a step whose effects already hold is skipped, and when
        only the end falls short, operations enabled there that satisfy more of the goal are
        appended (a robot that moved needs parking again).  Only operations that change
        measured variables alone are skipped or appended: a product that is not as planned
        is a deviation the operation planner must see (E1).
        """
        s = self.state
        plan = s.operation_plan
        if plan is None:
            return False
        values = self.predicted()
        skipped = []
        for k, name in enumerate(plan.steps):
            if k in plan.started:
                continue
            if s.operations[name] == "error":
                return False
            effects = assigned(self.r.operations[name].effects, values)
            if not self.r.operation_pre[name](self.r.as_state(values)):
                if self.measures_only(name) and all(
                    values[target] == value for target, value in effects.items()
                ):
                    skipped.append(k)
                    continue
                return False
            values.update(effects)
        appended: list[str] = []
        parts = [part for name in active for part in self.r.goal_parts[name]]
        met = sum(part(self.r.as_state(values)) for part in parts)
        while met < len(parts) and len(appended) < 4:
            found = None
            for name, operation in self.r.operations.items():
                if (
                    s.operations[name] == "error"
                    or not self.measures_only(name)
                    or not self.r.operation_pre[name](self.r.as_state(values))
                ):
                    continue
                after = values | assigned(operation.effects, values)
                state = self.r.as_state(after)
                if sum(part(state) for part in parts) > met:
                    found = (name, after, sum(part(state) for part in parts))
                    break
            if found is None:
                return False
            appended.append(found[0])
            values, met = found[1], found[2]
        if met < len(parts):
            return False
        for k in skipped:
            plan.started.add(k)
            plan.finished.add(k)
        for name in appended:
            plan.steps += (name,)
            plan.after += (frozenset(range(len(plan.steps) - 1)),)
        if skipped or appended:
            self.emit(
                "repaired",
                "OP",
                skipped=[plan.steps[k] for k in skipped],
                appended=appended,
            )
        return True

    def measures_only(self, operation: str) -> bool:
        return all(a.target in self.r.measured for a in self.r.operations[operation].effects)

    def plan_operations(self, active: list[str], reason: str) -> None:
        s = self.state
        errors = sorted(n for n, st in s.operations.items() if st == "error")
        intentions = [self.r.intentions[n] for n in active]
        query = self.r.op.query(
            self.predicted(), intentions, disabled=errors, max_steps=self.r.config.max_steps
        )
        result, millis = self.timed(self.r.op.plan, query)
        self.emit_plan("OP", ("DO",) if errors else (), reason, result, millis)
        if result.found:
            after = independent_operations(self.r.op_variables, result.plan)
            s.operation_plan = OperationPlan(result.plan, tuple(after))
            return
        s.operation_plan = None
        # which intentions fail: plan for each alone (seed 000 sec. 4.2)
        for intention in intentions:
            alone = self.r.op.query(
                self.predicted(), [intention], disabled=errors, max_steps=self.r.config.max_steps
            )
            single, millis = self.timed(self.r.op.plan, alone)
            if not single.found:
                self.set_intention(intention.name, "error", "no operation plan reaches its goal")
        s.replan_operations = ""
        still = [n for n, st in s.intentions.items() if st == "e"]
        if still and still != active:
            self.plan_operations(still, "error")
        if any(st == "error" for st in s.intentions.values()):
            self.maintenance_plan()

    def start_operations(self) -> None:
        s = self.state
        plan = s.operation_plan
        if plan is None or s.restart:
            return
        parallel = self.r.config.parallel_operations
        for k, name in enumerate(plan.steps):
            if k in plan.started or not plan.after[k] <= plan.finished:
                continue
            if not parallel and any(st == "e" for st in s.operations.values()):
                return
            if s.operations[name] != "i":
                continue
            if not self.r.operation_pre[name](self.r.as_state(s.values)):
                continue
            operation = self.r.operations[name]
            s.goals[name] = operation.planning_goal(s.values)
            plan.started.add(k)
            self.set_operation(name, "e", "next in the operation plan")
            s.replan_transitions = s.replan_transitions or "goals"

    # -- 6. transitions ------------------------------------------------------------------------

    def unstart(self, name: str) -> None:
        """The operation plan may start `name` again."""
        plan = self.state.operation_plan
        if plan is not None:
            for k in sorted(plan.started - plan.finished):
                if plan.steps[k] == name:
                    plan.started.discard(k)

    def transitions(self) -> None:
        s = self.state
        if s.restart:
            self.reset_transitions()
            return
        executing = [n for n in s.goals if s.operations[n] == "e"]
        if not executing:
            s.transition_plan = None
            s.replan_transitions = ""
            return
        goal = conjunction([s.goals[n] for n in executing])
        if not s.replan_transitions:
            plan = s.transition_plan
            if plan is None or plan.goal != goal:
                s.replan_transitions = "goals"
            elif not self.plan_reaches(plan):
                s.replan_transitions = "deviation"
        if s.replan_transitions:
            reason = s.replan_transitions
            s.replan_transitions = ""
            if not self.plan_transitions(executing, goal, reason):
                return
        plan = s.transition_plan
        if plan is None:
            return
        for k in self.startable(plan):
            self.take(plan, k, supervised=True)

    def disabled(self) -> set[str]:
        s = self.state
        disabled = set(s.timed_out)
        for resource in s.unavailable:
            disabled |= self.r.resource_transitions.get(resource, frozenset())
        if not s.restart:
            disabled |= self.r.station.restart_transitions
        return disabled

    def flags(self, maintenance: bool = False) -> tuple[str, ...]:
        s = self.state
        flags = []
        if s.timed_out:
            flags.append("ETO")
        if s.unavailable:
            flags.append("RTO")
        if maintenance:
            flags.append("MT")
        return tuple(flags)

    def forbidden(self, executing: Iterable[str]) -> tuple[Expr, ...]:
        """Monotonic abstraction (seed 000 sec. 4.3): the transition planner may change no
        decision variable but those the executing operations' effects change."""
        written: set[str] = set()
        for name in executing:
            written |= {a.target for a in self.r.operations[name].effects}
        return self.kept(set(self.r.decisions) - written)

    def kept(self, names: set[str]) -> tuple[Expr, ...]:
        """A forbidden predicate: any of `names` changed from its current value."""
        s = self.state
        kept = [
            effect_as_goal(Assign(name, value=s.values[name]), s.values)
            for name in self.r.decisions
            if name in names
        ]
        return (negation(conjunction(kept)),) if kept else ()

    def query(self, goal: Expr, executing: Iterable[str], maintenance: bool = False) -> PlanQuery:
        """A transition planning query from the current state.

        Maintenance planning drops the monotonic abstraction: a person putting things right
        (hanging back the tool a dead robot holds) changes what the operations estimate.
        """
        return PlanQuery(
            self.r.as_state(self.state.values),
            goal,
            self.r.config.max_steps,
            maintenance=maintenance,
            forbidden=() if maintenance else self.forbidden(executing),
            disabled=frozenset(self.disabled()),
            maintenance_cost=MAINTENANCE_COST if maintenance else 1,
        )

    def plan_transitions(self, executing: list[str], goal: Expr, reason: str) -> bool:
        s = self.state
        query = self.query(goal, executing)
        result, millis = self.timed(self.r.tp.plan, query)
        self.emit_plan("TP", self.flags(), reason, result, millis)
        if result.found:
            s.transition_plan = self.follow(goal, result)
            return True
        s.transition_plan = None
        # which executing operations cannot reach their goals: one by one (seed 000 Figure 6)
        failed = []
        for name in executing:
            alone, _ = self.timed(self.r.tp.plan, self.query(s.goals[name], executing))
            if not alone.found:
                failed.append(name)
        for name in failed or executing:
            s.failures[name] = s.failures.get(name, 0) + 1
            self.set_operation(
                name,
                "error",
                "its goal cannot be reached"
                + (f" ({s.failures[name]} failures)" if s.failures[name] > 1 else ""),
            )
            self.unstart(name)
        s.replan_operations = "error"
        return False

    def reset_transitions(self) -> None:
        """Restart mode: executing operations are paused; plan and take transitions (restart
        abilities included) that bring the operations being reset to their preconditions."""
        s = self.state
        for name in sorted(s.resets):
            if self.r.operation_pre[name](self.r.as_state(s.values)):
                s.resets.discard(name)
                self.emit("reset", name, done=True, why="its precondition holds")
        if not s.resets:
            s.transition_plan = None
            return
        preconditions = [self.r.operations[n].precondition for n in sorted(s.resets)]
        goal = conjunction(preconditions)
        plan = s.transition_plan
        if plan is None or plan.goal != goal or not self.plan_reaches(plan):
            written = {v for p in preconditions for v in variables_of(p)}
            query = replace(
                self.query(goal, []), forbidden=self.kept(set(self.r.decisions) - written)
            )
            result, millis = self.timed(self.r.tp.plan, query)
            self.emit_plan("TP", self.flags(), "reset", result, millis)
            if not result.found:
                for name in sorted(s.resets):
                    self.emit("reset", name, done=False, why="no plan reaches its precondition")
                s.resets.clear()
                s.transition_plan = None
                return
            s.transition_plan = plan = self.follow(goal, result)
        for k in self.startable(plan):
            self.take(plan, k, supervised=True)

    def follow(self, goal: Expr, result: PlanResult) -> TransitionPlan:
        pending = bool(result.states) and self.r.semantics.automatic_enabled(result.states[-1])
        order = blocks(self.r.model, result.plan, automatic_at_end=pending)
        plan = TransitionPlan(goal, result.plan, tuple(order))
        if plan.blocks and self.r.model.transition(plan.steps[0]).kind in UNCONTROLLABLE:
            plan.taken.add(0)  # leading effects and automatics happen by themselves
            plan.remaining[0] = list(plan.blocks[0].steps)
        return plan

    def startable(self, plan: TransitionPlan) -> list[int]:
        return [
            k
            for k, block in enumerate(plan.blocks)
            if k not in plan.taken
            and block.after <= plan.done
            and self.r.model.transition(block.transition).kind
            in (TransitionKind.CONTROLLED, TransitionKind.MAINTENANCE)
        ]

    def take(self, plan: TransitionPlan, k: int, *, supervised: bool) -> None:
        """Take block k's controlled transition if its guard (and the supervisor) allow it now."""
        s = self.state
        name = plan.blocks[k].transition
        chosen = self.r.semantics.by_name[name]
        if name in self.disabled():
            return
        state = self.r.as_state(s.values)
        if self.automatic_enabled(state) or not chosen.guard(state):
            return
        after = chosen.apply(state)
        if supervised and self.r.tp.sym.contains(self.r.tp.bad, after):
            return  # the supervisor's guard: never into a bad state
        s.values = self.r.semantics.values(after)
        plan.start(k)
        self.emit("taken", name, type=chosen.kind.value)
        self.automatic()

    def plan_reaches(self, plan: TransitionPlan) -> bool:
        """Simulate the rest of the plan from the current state: does it still reach the goal?

        Controlled steps are taken in the start order when their guards hold, the plan's
        effects happen when theirs do, automatic steps first, as at run time.
        """
        sem = self.r.semantics
        state = self.r.as_state(self.state.values)
        goal = self.r.compiled(plan.goal)
        sim = TransitionPlan(
            plan.goal,
            plan.steps,
            plan.blocks,
            set(plan.taken),
            {k: list(v) for k, v in plan.remaining.items()},
        )
        expected = set(plan.steps)
        planned_effects = [
            self.r.effects[k]
            for k in sorted(self.r.effect_index[n] for n in expected if n in self.r.effect_index)
        ]
        disabled = self.disabled()
        for _ in range(2 * len(plan.steps) + 2):
            if goal(state):
                return True
            autos = [a for a in sem.automatic if a.guard(state)]
            if autos:
                state = autos[0].apply(state)
                sim.happened(autos[0].name)
                continue
            step = None
            for k in self.startable(sim):
                chosen = sem.by_name[plan.blocks[k].transition]
                if chosen.kind is TransitionKind.CONTROLLED and chosen.guard(state):
                    step = k
                    break
            if step is not None:
                state = sem.by_name[plan.blocks[step].transition].apply(state)
                sim.start(step)
                continue
            waiting = [n for k in sorted(sim.remaining) for n in sim.remaining[k]]
            effect = next(
                (
                    e
                    for e in planned_effects
                    if e.name not in disabled
                    and e.guard(state)
                    and (e.name in waiting or not waiting)
                ),
                None,
            )
            if effect is None:
                effect = next(
                    (e for e in planned_effects if e.name not in disabled and e.guard(state)),
                    None,
                )
            if effect is None:
                return False
            state = effect.apply(state)
            sim.happened(effect.name)
        return goal(state)

    # -- maintenance planning after errors -----------------------------------------------------

    def maintenance_plan(self) -> None:
        """With intentions in error: a plan with maintenance transitions for a failed operation."""
        s = self.state
        failed = [n for n, st in s.operations.items() if st == "error" and n in s.goals]
        failed += [n for n, st in s.operations.items() if st == "error" and n not in s.goals]
        for name in failed:
            goal = s.goals.get(name) or self.r.operations[name].planning_goal(s.values)
            query = self.query(goal, [name], maintenance=True)
            result, millis = self.timed(self.r.tp.plan, query)
            self.emit_plan(
                "TP", self.flags(maintenance=True), "maintenance", result, millis, operation=name
            )
            steps = tuple(
                step
                for step in result.plan
                if self.r.model.transition(step).kind is TransitionKind.MAINTENANCE
            )
            if result.found and steps:
                # followed up to its last maintenance step; the rest is production again
                last = max(k for k, step in enumerate(result.plan) if step in steps)
                prefix = result.plan[: last + 1]
                pending = len(result.states) > last + 1 and self.r.semantics.automatic_enabled(
                    result.states[last + 1]
                )
                order = blocks(self.r.model, prefix, automatic_at_end=pending)
                s.maintenance = TransitionPlan(goal, prefix, tuple(order))
                s.maintained = name
                return

    def maintain(self) -> None:
        """Follow the maintenance plan: the runner takes its controlled steps (supervised),
        and each maintenance step, once the steps before it are done, becomes an instruction
        for the operator, who reports it done.  When all are done, the operation it was made
        for is tried again (if it has retries left)."""
        s = self.state
        plan = s.maintenance
        if plan is None:
            return
        if not any(st == "error" for st in s.intentions.values()):
            s.maintenance = None
            return
        for k in self.startable(plan):
            name = plan.blocks[k].transition
            if self.r.model.transition(name).kind is TransitionKind.MAINTENANCE:
                if k not in plan.asked:
                    plan.asked.add(k)
                    steps = [b.transition for b in plan.blocks]
                    self.emit(
                        "instruction",
                        name,
                        operation=s.maintained,
                        step=steps.index(name) + 1,
                        of=len(steps),
                        what=self.describe(name),
                    )
            else:
                self.take(plan, k, supervised=True)
        if len(plan.done) < len(plan.blocks):
            return
        name, s.maintenance, s.maintained = s.maintained, None, ""
        if s.operations[name] == "error" and s.failures.get(name, 0) < self.r.config.retries:
            s.goals.pop(name, None)
            self.set_operation(name, "i", "the maintenance it needed is done")
            s.replan_operations = s.replan_operations or "cleared"

    # -- 7. effect monitoring ------------------------------------------------------------------

    def monitor_effects(self) -> None:
        """Watch enabled effects for time-outs.  Only effects whose guard reads a variable
        changed in this tick, or whose resource came or went, can have become enabled or
        disabled; the enabled and timed-out ones are looked at every tick."""
        s = self.state
        state = self.r.as_state(s.values)
        look = touched(self.r.effects_reading, s.watched, state)
        s.watched = state
        if look is not None:
            look |= {self.r.effect_index[n] for n in s.effect_since}
            look |= {self.r.effect_index[n] for n in s.timed_out | self.look_again}
            for resource in self.availability_changed:
                look |= {
                    self.r.effect_index[n]
                    for n in self.r.resource_transitions.get(resource, ())
                    if n in self.r.effect_index
                }
        effects = self.r.effects if look is None else [self.r.effects[k] for k in sorted(look)]
        for effect in effects:
            name = effect.name
            owner = self.r.owner.get(name)
            enabled = effect.guard(state) and owner not in s.unavailable
            if not enabled:
                s.effect_since.pop(name, None)
                if name in s.timed_out:
                    s.timed_out.discard(name)
                    self.emit("reenabled", name, why="its guard no longer holds")
                continue
            since = s.effect_since.setdefault(name, self.now)
            timeout = self.r.config.timeout_of(name)
            if timeout is not None and name not in s.timed_out and self.now - since > timeout:
                s.timed_out.add(name)
                self.emit("timeout", name, waited=round(self.now - since, 3))
                s.replan_transitions = s.replan_transitions or "timeout"

    # -- background check ----------------------------------------------------------------------

    def recheck(self) -> None:
        """Clear operations and intentions in error that can be completed again."""
        s = self.state
        if s.recovery is not None:
            return
        for name, st in sorted(s.operations.items()):
            if st != "error" or s.failures.get(name, 0) >= self.r.config.retries:
                continue
            goal = s.goals.get(name) or self.r.operations[name].planning_goal(s.values)
            result, _ = self.timed(self.r.tp.plan, self.query(goal, [name]))
            if result.found:
                s.goals.pop(name, None)
                self.set_operation(name, "i", "its goal can be reached again")
                s.replan_operations = s.replan_operations or "cleared"
        for name, st in sorted(s.intentions.items()):
            if st != "error":
                continue
            errors = sorted(n for n, o in s.operations.items() if o == "error")
            query = self.r.op.query(
                self.predicted(),
                [self.r.intentions[name]],
                disabled=errors,
                max_steps=self.r.config.max_steps,
            )
            result, _ = self.timed(self.r.op.plan, query)
            if result.found:
                s.maintenance = None
                self.set_intention(name, "e", "its goal can be reached again")

    # -- planning bookkeeping ------------------------------------------------------------------

    def timed(
        self, plan: Callable[[PlanQuery], PlanResult], query: PlanQuery
    ) -> tuple[PlanResult, float | None]:
        watch = self.r.stopwatch
        if watch is None:
            return plan(query), None
        started = watch()
        result = plan(query)
        return result, (watch() - started) * 1000

    def emit_plan(
        self,
        level: str,
        flags: tuple[str, ...],
        reason: str,
        result: PlanResult,
        millis: float | None,
        **extra: object,
    ) -> None:
        label = level + "".join(f" w/{f}" for f in flags)
        detail: dict[str, object] = {
            "level": level,
            "flags": list(flags),
            "reason": reason,
            "status": result.status.value,
        }
        if result.status is PlanStatus.FOUND:
            detail["length"] = result.length
            detail["plan"] = list(result.plan)
        if result.violated:
            detail["violated"] = list(result.violated)
        detail.update(extra)
        self.events.append(Event(self.now, "plan", label, detail, millis))
