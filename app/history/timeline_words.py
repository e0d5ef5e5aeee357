"""A timeline's words for what the station did to recover, and for injected faults."""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from hw.faults import FaultKind
from planner.planning.query import PlanStatus
from planner.reading.display import humanised
from planner.words import Wording, replan_words

_SETTING = re.compile(r"(\w+)=([\w.]+)")


def plan_words(detail: Mapping[str, Any]) -> str:
    """A recovery's planning in words: why, and what came of it (the paper's label, such as
    "TP w/RTO", stays out: people read this)."""
    length = int(detail.get("length", 0) or 0)
    found = detail.get("status") == PlanStatus.FOUND.value
    result = f"a plan of {length} step{'' if length == 1 else 's'}" if found else "no plan"
    return f"{replan_words(str(detail.get('reason', '')))}: {result}"


def fault_words(text: str, words: Wording) -> str:
    """A fault injected into the simulated world ("kind=disconnect, resource=r2") in words."""
    parts = dict(_SETTING.findall(text))
    kind, resource, effect = parts.get("kind", ""), parts.get("resource"), parts.get("effect")
    if resource and kind in (FaultKind.DISCONNECT, FaultKind.RECONNECT):
        verb = "stops answering" if kind == FaultKind.DISCONNECT else "answers again"
        return f"simulated fault: {words.resource(resource)} {verb}"
    if effect:
        return f"simulated fault: {words.transition(effect)} ({humanised(kind)})"
    return f"simulated fault: {humanised(kind) or words.text(text)}"
