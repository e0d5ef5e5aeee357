"""A runner's live state as JSON and back (DESIGN.md section 4).

Size: one format, written and read.  Most of it is the loader's checks, one per stored
field, kept beside the writer so that a field changed in one is changed in the other.

The station server saves `dump(state)` after every tick and, after a `kill -9`, carries on
from `load(runner, saved, now)`.  Expressions are stored as text and parsed against the
runner's model, so a snapshot is checked against the model it is restored into: a name or a
value the model does not know raises `SnapshotError` saying which.

Not stored: `effects_watched_at`, `automatics_settled_at` and `invariants_held_at`, caches of
what the incremental checks last looked at; `None` makes the first tick after a restart look at
everything.  Nor `recovery_held` and `rechecked`: after a restart a held recovery is planned
once more and what is in error is checked once more.

Rebased: times of the old process's clock mean nothing to the new one, so heartbeat
windows, effect time-out windows and the background check start again at `now` (a device
that was unavailable stays so until it answers; a timed-out effect stays timed out).

The stored keys are those of format 1, which outside tools may read: where a field of
`RunnerState` was renamed since, `STORED_AS` gives its key.  Keys added since format 1 began
(`_ADDED`, and a plan's `held`, `early` and `kept`) are optional, so that older snapshots
still load.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import fields
from typing import Any, TypeVar

from planner.model.expression_text import parse_expr
from planner.model.expressions import Expr, ExpressionError, format_expr
from planner.planning.partial_order import Block
from planner.reading.yaml_reader import scope_for
from planner.runner.runner import Runner
from planner.runner.state import OperationPlan, RunnerState, TransitionPlan
from planner.runner.vocabulary import IntentionState, OperationState, ReplanReason

FORMAT = 1
# fields of RunnerState stored under their format-1 names
STORED_AS = {
    "operation_goals": "goals",
    "maintenance_for": "maintained",
    "last_heard": "heard",
    "effect_enabled_since": "effect_since",
    "restart_mode": "restart",
    "resetting": "resets",
    "auto_start": "armed",
    "next_background_check": "next_recheck",
}
# keys added to format 1 later, with the value an older snapshot means by leaving them out
_ADDED = {
    "restart_reason": "",
    "restart_user": "",
    "intention_causes": {},
    "operation_causes": {},
    "blamed_on_timeouts": {},
    "resumable": [],
    "reminded": {},
    "announced": [],
    "maintenance_due": False,
    "cannot_act": {},
    "stale": {},
    "run_finished": [],
}

T = TypeVar("T")
_State = TypeVar("_State", IntentionState, OperationState)


class SnapshotError(Exception):
    """A snapshot that cannot be restored into this runner; the message names what and where."""


def dump(state: RunnerState) -> dict[str, Any]:
    """The state as plain JSON values: sets as sorted lists, expressions as text."""
    return {STORED_AS.get(key, key): value for key, value in _fields(state).items()}


def _fields(state: RunnerState) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "values": dict(state.values),
        "intentions": {name: str(value) for name, value in state.intentions.items()},
        "operations": {name: str(value) for name, value in state.operations.items()},
        # pairs, not a mapping (a database may reorder a JSON object's keys): the transition
        # planner's goal conjoins the executing operations' goals in the order they started
        "operation_goals": [
            [name, format_expr(goal)] for name, goal in state.operation_goals.items()
        ],
        "failures": dict(state.failures),
        "operation_plan": _dump_operations(state.operation_plan),
        "transition_plan": _dump_plan(state.transition_plan),
        "recovery": _dump_plan(state.recovery),
        "relaxed": sorted(state.relaxed),
        "rejected": sorted(state.rejected),
        "maintenance": _dump_plan(state.maintenance),
        "maintenance_for": state.maintenance_for,
        "last_heard": dict(state.last_heard),
        "unavailable": sorted(state.unavailable),
        "effect_enabled_since": dict(state.effect_enabled_since),
        "timed_out": sorted(state.timed_out),
        "restart_mode": state.restart_mode,
        "restart_reason": state.restart_reason,
        "restart_user": state.restart_user,
        "resetting": sorted(state.resetting),
        "auto_start": sorted(state.auto_start),
        "next_background_check": state.next_background_check,
        "replan_operations": _reason(state.replan_operations),
        "replan_transitions": _reason(state.replan_transitions),
        "halted": state.halted,
        "intention_causes": dict(state.intention_causes),
        "operation_causes": dict(state.operation_causes),
        "blamed_on_timeouts": {
            name: [sorted(effects) for effects in blamed]
            for name, blamed in sorted(state.blamed_on_timeouts.items())
        },
        "resumable": sorted(state.resumable),
        "reminded": dict(sorted(state.reminded.items())),
        "announced": list(state.announced),
        "maintenance_due": state.maintenance_due,
        "cannot_act": dict(state.cannot_act),
        "stale": dict(state.stale),
        "run_finished": list(state.run_finished),
    }


def _reason(reason: ReplanReason | None) -> str:
    return "" if reason is None else reason.value


def _dump_plan(plan: TransitionPlan | None) -> dict[str, Any] | None:
    if plan is None:
        return None
    return {
        "goal": format_expr(plan.goal),
        "steps": list(plan.steps),
        "blocks": [
            {"index": b.index, "steps": list(b.steps), "after": sorted(b.after)}
            | {"reads": sorted(b.reads), "writes": sorted(b.writes)}
            for b in plan.blocks
        ],
        "taken": sorted(plan.taken),
        "remaining": {str(k): list(v) for k, v in sorted(plan.remaining.items())},
        "approved": sorted(plan.approved),
        "asked": sorted(plan.asked),
        "held": {str(k): why for k, why in sorted(plan.held.items())},
        "early": list(plan.early),
        "kept": [format_expr(expr) for expr in plan.kept],
    }


def _dump_operations(plan: OperationPlan | None) -> dict[str, Any] | None:
    if plan is None:
        return None
    return {
        "steps": list(plan.steps),
        "after": [sorted(a) for a in plan.after],
        "started": sorted(plan.started),
        "finished": sorted(plan.finished),
    }


def load(
    runner: Runner, data: Mapping[str, Any], now: float, *, strict: bool = True
) -> RunnerState:
    """The state `dump` saved, for `runner`'s model, on the clock of the process that loads it.

    What the model has and the snapshot lacks starts as `Runner.initial` would (a variable at
    its initial value, an intention or operation in `i`): a newer model version may add them.
    Names the model lacks raise, or with `strict=False` are dropped; but plans are never
    patched, so a plan step the model does not know always raises.
    """
    if not isinstance(data, Mapping):
        raise SnapshotError(f"a snapshot is a mapping, not {type(data).__name__}")
    if data.get("format") != FORMAT:
        shown = data.get("format")
        raise SnapshotError(f"snapshot format {shown!r}; this version reads format {FORMAT}")
    data = {**_ADDED, **data}
    for key in ("transition_plan", "recovery", "maintenance"):
        if isinstance(data.get(key), dict):
            data[key] = {"held": {}, "early": [], "kept": [], **data[key]}
    loader = _Loader(runner, strict)
    keys = dump(runner.initial())  # every key dump writes
    return loader.state(loader.record(data, keys, "the snapshot"), now)


class _Loader:
    def __init__(self, runner: Runner, strict: bool) -> None:
        self.runner, self.model, self.strict = runner, runner.model, strict
        self.scope = scope_for(self.model.domains)
        self.resources = [r.name for r in runner.station.resources]
        self.known: dict[str, Collection[str]] = {
            "variable": self.model.variable_index,
            "transition": self.model.transition_index,
            "specification": {s.name for s in self.model.specifications},
            "resource": self.resources,
            "operation": runner.index.operations,
            "intention": runner.index.intentions,
        }

    def state(self, data: Mapping[str, Any], now: float) -> RunnerState:
        values = self.values(data["values"])
        goals = self.goals(data["goals"])
        failures = self.counts(data["failures"], "operation", "failures")
        strings = self.strings(data)
        self.mapping(data["heard"], "resource", "heard")  # the old clock's times
        since = self.mapping(data["effect_since"], "transition", "effect_since")
        return RunnerState(
            values={v.name: values.get(v.name, v.initial) for v in self.model.variables},
            intentions=self.states(data["intentions"], "intention", IntentionState),
            operations=self.states(data["operations"], "operation", OperationState),
            operation_goals={
                name: self.expr(text, f"goals['{name}']") for name, text in goals.items()
            },
            failures=failures,
            operation_plan=self.operation_plan(data["operation_plan"]),
            transition_plan=self.plan(data["transition_plan"], "transition_plan"),
            recovery=self.plan(data["recovery"], "recovery"),
            relaxed=frozenset(self.names(data["relaxed"], "specification", "relaxed")),
            rejected=self.names(data["rejected"], "transition", "rejected"),
            maintenance=self.plan(data["maintenance"], "maintenance"),
            maintenance_for=strings["maintained"],
            # fresh heartbeat and effect time-out windows on the new clock
            last_heard=dict.fromkeys(self.resources, now),
            unavailable=self.names(data["unavailable"], "resource", "unavailable"),
            effect_enabled_since=dict.fromkeys(since, now),
            timed_out=self.names(data["timed_out"], "transition", "timed_out"),
            restart_mode=self.check(data["restart"], bool, "restart"),
            restart_reason=strings["restart_reason"],
            restart_user=strings["restart_user"],
            resetting=self.names(data["resets"], "operation", "resets"),
            auto_start=self.names(data["armed"], "intention", "armed"),
            next_background_check=now,
            replan_operations=self.reason(strings["replan_operations"], "replan_operations"),
            replan_transitions=self.reason(strings["replan_transitions"], "replan_transitions"),
            halted=strings["halted"],
            intention_causes=self.causes(data["intention_causes"], "intention"),
            operation_causes=self.causes(data["operation_causes"], "operation"),
            **self.added_fields(data),
        )

    def values(self, raw: Any) -> dict[str, Any]:
        values = self.mapping(raw, "variable", "values")
        for name, value in values.items():
            variable = self.model.variable(name)
            if not any(type(value) is type(v) and value == v for v in variable.domain):
                shown = variable.describe_domain()
                raise SnapshotError(f"values: {value!r} is not a value of '{name}' ({shown})")
        return values

    def goals(self, raw: Any) -> dict[str, Any]:
        """The executing operations' goals, as pairs in the order they started."""
        pairs = self.check(raw, list, "goals")
        if not all(isinstance(p, list) and len(p) == 2 and isinstance(p[0], str) for p in pairs):
            raise SnapshotError("goals: expected a list of [operation, goal] pairs")
        return self.mapping(dict(pairs), "operation", "goals")

    def strings(self, data: Mapping[str, Any]) -> dict[str, str]:
        """The fields stored as text: the operation maintained, restart's reason and user,
        why plans are made again, why automatic steps halted."""
        texts = (
            "maintained",
            "restart_reason",
            "restart_user",
            "replan_operations",
            "replan_transitions",
            "halted",
        )
        strings = {key: self.check(data[key], str, key) for key in texts}
        if strings["maintained"]:
            self.keep(strings["maintained"], "operation", "maintained", droppable=False)
        return strings

    def added_fields(self, data: Mapping[str, Any]) -> dict[str, Any]:
        """Fields added to format 1 later: late effects, reminders, announced violations,
        maintenance waiting for the operations to come to rest, resources that cannot act."""
        return {
            "blamed_on_timeouts": self.blamed(data["blamed_on_timeouts"]),
            "resumable": self.names(data["resumable"], "operation", "resumable"),
            "reminded": self.counts(data["reminded"], "transition", "reminded"),
            "announced": tuple(self.steps(data["announced"], "specification", "announced")),
            "maintenance_due": self.check(data["maintenance_due"], bool, "maintenance_due"),
            "run_finished": tuple(
                name
                for name in self.check(data["run_finished"], list, "run_finished")
                if self.keep(name, "operation", "run_finished")
            ),
            "cannot_act": {
                name: self.check(why, str, f"cannot_act['{name}']")
                for name, why in self.mapping(data["cannot_act"], "resource", "cannot_act").items()
            },
            "stale": {
                name: self.check(why, str, f"stale['{name}']")
                for name, why in self.mapping(data["stale"], "variable", "stale").items()
            },
        }

    def counts(self, raw: Any, what: str, where: str) -> dict[str, int]:
        counts = self.mapping(raw, what, where)
        for name, count in counts.items():
            self.check(count, int, f"{where}['{name}']")
        return counts

    def blamed(self, raw: Any) -> dict[str, list[frozenset[str]]]:
        blamed = self.mapping(raw, "operation", "blamed_on_timeouts")
        return {
            name: [
                frozenset(self.names(effects, "transition", f"blamed_on_timeouts['{name}']"))
                for effects in self.check(lists, list, f"blamed_on_timeouts['{name}']")
            ]
            for name, lists in blamed.items()
        }

    def causes(self, raw: Any, what: str) -> dict[str, str]:
        where = f"{what}_causes"
        causes = self.mapping(raw, what, where)
        for name, why in causes.items():
            self.check(why, str, f"{where}['{name}']")
        return causes

    @staticmethod
    def reason(text: str, where: str) -> ReplanReason | None:
        if not text:
            return None
        try:
            return ReplanReason(text)
        except ValueError:
            raise SnapshotError(f"{where}: {text!r} is not a reason to plan again") from None

    def record(self, raw: Any, keys: Iterable[str], where: str) -> dict[str, Any]:
        """`raw` as a mapping with (at least) these keys."""
        record = self.check(raw, dict, where)
        missing = [key for key in keys if key not in record]
        if missing:
            raise SnapshotError(f"{where}: {', '.join(missing)} missing")
        return record

    @staticmethod
    def check(value: Any, kind: type[T], where: str) -> T:
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            raise SnapshotError(f"{where}: expected {kind.__name__}, found {value!r}")
        return value

    def keep(self, name: Any, what: str, where: str, *, droppable: bool = True) -> bool:
        """Is `name` in the model?  If not: an error, or (not strict) False to drop it."""
        if isinstance(name, str) and name in self.known[what]:
            return True
        if self.strict or not droppable or not isinstance(name, str):
            raise SnapshotError(f"{where}: unknown {what} {name!r}")
        return False

    def mapping(self, raw: Any, what: str, where: str) -> dict[str, Any]:
        return {k: v for k, v in self.check(raw, dict, where).items() if self.keep(k, what, where)}

    def names(self, raw: Any, what: str, where: str) -> set[str]:
        return {name for name in self.check(raw, list, where) if self.keep(name, what, where)}

    def steps(self, raw: Any, what: str, where: str) -> tuple[str, ...]:
        """Names in a plan, in order; unknown ones always raise."""
        steps = self.check(raw, list, where)
        return tuple(n for n in steps if self.keep(n, what, where, droppable=False))

    def states(self, raw: Any, what: str, life_cycle: type[_State]) -> dict[str, _State]:
        where = what + "s"
        states = self.mapping(raw, what, where)
        for name, state in states.items():
            if state not in {member.value for member in life_cycle}:
                shown = ", ".join(member.value for member in life_cycle)
                raise SnapshotError(f"{where}['{name}']: state {state!r} is not one of {shown}")
        initial = life_cycle("i")
        return {name: life_cycle(states.get(name, initial)) for name in self.known[what]}

    def expr(self, text: Any, where: str) -> Expr:
        try:
            return parse_expr(self.check(text, str, where), self.scope)
        except ExpressionError as exc:
            raise SnapshotError(f"{where}: {exc.message} in {text!r}") from None

    def indexes(self, raw: Any, bound: int, where: str) -> set[int]:
        """Positions in a plan (of blocks or steps), each below `bound`."""
        out = {self.check(k, int, where) for k in self.check(raw, list, where)}
        if any(not 0 <= k < bound for k in out):
            raise SnapshotError(f"{where}: {sorted(out)} reaches past the {bound} in the plan")
        return out

    def plan(self, raw: Any, where: str) -> TransitionPlan | None:
        if raw is None:
            return None
        raw = self.record(raw, _names(TransitionPlan), where)
        blocks = []
        for k, block in enumerate(self.check(raw["blocks"], list, f"{where}.blocks")):
            at = f"{where}.blocks[{k}]"
            block = self.record(block, _names(Block), at)
            steps = self.steps(block["steps"], "transition", f"{at}.steps")
            if not steps:
                raise SnapshotError(f"{at}.steps: a block has at least one step")
            reads = self.steps(block["reads"], "variable", f"{at}.reads")
            writes = self.steps(block["writes"], "variable", f"{at}.writes")
            after = self.indexes(block["after"], k, f"{at}.after")  # earlier blocks only
            index = self.check(block["index"], int, f"{at}.index")
            blocks.append(
                Block(index, steps, frozenset(reads), frozenset(writes), frozenset(after))
            )
        remaining: dict[int, list[str]] = {}
        for key, waiting in self.check(raw["remaining"], dict, f"{where}.remaining").items():
            if not str(key).isdigit() or int(key) >= len(blocks):
                raise SnapshotError(f"{where}.remaining: {key!r} is not a block number")
            at = f"{where}.remaining[{key}]"
            remaining[int(key)] = list(self.steps(waiting, "transition", at))
        held: dict[int, str] = {}
        for key, why in self.check(raw["held"], dict, f"{where}.held").items():
            if not str(key).isdigit() or int(key) >= len(blocks):
                raise SnapshotError(f"{where}.held: {key!r} is not a block number")
            held[int(key)] = self.check(why, str, f"{where}.held[{key}]")
        return TransitionPlan(
            self.expr(raw["goal"], f"{where}.goal"),
            self.steps(raw["steps"], "transition", f"{where}.steps"),
            tuple(blocks),
            self.indexes(raw["taken"], len(blocks), f"{where}.taken"),
            remaining,
            self.indexes(raw["approved"], len(blocks), f"{where}.approved"),
            self.indexes(raw["asked"], len(blocks), f"{where}.asked"),
            held,
            list(self.steps(raw["early"], "transition", f"{where}.early")),
            tuple(
                self.expr(text, f"{where}.kept[{k}]")
                for k, text in enumerate(self.check(raw["kept"], list, f"{where}.kept"))
            ),
        )

    def operation_plan(self, raw: Any) -> OperationPlan | None:
        if raw is None:
            return None
        raw = self.record(raw, _names(OperationPlan), "operation_plan")
        steps = self.steps(raw["steps"], "operation", "operation_plan.steps")
        after = self.check(raw["after"], list, "operation_plan.after")
        if len(after) != len(steps):
            raise SnapshotError("operation_plan.after: needs one entry per step")
        at = "operation_plan.after"  # each step waits for earlier ones only
        waits = [frozenset(self.indexes(a, k, f"{at}[{k}]")) for k, a in enumerate(after)]
        return OperationPlan(
            steps,
            tuple(waits),
            self.indexes(raw["started"], len(steps), "operation_plan.started"),
            self.indexes(raw["finished"], len(steps), "operation_plan.finished"),
        )


def _names(plan: type[Any]) -> list[str]:
    return [f.name for f in fields(plan)]
