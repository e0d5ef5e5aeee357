"""Modbus TCP devices in one process, each on its own address, with faults on demand.

    python -m hw.modbus.emulator.server --device nutrunner:nr:127.0.0.20:1502 \\
        --device connector:r1_tc:127.0.0.21:1502:1 [--control 127.0.0.20:1600]

Each `--device KIND:NAME:HOST:PORT[:DEVICE_ID]` gets a pymodbus TCP server (port 0: any free
one) serving the kind's register map (`hw.modbus.emulator.kinds`) with its logic; unit id
`DEVICE_ID` (default 1), any other unit id is answered with exception 11 (gateway target
failed to respond).  Once every server listens it prints one line,
`{"ready": true, "ports": {NAME: PORT, ..., "control": PORT}}`, and serves until SIGTERM.

The control channel (`hw.emulator_kit.control`, default on the first device's host, any free
port) takes `{"op": OP, "device": NAME, ...}`; `device` may be left out when the process
serves one device.  The operations are in `hw.modbus.emulator.operations`, with their JSON in
`docs/modbus_devices.md`.

The device's logic steps on every request and every control operation, at the emulator's
clock (which stops while the device is frozen); nothing runs between requests.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import signal
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from hw.emulator_kit.control import serve_control
from hw.emulator_kit.process import exit_with_parent
from hw.modbus.emulator.kinds import KINDS
from hw.modbus.emulator.logic import DeviceLogic
from hw.modbus.emulator.operations import OPERATIONS
from hw.modbus.registers import Point, RegisterMap, Table

log = logging.getLogger(__name__)
NETWORK_MODES = ("up", "silent", "refuse")
_TABLE_OF_FUNCTION = {1: Table.COIL, 5: Table.COIL, 15: Table.COIL, 2: Table.DISCRETE_INPUT}
_TABLE_OF_FUNCTION.update({3: Table.HOLDING_REGISTER, 6: Table.HOLDING_REGISTER})
_TABLE_OF_FUNCTION.update({16: Table.HOLDING_REGISTER, 4: Table.INPUT_REGISTER})


@dataclass(frozen=True)
class DeviceSpec:
    kind: str
    name: str
    host: str
    port: int
    device_id: int = 1

    @classmethod
    def parse(cls, text: str) -> DeviceSpec:
        parts = text.split(":")
        if len(parts) not in (4, 5):
            raise ValueError(f"'{text}' is not KIND:NAME:HOST:PORT[:DEVICE_ID]")
        if parts[0] not in KINDS:
            raise ValueError(f"'{parts[0]}' is no device kind; known: {', '.join(KINDS)}")
        try:
            numbers = [int(p) for p in parts[3:]]
        except ValueError:
            raise ValueError(f"'{text}': port and device id are numbers") from None
        if not 0 <= numbers[0] <= 65535 or not all(0 <= n <= 255 for n in numbers[1:]):
            raise ValueError(f"'{text}': port 0..65535, device id 0..255")
        return cls(parts[0], parts[1], parts[2], *numbers)


class EmulatedDevice:
    """One device: its logic, its Modbus server and its network and data faults."""

    def __init__(self, spec: DeviceSpec, delay_scale: float = 1.0) -> None:
        self.spec = spec
        self.port = spec.port
        self.delay_scale = delay_scale
        self.network = "up"
        self.frozen_since: float | None = None
        self.frozen_total = 0.0
        self.garbage = 0
        self.garbage_kind = "noise"
        self.server: ModbusTcpServer | None = None
        self.logic = self._power_on()

    @property
    def map(self) -> RegisterMap:
        return self.logic.register_map

    def _power_on(self) -> DeviceLogic:
        kind = KINDS[self.spec.kind]
        timing = {k: v * self.delay_scale for k, v in kind.timing_defaults.items()}
        return kind(self.clock(), timing)

    def clock(self) -> float:
        """The device's own time: monotonic seconds, standing still while frozen."""
        now = time.monotonic() if self.frozen_since is None else self.frozen_since
        return now - self.frozen_total

    def step(self) -> None:
        if self.frozen_since is None:
            self.logic.step(self.clock())

    async def listen(self) -> None:
        server = ModbusTcpServer(
            self._sim_devices(), address=(self.spec.host, self.port), trace_packet=self._trace
        )
        await server.serve_forever(background=True)
        sockets = cast(asyncio.Server, server.transport).sockets
        self.port = sockets[0].getsockname()[1]
        self.server = server

    async def close(self) -> None:
        if self.server is not None:
            await self.server.shutdown()  # type: ignore[no-untyped-call]
            self.server = None

    def _sim_devices(self) -> list[SimDevice]:
        devices = [SimDevice(id=self.spec.device_id, simdata=self._blocks(), action=self._action)]
        if self.spec.device_id != 0:
            devices.append(SimDevice(id=0, simdata=self._blocks(), action=_no_such_unit))
        return devices

    def _blocks(self) -> tuple[list[SimData], list[SimData], list[SimData], list[SimData]]:
        blocks: list[list[SimData]] = []
        for table in (Table.COIL, Table.DISCRETE_INPUT, Table.HOLDING_REGISTER):
            blocks.append(self._block(table))
        blocks.append(self._block(Table.INPUT_REGISTER))
        return blocks[0], blocks[1], blocks[2], blocks[3]

    def _block(self, table: Table) -> list[SimData]:
        registers = self.map.table(table)
        count = registers[-1].point.address + 1 if registers else 1
        if table.is_bit:
            return [SimData(0, count=count, values=False, datatype=DataType.BITS)]
        if not registers:  # every address refused
            return [SimData(0, datatype=DataType.INVALID)]
        return [SimData(0, count=count, values=0, datatype=DataType.REGISTERS)]

    async def _action(
        self,
        function_code: int,
        start: int,
        address: int,
        count: int,
        registers: list[int],
        values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        """pymodbus asks before every read and write: answer from the device's logic."""
        try:
            return self._answer(function_code, start, address, count, registers, values)
        except Exception:  # a bug in a device's logic: said on stderr, answered as Modbus does
            log.exception("%s: the device's logic failed", self.spec.name)
            return ExcCodes.DEVICE_FAILURE

    def _answer(
        self,
        function_code: int,
        start: int,
        address: int,
        count: int,
        registers: list[int],
        values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        if self.network != "up":
            return ExcCodes.DEVICE_BUSY  # not seen: the answer is dropped (`_trace`)
        table = _TABLE_OF_FUNCTION[function_code]
        if values is not None:
            points = [Point(table, address + k) for k in range(len(values))]
        elif table.is_bit:  # pymodbus gives the count in words here: check the first bit
            points = [Point(table, address)]
        else:
            points = [Point(table, address + k) for k in range(count)]
        if any(self.map.at(p) is None for p in points):
            return ExcCodes.ILLEGAL_ADDRESS
        self.step()
        if values is not None:
            for point, value in zip(points, values, strict=True):
                self.logic.write(point, int(value))
            self.step()
        self._fill(table, start, registers)
        return None

    def _fill(self, table: Table, start: int, registers: list[int]) -> None:
        documented = self.map.table(table)
        if table.is_bit:
            for k in range(len(registers) - 1):
                registers[k] = 0
            for register in documented:
                address = register.point.address
                if self.logic.raw[register.point]:
                    registers[address // 16 - start] |= 1 << (address % 16)
        else:
            for register in documented:
                registers[register.point.address - start] = self.logic.raw[register.point]

    def _trace(self, sending: bool, frame: bytes) -> bytes:
        """Every frame the server sends passes here: the network and garbage faults."""
        if not sending:
            return frame
        if self.network != "up":
            return b""
        if self.garbage > 0 and len(frame) >= 8:
            self.garbage -= 1
            return corrupt(frame, self.garbage_kind)
        return frame

    async def set_network(self, mode: str) -> None:
        if mode not in NETWORK_MODES:
            raise ValueError(f"network mode is one of {', '.join(NETWORK_MODES)}, not {mode!r}")
        self.network = mode
        if mode == "refuse":
            await self.close()
        elif self.server is None:
            await self.listen()

    def freeze(self, frozen: bool) -> None:
        if frozen and self.frozen_since is None:
            self.step()
            self.frozen_since = time.monotonic()
        elif not frozen and self.frozen_since is not None:
            self.frozen_total += time.monotonic() - self.frozen_since
            self.frozen_since = None

    def restart(self) -> None:
        """A power cycle: every register back to its initial value, no faults, not frozen."""
        self.freeze(False)
        self.garbage = 0
        self.logic = self._power_on()

    def state(self) -> dict[str, Any]:
        self.step()
        return {
            "device": self.spec.name,
            **self.logic.state(),
            "network": self.network,
            "frozen": self.frozen_since is not None,
            "garbage": {"count": self.garbage, "kind": self.garbage_kind},
            "port": self.port,
            "device_id": self.spec.device_id,
        }


async def _no_such_unit(*_: object) -> ExcCodes | None:
    return ExcCodes.GATEWAY_NO_RESPONSE


def corrupt(frame: bytes, kind: str) -> bytes:
    """A malformed version of an answer frame (MBAP header + PDU)."""
    function = frame[7]
    if kind == "function":  # a function code no request had
        return frame[:7] + b"\x63" + frame[8:]
    if kind == "wrong_id":  # the answer to another transaction
        tid = (int.from_bytes(frame[:2], "big") + 1) & 0xFFFF
        return tid.to_bytes(2, "big") + frame[2:]
    if kind == "other_unit":  # this transaction's answer, from another unit behind the address
        return frame[:6] + bytes([frame[6] % 247 + 1]) + frame[7:]
    if kind == "short" and function in (1, 2, 3, 4):  # no values at all
        return frame[:4] + b"\x00\x03" + frame[6:8] + b"\x00"
    if kind == "short" and function in (5, 6):  # the echo names another address
        address = (int.from_bytes(frame[8:10], "big") + 1) & 0xFFFF
        return frame[:8] + address.to_bytes(2, "big") + frame[10:]
    return b"\xde\xad\xbe\xef\x00\x05\x01\x99\x99\x99\x99"  # not Modbus at all


class Emulator:
    """The devices of one process and their control channel."""

    def __init__(self, specs: Sequence[DeviceSpec], delay_scale: float = 1.0) -> None:
        names = [s.name for s in specs]
        if len(set(names)) != len(names) or "control" in names:
            raise ValueError("device names must differ from each other and from 'control'")
        self.devices = {s.name: EmulatedDevice(s, delay_scale) for s in specs}
        self.ops = OPERATIONS

    async def handle(self, request: dict[str, Any]) -> dict[str, Any]:
        op = request["op"]
        if op == "devices":
            return {
                "devices": {
                    name: {"kind": d.spec.kind, "port": d.port, "device_id": d.spec.device_id}
                    for name, d in self.devices.items()
                }
            }
        if op not in self.ops:
            raise ValueError(f"no operation '{op}'; known: devices, {', '.join(self.ops)}")
        name = request.get("device")
        if name is None and len(self.devices) == 1:
            name = next(iter(self.devices))
        if name not in self.devices:
            raise ValueError(f"no device {name!r}; known: {', '.join(self.devices)}")
        device = self.devices[name]
        device.step()  # what the operation changes, it changes now
        return await self.ops[op](device, request)


async def serve(specs: Sequence[DeviceSpec], control: tuple[str, int], scale: float) -> None:
    emulator = Emulator(specs, scale)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for signum in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(signum, stop.set)
    try:
        for device in emulator.devices.values():
            await device.listen()
        channel = await serve_control(*control, emulator.handle)
        ports = {name: d.port for name, d in emulator.devices.items()}
        ports["control"] = channel.sockets[0].getsockname()[1]
        print(json.dumps({"ready": True, "ports": ports}), flush=True)
        await stop.wait()
        channel.close()
    finally:
        for device in emulator.devices.values():
            await device.close()


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m hw.modbus.emulator.server", description=__doc__
    )
    parser.add_argument("--device", action="append", required=True, metavar="KIND:NAME:HOST:PORT")
    parser.add_argument("--control", metavar="HOST:PORT", help="default: first device's host")
    parser.add_argument(
        "--delay-scale", type=float, default=1.0, help="multiplies every device delay"
    )
    args = parser.parse_args(argv)
    try:
        specs = [DeviceSpec.parse(text) for text in args.device]
        names = [spec.name for spec in specs]
        if len(set(names)) != len(names) or "control" in names:
            raise ValueError("device names must differ from each other and from 'control'")
        host, _, port = (args.control or f"{specs[0].host}:0").rpartition(":")
        control = (host, int(port))
    except ValueError as problem:
        parser.error(str(problem))
    if not args.delay_scale >= 0:
        parser.error("--delay-scale is a number >= 0")
    logging.basicConfig(format="%(name)s: %(message)s")
    exit_with_parent()
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)  # chatter about closed clients
    asyncio.run(serve(specs, control, args.delay_scale))
    return 0


if __name__ == "__main__":
    sys.exit(main())
