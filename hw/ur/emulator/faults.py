"""The UR emulator's control-channel operations: its state, faults on demand, people's hands.

Each operation is one JSON object (`docs/ur_emulator.md` lists them with examples).  A fault
stays until the same operation ends it; the control channel itself never plays a fault.
"""

from __future__ import annotations

import math
from collections.abc import Awaitable, Callable
from typing import Any, Protocol

from hw.ur.emulator.controller import Controller, RobotMode, RuntimeState, SafetyMode


class ControlledEmulator(Protocol):
    """What the operations use of the emulator they act on (`server.Emulator` is one)."""

    @property
    def controller(self) -> Controller: ...

    @property
    def network(self) -> str: ...  # "", "silent" or "refuse"

    @property
    def frozen(self) -> dict[str, Any] | None: ...

    def connection_counts(self) -> dict[str, int]: ...

    async def set_network(self, down: bool, mode: str = "silent") -> None: ...

    def freeze(self, on: bool) -> None: ...


Operation = Callable[[ControlledEmulator, dict[str, Any]], Awaitable[dict[str, Any]]]


async def handle(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    operation = OPERATIONS.get(request["op"])
    if operation is None:
        raise ValueError(f"no operation {request['op']!r}; known: {', '.join(sorted(OPERATIONS))}")
    return await operation(emulator, request)


def _joints(value: Any, name: str) -> list[float]:
    if not isinstance(value, list) or len(value) != 6:
        raise ValueError(f"'{name}' is a list of 6 numbers")
    numbers = [float(x) for x in value]
    if not all(math.isfinite(x) for x in numbers):
        raise ValueError(f"'{name}' must be finite")
    return numbers


def _flag(request: dict[str, Any], name: str = "on") -> bool:
    value = request.get(name, True)
    if not isinstance(value, bool):
        raise ValueError(f"'{name}' is true or false")
    return value


def faults(emulator: ControlledEmulator) -> list[str]:
    c = emulator.controller
    active = []
    if emulator.network:
        active.append(f"network {emulator.network}")
    if emulator.frozen is not None:
        active.append("freeze")
    if c.stalled:
        active.append("stall")
    if c.safety_mode == SafetyMode.PROTECTIVE_STOP:
        active.append("protective stop")
    if c.robot_mode == RobotMode.POWER_OFF:
        active.append("power off")
    return active


async def state(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    c = emulator.controller
    script = c.script
    return {
        "joints": list(c.arm.q),
        "target": list(c.arm.target) if c.arm.target is not None else None,
        "goal": list(script.move.goal) if script is not None and script.move else None,
        "steady": c.arm.steady,
        "robot_mode": RobotMode(c.robot_mode).name,
        "safety": SafetyMode(c.safety_mode).name,
        "runtime_state": RuntimeState(c.runtime).name,
        "faults": faults(emulator),
        "connections": emulator.connection_counts(),
        "tcp": list(c.tcp),
        "payload": c.payload,
        "payload_cog": list(c.payload_cog),
        "script_error": c.script_error,
        "timestamp": c.timestamp,
        "inputs": {k: v for k, v in c.inputs.items() if isinstance(v, int | float)},
    }


async def network(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    await emulator.set_network(_flag(request, "down"), str(request.get("mode", "silent")))
    return {"faults": faults(emulator)}


async def freeze(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    emulator.freeze(_flag(request))
    return {"faults": faults(emulator)}


async def protective_stop(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    if _flag(request):
        emulator.controller.protective_stop()
    else:
        emulator.controller.unlock_protective_stop()
    return {"faults": faults(emulator)}


async def stall(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    emulator.controller.stall(_flag(request))
    return {"faults": faults(emulator)}


async def push(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    emulator.controller.push(_joints(request.get("offset"), "offset"))
    return {"joints": list(emulator.controller.arm.q)}


async def jog(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    emulator.controller.jog(_joints(request.get("joints"), "joints"))
    return {"joints": list(emulator.controller.arm.q)}


async def power(emulator: ControlledEmulator, request: dict[str, Any]) -> dict[str, Any]:
    c = emulator.controller
    if not _flag(request):
        c.power_off()
    elif "brake_release" in request and _flag(request, "brake_release"):
        c.brake_release(c.clock)
    else:
        c.power_on(c.clock)
    return {"faults": faults(emulator)}


OPERATIONS: dict[str, Operation] = {
    "state": state,
    "network": network,
    "freeze": freeze,
    "protective_stop": protective_stop,
    "stall": stall,
    "push": push,
    "jog": jog,
    "power": power,
}
