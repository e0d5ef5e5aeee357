"""Phase 3: forbidden-state recovery (DESIGN.md section 4.3, seed 000 sec. 4.4).

When the state violates a specification, production stops: the runner drops the violated
specifications, plans with maintenance transitions back to a state where every one holds,
and has a person consent to each step before it is taken.  A machine's step waits for an
operator's approval, then the runner takes it.  A person's step is an instruction: a
maintenance step is shown as such and reported done (`MaintenanceDone`), a step of a
person's resource (a watch card) is taken, which shows it; doing it is the consent.  A
rejected step (a machine's, or an instruction a person cannot follow) is left out of the
next plan.  Recovery ends when every specification holds and the state is not bad.

    no recovery --violation--> plan found: steps shown as their turn comes
    machine's step asked --approve--> approved --taken--> next step
    person's step shown (an instruction) --done--> next step
    step asked --reject--> plan made again without it
    plan shown --approve plan--> every machine step approved at once (in advance too)
    plan shown --reject plan--> plan made again without any of its machine steps
    no plan (everything rejected) --> hold: nothing moves, said once (an `error` event)
    holding --the state changes--> plan again (quietly, if still nothing)
    holding --what a rejected step reads or writes, or what planning may use, changes-->
        rejections forgotten, plan again
    every specification holds and the state is good --> recovered, production replans
"""

from __future__ import annotations

from planner.model.expressions import TRUE, variables_of
from planner.model.flat import TransitionKind
from planner.model.semantics import State
from planner.planning.query import PlanQuery
from planner.runner.automatic import violates_specifications
from planner.runner.following import follow, startable, stuck, take
from planner.runner.queries import announce, ask, disabled, no_plan_because
from planner.runner.state import TransitionPlan
from planner.runner.station_index import StationIndex
from planner.runner.tick import Tick
from planner.runner.vocabulary import EventKind, PlanLevel, RecoveryFlag, ReplanReason


def in_forbidden_state(tick: Tick) -> bool:
    """Is recovery under way, or does the state violate a specification?"""
    return tick.state.recovery is not None or violates_specifications(tick)


def announce_violation(tick: Tick) -> None:
    """Say at once, and once, which specifications the state violates: the recovery plan
    may still be in the making (a slow planner), but people must know now."""
    violated = tuple(tick.index.semantics.violated(tick.current()))
    if violated and violated != tick.state.announced:
        tick.emit(EventKind.FORBIDDEN, ", ".join(violated), violated=list(violated))
    tick.state.announced = violated or tick.state.announced


def recover(tick: Tick) -> None:
    state = tick.state
    violated = tick.index.semantics.violated(tick.current())
    if state.recovery is None:
        if not violated:
            state.recovery_held = None
            state.announced = ()
            return
        kept = holding(tick)
        if kept is None:
            return
        plan_recovery(tick, violated, quiet=kept)
    plan = state.recovery
    if plan is None:
        return
    if not violated and not tick.runner.is_bad(tick.current()):
        tick.emit(EventKind.RECOVERED, "all specifications hold", relaxed=sorted(state.relaxed))
        state.announced = ()
        state.recovery = None
        state.relaxed = frozenset()
        state.rejected.clear()
        tick.replan_operations(ReplanReason.RECOVERED)
        tick.replan_transitions(ReplanReason.RECOVERED)
        return
    if stuck(tick, plan, "recovery plan"):  # planned again; approvals given so far are void
        state.recovery = None
        plan_recovery(tick, violated)
        if state.recovery is None:
            return
        plan = state.recovery
    for k in startable(tick, plan):
        name = plan.blocks[k].transition
        kind = tick.index.kind_of(name)
        if k not in plan.asked:
            plan.asked.add(k)
            what = tick.index.describe(name)
            if kind is TransitionKind.MAINTENANCE:
                plan.approved.add(k)  # a person's step: doing it is the consent
                of = len(plan.blocks)
                tick.emit(EventKind.INSTRUCTION, name, step=k, of=of, what=what, recovery=True)
            elif name in tick.index.person_transitions:
                plan.approved.add(k)  # the person's own card: showing it asks them
            elif k in plan.approved:
                pass  # approved in advance with the whole plan (`ApprovePlan`): not asked again
            else:
                tick.emit(EventKind.APPROVAL, name, step=k, type=kind.value, what=what)
        if k not in plan.approved or kind is TransitionKind.MAINTENANCE:
            continue  # waits for approval, or for the operator to report it done
        take(tick, plan, k, supervised=False)


def needs_approval(index: StationIndex, plan: TransitionPlan) -> list[int]:
    """The plan's machine steps not yet approved nor taken, in plan order: what one approval
    of the whole plan covers (a person's steps are consented to by doing them)."""
    return [
        k
        for k, block in enumerate(plan.blocks)
        if k not in plan.approved and k not in plan.taken and not _persons(index, block.transition)
    ]


def numbered(index: StationIndex, plan: TransitionPlan, k: int) -> tuple[int, int]:
    """Step k as people see it numbered (1-based): a machine step among the plan's machine
    steps, a person's step among the person's steps ("step 2 of 6")."""
    person = _persons(index, plan.blocks[k].transition)
    same = [j for j, b in enumerate(plan.blocks) if _persons(index, b.transition) == person]
    return same.index(k) + 1, len(same)


def _persons(index: StationIndex, name: str) -> bool:
    return index.kind_of(name) is TransitionKind.MAINTENANCE or name in index.person_transitions


def holding(tick: Tick) -> bool | None:
    """Recovery found no plan here: plan again only once something changed (the state, or
    what planning may use), never tick after tick (None: hold).  A rejection stands while
    nothing it depends on changed: a step is rejected for the state it would act in, and
    other work coming to an end (a person's card, a robot arriving) does not make it
    acceptable; what the station has learned from a change that leaves the rejections
    standing is only whether a new way out appeared (True: plan again, quietly if not)."""
    state = tick.state
    if state.recovery_held is None:
        return False
    held_at, held_disabled = state.recovery_held
    now_disabled = disabled(tick)
    if (held_at, held_disabled) == (tick.current(), now_disabled):
        return None
    state.recovery_held = None
    if held_disabled != now_disabled or touches_rejected(tick, held_at):
        state.rejected.clear()
        return False
    return True


def touches_rejected(tick: Tick, before: State) -> bool:
    """Whether a variable a rejected step reads or writes changed since `before`."""
    model = tick.index.model
    touched: set[str] = set()
    for name in tick.state.rejected:
        transition = model.transition(name)
        touched |= variables_of(transition.guard) | {a.target for a in transition.actions}
    now = tick.current()
    return any(before[model.variable_index[v]] != now[model.variable_index[v]] for v in touched)


def plan_recovery(tick: Tick, violated: list[str], *, quiet: bool = False) -> None:
    """A plan back to a state where every specification holds, without rejected steps;
    `quiet`: no plan was found before with these rejections, and that was said."""
    state = tick.state
    state.relaxed = frozenset(violated)
    query = PlanQuery(
        tick.current(),
        TRUE,
        tick.config.max_steps,
        maintenance=True,
        disabled=disabled(tick) | state.rejected,
        relaxed=state.relaxed,
    )
    result, millis = ask(tick, PlanLevel.TRANSITIONS, query, "forbidden-state recovery")
    flags = (RecoveryFlag.MAINTENANCE,)
    announce(tick, PlanLevel.TRANSITIONS, flags, ReplanReason.FORBIDDEN_STATE, result, millis)
    if not result.found:
        state.recovery_held = (tick.current(), disabled(tick))
        if quiet:
            return
        usual = "every way out was rejected" if state.rejected else "no way out exists"
        why = no_plan_because(result, usual)
        tick.emit(
            EventKind.ERROR,
            "no recovery plan",
            why=f"{why}; nothing moves until the state changes or a person puts it right",
            violated=violated,
            rejected=sorted(state.rejected),
        )
        return
    state.recovery = follow(tick, TRUE, result)
    if not state.recovery.blocks:
        state.recovery = None
