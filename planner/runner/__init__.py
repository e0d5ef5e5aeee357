"""The runner (DESIGN.md section 4, seed 000 sec. 4): the one place live state changes.

`Runner.tick` runs the phases of a tick in the order `run_tick` gives; each phase is a
module named after what it does:

    observing      1. what the devices report: availability, effects, unexpected changes
    people         people's actions (restart mode's in `restart`)
    automatic      2. automatic transitions to a fixpoint; violated specifications
    forbidden      3. forbidden-state recovery, each step approved; nothing else runs
    intentions     4. intentions start and finish
    operations     5. the operation plan: finish, plan (error propagation), start
    transitions    6. the transition plan for the executing operations
    restart        6. in restart mode instead: the resets; also estimates, restart abilities
    following         taking a plan's steps in its start order; checking its rest
    maintenance       after errors: the operator's maintenance steps
    effects        7. effect time-outs
    background        the background check of what is in error, when it is due
    queries           planning queries: their labels, the monotonic abstraction, timing
    retries           failures counted per operation; an operation out of retries fails

Besides `run_tick`, a phase's step runs inside another phase where the paper's order needs it:

    automatic.settle               also entered from `following.take`, after every step
                                   it takes (phases 3 and 6, maintenance, the resets)
    operations.plan_operations     also entered from itself, for the intentions that do
                                   not fail
    maintenance.plan_maintenance   also entered from `operations.plan_operations` (after
                                   intentions fail, once the operations still executing
                                   have come to rest) and `background.background_check`
    retries.failed_attempt         also entered from phase 1, when an effect other than the
                                   expected one happens: an operation out of retries fails,
                                   which drops the transition plan and asks for a new
                                   operation plan before phases 5 and 6 run

`vocabulary` holds the typed words (life cycles, plan labels, reasons, event kinds),
`state` the live state and its plans, `snapshot` their JSON form, `carry_over` the move to
a new model version.
"""

from planner.runner.actions import (
    Action,
    Approve,
    ApprovePlan,
    CancelIntention,
    EnterRestart,
    LeaveRestart,
    MaintenanceDone,
    ReenableEffect,
    Reject,
    RejectPlan,
    Reply,
    ResetOperation,
    SetEstimated,
    StartIntention,
)
from planner.runner.answers import QueryObserver
from planner.runner.runner import Runner, run_tick
from planner.runner.state import OperationPlan, RunnerState, TransitionPlan
from planner.runner.tick_io import Event, Inputs, RunnerConfig, TickResult
from planner.runner.vocabulary import (
    EventKind,
    IntentionState,
    OperationState,
    PlanLevel,
    RecoveryFlag,
    ReplanReason,
    plan_label,
)

__all__ = [
    "Action",
    "Approve",
    "ApprovePlan",
    "CancelIntention",
    "EnterRestart",
    "Event",
    "EventKind",
    "Inputs",
    "IntentionState",
    "LeaveRestart",
    "MaintenanceDone",
    "OperationPlan",
    "OperationState",
    "PlanLevel",
    "QueryObserver",
    "RecoveryFlag",
    "ReenableEffect",
    "Reject",
    "RejectPlan",
    "ReplanReason",
    "Reply",
    "ResetOperation",
    "Runner",
    "RunnerConfig",
    "RunnerState",
    "SetEstimated",
    "StartIntention",
    "TickResult",
    "TransitionPlan",
    "plan_label",
    "run_tick",
]
