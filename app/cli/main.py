"""The `sp` command: plan on and check station models (DESIGN.md section 8, a fixed contract).

Exit codes: 0 plan found (or model valid), 1 unreachable or bad start, 2 invalid model or
arguments, with a message on stderr naming file, line and column.  `millis` is the time from
the command's start to its answer, Python's own start-up excluded.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from app.cli import arguments
from app.cli import station as cli_station
from app.cli.common import UsageError, planner_for, read_station, remember_order
from planner.bdd.synthesis import COUNTABLE_BITS
from planner.model.expression_text import parse_expr
from planner.model.expressions import Expr, ExpressionError
from planner.model.flat import Model, SourceLocation, TransitionKind, VariableKind
from planner.model.station import Station
from planner.planning.query import PlanQuery, PlanResult, PlanStatus, State
from planner.reading.yaml_reader import Diagnostic, ModelError, closest, scope_for
from planner.runner import QueryObserver


def main(argv: Sequence[str] | None = None, *, observer: QueryObserver | None = None) -> int:
    """`sp ARGS`; `observer` sees every planning query of `sp run` (benchmarks)."""
    started = time.perf_counter()
    parser = arguments.parser()
    args = parser.parse_args(argv)
    _end_cleanly_on_sigterm()
    try:
        if args.command == "plan":
            return _plan(args, started)
        if args.command == "run":
            return cli_station.run(args, observer)
        if args.command == "serve":
            return cli_station.serve(args)
        if args.command == "emulate":
            return cli_station.emulate(args)
        if args.command == "audit":
            return cli_station.audit(args)
        if args.command == "store":
            return cli_station.store(args)
        return _check(args)
    except ModelError as exc:
        for diagnostic in exc.diagnostics:
            print(f"error: {diagnostic}", file=sys.stderr)
        return 2
    except UsageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `sp check MODEL | head`: the reader has gone, nothing to report
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


def _end_cleanly_on_sigterm() -> None:
    """`kill` (a CI time-out, a service manager) ends `sp` as Ctrl-C does: emulators,
    drivers and the store are closed on the way out."""
    if threading.current_thread() is not threading.main_thread():
        return

    def terminate(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, terminate)


def _goal(station: Station, text: str) -> Expr:
    """The goal; besides variables it may name predicates (`tighten_bp1.goal`)."""
    try:
        return parse_expr(text, scope_for(station.model.domains, station.predicates))
    except ExpressionError as exc:
        raise ModelError(
            [Diagnostic(SourceLocation("--goal", 1, exc.offset + 1), exc.message)]
        ) from None


def _plan(args: argparse.Namespace, started: float) -> int:
    station, text = read_station(args.model, cache=not args.no_cache)
    model = station.model
    goal = _goal(station, args.goal)
    start = _read_state(model, args.state) if args.state else tuple(model.initial_values().values())
    planner = planner_for(args, model, text, args.engine)
    query = PlanQuery(
        start,
        goal,
        max_steps=args.max_steps,
        maintenance=args.maintenance,
        disabled=frozenset() if args.restart else station.restart_transitions,
    )
    result = planner.plan(query)
    millis = round((time.perf_counter() - started) * 1000, 3)
    remember_order(args, planner, text)
    if args.json:
        print(json.dumps(_plan_json(result, millis)))
    else:
        _print_plan(result, millis)
    return 0 if result.status is PlanStatus.FOUND else 1


def _plan_json(result: PlanResult, millis: float) -> dict[str, Any]:
    if result.status is PlanStatus.FOUND:
        return {
            "status": "found",
            "length": result.length,
            "plan": list(result.plan),
            "millis": millis,
        }
    if result.status is PlanStatus.UNREACHABLE:
        return {"status": "unreachable", "max_steps": result.max_steps, "millis": millis}
    return {"status": "bad_start", "violated": list(result.violated)}


def _print_plan(result: PlanResult, millis: float) -> None:
    if result.status is PlanStatus.FOUND:
        steps = "step" if result.length == 1 else "steps"
        print(f"found a plan of {result.length} {steps} ({millis} ms, engine {result.engine})")
        for i, name in enumerate(result.plan, 1):
            print(f"{i:4}. {name}")
    elif result.status is PlanStatus.UNREACHABLE:
        print(f"unreachable: no plan of at most {result.max_steps} steps ({millis} ms)")
    else:
        print("bad start: the start state is bad for " + ", ".join(result.violated))


def _read_state(model: Model, path: str) -> State:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{path}: cannot read the state: {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        _state_error(path, exc.lineno, exc.colno, f"invalid JSON: {exc.msg}")
    if not isinstance(data, dict):
        _state_error(path, 1, 1, "the state must be a JSON object: variable name -> value")
    values: list[Any] = []
    unknown = [name for name in data if name not in model.variable_index]
    for name in unknown:
        hint = closest(name, model.variable_index)
        extra = f" (did you mean '{hint}'?)" if hint else ""
        line, column = _position_of(text, json.dumps(name))
        _state_error(path, line, column, f"unknown variable '{name}'{extra}")
    missing = [v.name for v in model.variables if v.name not in data]
    if missing:
        shown = ", ".join(missing[:8]) + (" ..." if len(missing) > 8 else "")
        _state_error(path, 1, 1, f"the state must give every variable; missing: {shown}")
    for variable in model.variables:
        raw = data[variable.name]
        value: Any = (
            raw if isinstance(raw, bool) else str(raw) if isinstance(raw, str | int) else None
        )
        if variable.is_bool and isinstance(raw, str) and raw in ("true", "false"):
            value = raw == "true"
        if (
            value is None
            or value not in variable.domain
            or (isinstance(value, bool) != variable.is_bool)
        ):
            line, column = _position_of(text, json.dumps(variable.name))
            _state_error(
                path,
                line,
                column,
                f"value {json.dumps(raw)} of '{variable.name}' is outside its domain "
                f"{variable.describe_domain()}",
            )
        values.append(value)
    return tuple(values)


def _position_of(text: str, needle: str) -> tuple[int, int]:
    index = text.find(needle)
    if index < 0:
        return 1, 1
    before = text[:index]
    return before.count("\n") + 1, index - (before.rfind("\n") + 1) + 1


def _state_error(path: str, line: int, column: int, message: str) -> NoReturn:
    raise ModelError([Diagnostic(SourceLocation(path, line, column), message)])


def _check(args: argparse.Namespace) -> int:
    station, text = read_station(args.model, cache=not args.no_cache)
    model = station.model
    planner = planner_for(args, model, text)
    report = _size_report(model, planner, reachable=args.reachable)
    if args.json:
        print(json.dumps(report))
        return 0
    print(f"{args.model}: valid")
    kinds = ", ".join(f"{n} {k}" for k, n in report["variables_by_kind"].items() if n)
    print(f"variables: {report['variables']} ({kinds})")
    print(f"flattened boolean variables: {report['boolean_variables']}")
    by_kind = ", ".join(f"{n} {k}" for k, n in report["transitions_by_kind"].items())
    print(f"transitions: {report['transitions']} ({by_kind})")
    print(f"specifications: {report['specifications']}")
    sizes = f"states: {_count_text(report['states'])}, bad: {_count_text(report['bad_states'])}"
    if "reachable_states" in report:
        sizes += f", reachable from the initial state: {_count_text(report['reachable_states'])}"
    print(sizes)
    guards = report["supervisor_guards"]
    print(f"supervisor guards added: {len(guards)}")
    for guard in guards:
        print(f"  {guard['transition']}: {guard['guard']}")
        print(f"      (forbids it in {_count_text(guard['forbidden_states'])} states)")
    return 0


def _count_text(count: int | None) -> str:
    return "more than 2^1000" if count is None else str(count)


def _size_report(model: Model, planner: Any, reachable: bool = False) -> dict[str, Any]:
    """Sizes for `sp check`; counts CUDD cannot make (over 1,000 bits, its doubles
    overflow) are None."""
    sym = planner.sym
    variable_kinds = Counter(v.kind for v in model.variables)
    transition_kinds = Counter(t.kind for t in model.transitions)
    countable = len(sym.state_bits) <= COUNTABLE_BITS

    def count(states: Any) -> int | None:
        return sym.count(states) if countable else None

    report = {
        "valid": True,
        "variables": len(model.variables),
        "variables_by_kind": {k.value: variable_kinds[k] for k in VariableKind},
        "boolean_variables": len(sym.state_bits),
        "transitions": len(model.transitions),
        "transitions_by_kind": {k.value: transition_kinds[k] for k in TransitionKind},
        "specifications": len(model.specifications),
        "states": count(sym.true),
        "bad_states": count(planner.bad),
        "supervisor_guards": [
            {
                "transition": g.transition,
                "guard": g.describe(),
                "forbidden_states": g.forbidden_states,
            }
            for g in planner.guards
        ],
    }
    if reachable:
        start = tuple(model.initial_values().values())
        report["reachable_states"] = count(planner.reachable(start))
    return report


if __name__ == "__main__":
    sys.exit(main())
