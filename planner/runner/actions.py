"""What people do to the runner (operators, engineers, line systems), and its reply to each.

Every action carries the `user` who did it, which the runner records in its events.  The
runner answers each action of a tick with a `Reply`: accepted, or refused with the reason in
words a person can act on.
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.model.expressions import Value


@dataclass(frozen=True)
class Action:
    """Something a person did; `user` is recorded with it."""

    user: str = "operator"


@dataclass(frozen=True)
class StartIntention(Action):
    name: str = ""


@dataclass(frozen=True)
class CancelIntention(Action):
    name: str = ""


@dataclass(frozen=True)
class Approve(Action):
    """Approve step `step` of the forbidden-state recovery plan."""

    step: int = 0


@dataclass(frozen=True)
class Reject(Action):
    """Reject step `step` of the forbidden-state recovery plan: plan again without it."""

    step: int = 0


@dataclass(frozen=True)
class ApprovePlan(Action):
    """Approve, in one decision, every machine step of the forbidden-state recovery plan
    not yet approved: `steps` are their transitions in plan order, as the person was shown
    them (a plan that changed meanwhile is refused, not approved unseen).  Steps whose turn
    has not come are approved in advance: no approval is asked for them again."""

    steps: tuple[str, ...] = ()


@dataclass(frozen=True)
class RejectPlan(Action):
    """Refuse the recovery plan shown (`steps`, as for `ApprovePlan`) in one decision: every
    one of its machine steps is left out of the next plan, as `Reject` leaves out one."""

    steps: tuple[str, ...] = ()


@dataclass(frozen=True)
class MaintenanceDone(Action):
    """The operator has carried out maintenance transition `transition` in the world."""

    transition: str = ""


@dataclass(frozen=True)
class EnterRestart(Action):
    reason: str = ""


@dataclass(frozen=True)
class LeaveRestart(Action):
    pass


@dataclass(frozen=True)
class SetEstimated(Action):
    """Set an estimated or decision variable to match reality (restart mode, with a reason)."""

    variable: str = ""
    value: Value = False
    reason: str = ""


@dataclass(frozen=True)
class ResetOperation(Action):
    """Restart mode: put an operation back to initial and plan to reach its precondition."""

    name: str = ""


@dataclass(frozen=True)
class ReenableEffect(Action):
    """Let planning use a timed-out effect again (a person fixed what stopped it)."""

    name: str = ""


@dataclass(frozen=True)
class Reply:
    """The runner's answer to one action: accepted, or refused and why."""

    action: Action
    accepted: bool
    why: str = ""
    subject: str = ""  # what a refusal is about (an intention, a step, a variable)

    @staticmethod
    def accept(action: Action) -> Reply:
        return Reply(action, True)

    @staticmethod
    def refuse(action: Action, subject: str, why: str) -> Reply:
        return Reply(action, False, why, subject)

    def __str__(self) -> str:
        return "accepted" if self.accepted else f"{self.subject}: {self.why}"
