"""Running another model version: made ready beside the loop, then swapped in one round.

What takes time (the new version's planners, its planning worker, a simulated world of the
new model) is made off the loop by `prepare`; the loop then only swaps (`activate`): the
runner's state carried over to the new model (`planner.runner.carry_over`), the devices
going on from where they are, the alarm book and the run kept.  The station must be idle or
in restart mode (`busy`): a model is not changed under a running operation.
"""

from __future__ import annotations

import hashlib
import threading
from dataclasses import dataclass

from app.station.cycle import StationCycle
from app.station.planning_worker import PlanningWorker
from app.station.rounds import Round
from app.station.running import Running, runner_for
from app.station.view import ActiveModel
from app.store.audit import AuditEntry, AuditKind
from hw.devices import Devices
from planner.runner import IntentionState, OperationState, Runner, RunnerState
from planner.runner.carry_over import carry_over


@dataclass(frozen=True)
class Prepared:
    """A model version ready to run: its runner, its planning worker, its devices."""

    model: ActiveModel
    runner: Runner
    worker: PlanningWorker | None
    devices: Devices

    def discard(self, current: Devices) -> None:
        """Not taken after all: what was made for it is stopped (not the running devices)."""
        if self.worker is not None:
            self.worker.close()
        if self.devices is not current:
            self.devices.close()


def busy(state: RunnerState) -> str:
    """Why a model cannot be swapped now ("" when it can)."""
    if state.restart_mode:
        return ""
    executing = state.intentions_in(IntentionState.EXECUTING)
    executing += state.operations_in(OperationState.EXECUTING)
    if executing:
        return "the station is running " + ", ".join(sorted(executing)[:5])
    return ""


def prepare(running: Running, model: ActiveModel) -> Prepared:
    """What running `model` needs that takes time, made beside the loop (a caller's thread):
    the devices are only asked for their successor, which reads none of their live state."""
    worker = running.planning.worker(model)
    runner = runner_for(model, running.config, worker)
    return Prepared(model, runner, worker, running.devices.for_model(model.station))


def activate(running: Running, round_: Round, prepared: Prepared, user: str) -> None:
    """Swap in `prepared` in this round (the caller checked `busy`)."""
    old, old_worker, old_devices = running.model, running.worker, running.devices
    running.model, running.worker = prepared.model, prepared.worker
    if old_worker is not None:  # its process may take a while to end: not in the loop
        threading.Thread(target=old_worker.close, name="old-planning-worker").start()
    prepared.runner.learned = running.durations.medians()  # read here, in the loop
    state = carry_over(running.state, prepared.runner, round_.now)
    devices = prepared.devices
    if devices is not old_devices:  # a simulated world of the new model takes up the old one
        devices.restore(old_devices.dump(round_.now), round_.now)
        old_devices.close()
    running.cycle = StationCycle(prepared.runner, devices, state)
    detail = {
        "version": prepared.model.number,
        "previous": old.number,
        "sha256": hashlib.sha256(prepared.model.text.encode()).hexdigest(),  # what ran
    }
    round_.record(AuditEntry(AuditKind.MODEL, "activated", user, "", detail))
