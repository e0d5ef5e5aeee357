"""The emulator's control operations: what a test, a scenario or the simulation panel may do
to a device.  Each takes the device and the request, and answers with the device's state
(`docs/modbus_devices.md` lists them with their JSON).
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any, Protocol, TypeVar

from hw.modbus.emulator.camera import Camera
from hw.modbus.emulator.connector import Connector, LockFault
from hw.modbus.emulator.logic import DeviceLogic, Shots
from hw.modbus.emulator.nutrunner import Nutrunner
from hw.modbus.registers import RegisterMap, encode

L = TypeVar("L", bound=DeviceLogic)
GARBAGE_KINDS = ("noise", "function", "short", "wrong_id", "other_unit")


class Named(Protocol):
    @property
    def name(self) -> str: ...

    @property
    def kind(self) -> str: ...


class ControlledDevice(Protocol):
    """What the operations use of the device they act on (`server.EmulatedDevice` is one)."""

    garbage: int  # answers still to be corrupted
    garbage_kind: str

    @property
    def spec(self) -> Named: ...

    @property
    def logic(self) -> DeviceLogic: ...

    @property
    def map(self) -> RegisterMap: ...

    async def set_network(self, mode: str) -> None: ...

    def freeze(self, frozen: bool) -> None: ...

    def restart(self) -> None: ...

    def state(self) -> dict[str, Any]: ...


async def _state(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    return device.state()


async def _network(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    await device.set_network(request.get("mode", "up"))
    return device.state()


async def _freeze(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    frozen = request.get("frozen", True)
    if not isinstance(frozen, bool):
        raise ValueError("'frozen' is true or false")
    device.freeze(frozen)
    return device.state()


async def _set(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    values, raw = request.get("values"), request.get("raw", False)
    if not isinstance(values, dict) or not values or not isinstance(raw, bool):
        raise ValueError('set takes {"values": {NAME: VALUE, ...}, "raw": false}')
    for name, value in values.items():  # all or nothing
        encode(device.map[name], value, raw=raw)
    for name, value in values.items():
        device.logic.set(name, value, raw=raw)
    return device.state()


async def _stuck(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    name = request.get("name")
    if not isinstance(name, str):
        raise ValueError('stuck takes {"name": SENSOR, "value": VALUE (default: as it is)}')
    device.logic.stick(name, request.get("value"), raw=request.get("raw", False))
    return device.state()


async def _nok(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    _logic(device, Nutrunner, "nok").nok_fault = Shots.from_request(request)
    return device.state()


async def _engage(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    on = request.get("on", True)
    if not isinstance(on, bool):
        raise ValueError("'on' is true or false")
    _logic(device, Nutrunner, "engage").engaged = on
    return device.state()


async def _lock_fails(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    mode = request.get("mode", "never")
    if mode not in [m.value for m in LockFault]:
        raise ValueError(f"lock_fails mode is never or failure, not {mode!r}")
    _logic(device, Connector, "lock_fails").fail_locks(Shots.from_request(request), LockFault(mode))
    return device.state()


async def _unlock_fails(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    _logic(device, Connector, "unlock_fails").fail_unlocks(Shots.from_request(request))
    return device.state()


async def _miss(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    _logic(device, Camera, "miss").miss_fault = Shots.from_request(request)
    return device.state()


async def _scene(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    pose = request.get("pose")
    if not isinstance(pose, list) or len(pose) != 6:
        raise ValueError('scene takes {"pose": [x, y, z, rx, ry, rz]} (mm, rad)')
    x, y, z, rx, ry, rz = (float(v) for v in pose)
    _logic(device, Camera, "scene").see((x, y, z, rx, ry, rz))
    return device.state()


async def _garbage(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    count, kind = request.get("count", 1), request.get("kind", "noise")
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise ValueError("garbage 'count' is a number of answers: 0, 1, 2 ...")
    if kind not in GARBAGE_KINDS:
        raise ValueError(f"garbage 'kind' is one of {', '.join(GARBAGE_KINDS)}, not {kind!r}")
    device.garbage, device.garbage_kind = count, kind
    return device.state()


async def _timing(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    values = request.get("values")
    if not isinstance(values, dict):
        raise ValueError('timing takes {"values": {DELAY: SECONDS, ...}}')
    device.logic.set_timing(values)
    return device.state()


async def _reset(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    device.logic.reset()
    device.garbage = 0
    return device.state()


async def _restart(device: ControlledDevice, request: dict[str, Any]) -> dict[str, Any]:
    device.restart()
    return device.state()


def _logic(device: ControlledDevice, kind: type[L], op: str) -> L:
    if not isinstance(device.logic, kind):
        raise ValueError(f"{device.spec.name} is a {device.spec.kind}: it has no '{op}'")
    return device.logic


Operation = Callable[[ControlledDevice, dict[str, Any]], Awaitable[dict[str, Any]]]
OPERATIONS: dict[str, Operation] = {
    "state": _state,
    "network": _network,
    "freeze": _freeze,
    "set": _set,
    "stuck": _stuck,
    "nok": _nok,
    "engage": _engage,
    "lock_fails": _lock_fails,
    "unlock_fails": _unlock_fails,
    "miss": _miss,
    "scene": _scene,
    "garbage": _garbage,
    "timing": _timing,
    "reset": _reset,
    "restart": _restart,
}
