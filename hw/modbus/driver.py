"""The station's driver for one Modbus TCP device: polls points, writes level commands.

Size: one class, one concept (a device's link: poll, write, reconnect, judge the answers);
the station's side and the loop's side share its state, and apart each would hold half of
one life cycle.

Life cycle: `ModbusDriver(...)`, `start()`, then from the station's tick, none of which
blocks: `latest()` (the last good reading), `write(point, value)` (a level: the newest value
per point wins), `status()` and `available`; finally `close()`, which leaves no thread and
no connection behind.  All input and output happens on one background asyncio loop that
every driver of the process shares (`hw.modbus.loop`).

Each round (every `poll_period`) writes the commands whose wanted value differs from what
was last written with success, then reads every polled point with as few requests as the
tables allow (`plan_reads`).  After a reconnect every wanted command is written again: the
device may have restarted.  A Modbus exception, a time-out, a closed connection or a
malformed answer makes the device unavailable with an error in plain words, never an
exception into the caller; the driver reconnects by itself (waiting a little longer after
each failure, up to a second) and the device is available again after its next good round.

A heartbeat point (a counter the device advances while its logic runs) makes a device
whose logic froze unavailable too, although it still answers.

A device can also restart behind an open connection (a power cycle of the tool while the
gateway stays up, a PLC going STOP -> RUN): its commands fall back to their power-on values
and a driver that writes only what changed would never send them again.  So every round
reads back the commanded points too; a heartbeat that counted back, or a command that no
longer reads what was written, means the device restarted: every command is written again
at once, and the status counts it (`LinkStatus.device_restarts`, with the reason).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.pdu import ModbusPDU

from hw.link import LinkStatus
from hw.modbus import loop as shared_loop
from hw.modbus.registers import Point, Table

Value = int | bool
LIMITS = {True: 2000, False: 125}  # per read request: bits, registers (Modbus spec)
MAX_BACKOFF = 1.0  # seconds between reconnection attempts, at most
EXCEPTIONS = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "device failure",
    5: "acknowledge",
    6: "device busy",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target failed to respond",
}


@dataclass(frozen=True, slots=True)
class ModbusReading:
    """One good poll: every polled point's value (`bool` for bits, 0..65535 for words),
    when it arrived (`time.monotonic()`), and when the heartbeat point last changed."""

    values: Mapping[Point, Value]
    received: float
    heartbeat_changed: float | None = None


@dataclass(frozen=True, slots=True)
class ReadRequest:
    table: Table
    address: int
    count: int

    def __str__(self) -> str:
        last = self.address + self.count - 1
        return f"{self.table.value}s {self.address}..{last}"


def plan_reads(points: Sequence[Point], max_gap: int | None = None) -> tuple[ReadRequest, ...]:
    """The fewest read requests that cover `points`: one per table while the span fits a
    request, spanning gaps unless they are longer than `max_gap` (for devices that refuse
    addresses they do not have)."""
    requests: list[ReadRequest] = []
    for table in Table:
        addresses = sorted({p.address for p in points if p.table is table})
        if not addresses:
            continue
        first = last = addresses[0]
        for address in addresses[1:]:
            too_long = address - first + 1 > LIMITS[table.is_bit]
            if too_long or (max_gap is not None and address - last - 1 > max_gap):
                requests.append(ReadRequest(table, first, last - first + 1))
                first = address
            last = address
        requests.append(ReadRequest(table, first, last - first + 1))
    return tuple(requests)


class _Trouble(Exception):
    """A failed round: why, and whether the connection is to be dropped."""

    def __init__(self, message: str, *, reconnect: bool = True) -> None:
        super().__init__(message)
        self.reconnect = reconnect


class ModbusDriver:
    """One Modbus TCP device, polled every `poll_period` seconds (see the module).

    The public methods are the station's side: any thread, never blocking on the device.
    The underscored ones run on the shared loop."""

    def __init__(
        self,
        name: str,
        host: str,
        port: int,
        device_id: int,
        points: Sequence[Point],
        *,
        poll_period: float = 0.05,
        timeout: float = 0.5,
        heartbeat_timeout: float = 1.0,
        heartbeat: Point | None = None,
        max_gap: int | None = None,
    ) -> None:
        if not poll_period > 0 or not timeout > 0 or not heartbeat_timeout > 0:
            raise ValueError("poll_period, timeout and heartbeat_timeout are positive seconds")
        self.name, self.host, self.port, self.device_id = name, host, port, device_id
        self.points = tuple(dict.fromkeys([*points, *([heartbeat] if heartbeat else [])]))
        self.poll_period, self.timeout = poll_period, timeout
        self.heartbeat_timeout, self.heartbeat = heartbeat_timeout, heartbeat
        self.reads = plan_reads(self.points, max_gap)
        self._lock = threading.Lock()
        self._desired: dict[Point, Value] = {}
        self._written: dict[Point, Value] = {}  # loop thread only
        self._latest: ModbusReading | None = None
        self._last_good: float | None = None
        self._latency_ms: float | None = None
        self._error = "not started"
        self._restarts = 0
        self._device_restarts = 0
        self._restart_reason = ""
        self._beat: tuple[Value, float] | None = None  # heartbeat value, when it changed
        self._loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task[None] | None = None
        self._wake: asyncio.Future[None] | None = None
        self._sent: tuple[bytes, int] = (b"", 0)  # the request's transaction id, function
        self._malformed = ""
        self._ending = False

    def start(self) -> None:
        if self._loop is not None:
            raise RuntimeError(f"Modbus driver {self.name} is started already")
        self._loop = shared_loop.acquire()
        self._error = "connecting"
        asyncio.run_coroutine_threadsafe(self._begin(), self._loop).result()

    def close(self) -> None:
        """Stops polling and closes the connection; waits until both are done."""
        loop, self._loop = self._loop, None
        if loop is None:
            return
        try:
            future = asyncio.run_coroutine_threadsafe(self._end(), loop)
            future.result(timeout=self.timeout + 5.0)
        except concurrent.futures.TimeoutError:
            pass  # the loop's own shutdown cancels what is left
        finally:
            with self._lock:
                self._error = "closed"
            shared_loop.release()

    def latest(self) -> ModbusReading | None:
        """The last good reading (also while the device is unavailable: see `received`)."""
        return self._latest

    def write(self, point: Point, value: Value) -> None:
        """Wants `point` (a coil or holding register) at `value` from now on."""
        if point.table is Table.COIL and not isinstance(value, bool):
            raise ValueError(f"{self.name}: {point} takes true or false, not {value!r}")
        if point.table is Table.HOLDING_REGISTER and (
            isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF
        ):
            raise ValueError(f"{self.name}: {point} takes a word 0..65535, not {value!r}")
        if not point.table.writable:
            raise ValueError(f"{self.name}: {point} is read-only")
        with self._lock:
            changed = self._desired.get(point) != value or point not in self._desired
            self._desired[point] = value
        loop = self._loop
        if changed and loop is not None:
            loop.call_soon_threadsafe(self._poke)

    @property
    def available(self) -> bool:
        """A good round within `heartbeat_timeout`, none failed since, heartbeat advancing."""
        return not self._judge(time.monotonic())

    def status(self) -> LinkStatus:
        with self._lock:
            error = self._judge(time.monotonic())
            return LinkStatus(
                connected=not error,
                latency_ms=self._latency_ms,
                last_data=self._last_good,
                error=error,
                restarts=self._restarts,
                device_restarts=self._device_restarts,
                device_restart=self._restart_reason,
            )

    def _judge(self, now: float) -> str:
        """Why the device is not available, or "" when it is."""
        if self._error:
            return self._error
        if self._last_good is None:
            return "no answer yet"
        if now - self._last_good > self.heartbeat_timeout:
            return f"no good answer for {now - self._last_good:.1f} s"
        if self._beat is not None and now - self._beat[1] > self.heartbeat_timeout:
            return (
                f"heartbeat counter stuck at {self._beat[0]} for {now - self._beat[1]:.1f} s: "
                "the device answers but its logic does not run"
            )
        return ""

    async def _begin(self) -> None:
        self._task = asyncio.get_running_loop().create_task(self._run(), name=self.name)

    async def _end(self) -> None:
        self._ending = True  # a cancellation the client swallows still ends the poll loop
        if self._task is not None:
            self._task.cancel()
            self._poke()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task

    def _poke(self) -> None:
        if self._wake is not None and not self._wake.done():
            self._wake.set_result(None)

    async def _pause(self, seconds: float) -> None:
        """Sleeps `seconds`, or less when a new command comes."""
        loop = asyncio.get_running_loop()
        self._wake = wake = loop.create_future()
        handle = loop.call_later(seconds, self._poke)
        try:
            await wake
        finally:
            handle.cancel()
            self._wake = None

    async def _run(self) -> None:
        client: AsyncModbusTcpClient | None = None
        connected_before = False
        backoff = self.poll_period
        loop = asyncio.get_running_loop()
        try:
            while not self._ending:
                began = loop.time()
                try:
                    if client is None:
                        client = await self._connect()
                        if connected_before:
                            with self._lock:
                                self._restarts += 1
                        connected_before = True
                    await self._round(client)
                    backoff = self.poll_period
                    await self._pause(self.poll_period - (loop.time() - began))
                except Exception as trouble:
                    # anything else is a fault of this driver or of pymodbus: said, not raised,
                    # so that one device's trouble never stops the station (HARDWARE.md)
                    reconnect = not isinstance(trouble, _Trouble) or trouble.reconnect
                    with self._lock:
                        self._error = (
                            str(trouble)
                            if isinstance(trouble, _Trouble)
                            else f"driver failure: {trouble!r}"
                        )
                    if reconnect and client is not None:
                        client.close()
                        client = None
                    await self._pause(backoff)
                    backoff = min(2 * backoff, max(MAX_BACKOFF, self.poll_period))
        finally:
            if client is not None:
                client.close()
                await asyncio.sleep(0)  # let the transport close its socket

    async def _connect(self) -> AsyncModbusTcpClient:
        self._malformed = ""
        client = AsyncModbusTcpClient(
            self.host,
            port=self.port,
            name=self.name,
            timeout=self.timeout,
            retries=0,
            reconnect_delay=0,  # this driver reconnects, and says so
            trace_packet=self._trace,
        )
        if not await client.connect():
            client.close()
            raise _Trouble(f"no connection to {self.host}:{self.port} (refused or unreachable)")
        self._written.clear()  # the device may have restarted: write every command again
        return client

    async def _round(self, client: AsyncModbusTcpClient) -> None:
        with self._lock:
            writes = [(p, v) for p, v in self._desired.items() if self._written.get(p) != v]
        for point, value in writes:
            if point.table is Table.COIL:
                answer = await self._ask(client.write_coil, point.address, bool(value))
                echo: Value = bool(answer.bits[0]) if answer.bits else not value
            else:
                answer = await self._ask(client.write_register, point.address, int(value))
                echo = answer.registers[0] if answer.registers else -1
            self._refused(answer, f"writing {point}")
            if answer.address != point.address or echo != value:
                raise _Trouble(f"malformed answer to writing {point}: the echo differs")
            self._written[point] = value
        values: dict[Point, Value] = {}
        sent = time.monotonic()
        for request in self.reads:
            read = _reader(client, request.table)
            answer = await self._ask(read, request.address, count=request.count)
            self._refused(answer, f"reading {request}")
            values.update(self._values(request, answer))
        received = time.monotonic()
        restarted = self._restarted(values)
        if restarted:
            self._written.clear()  # written again at the start of the next round
            with self._lock:
                self._device_restarts += 1
                self._restart_reason = restarted
            loop = asyncio.get_running_loop()
            loop.call_soon(self._poke)
        self._store(values, sent, received)

    def _restarted(self, values: Mapping[Point, Value]) -> str:
        """Why the device seems to have restarted since the last round ("" if it does not):
        its heartbeat counted back (modulo 2^16: a wrap is counting on), or a command it
        had taken reads another value (the device's logic never writes commands)."""
        if self.heartbeat is not None and self._beat is not None:
            before, now = int(self._beat[0]), int(values[self.heartbeat])
            if (now - before) & 0xFFFF > 0x8000:
                return f"its heartbeat counted back from {before} to {now}"
        for point, value in self._written.items():
            if point in values and values[point] != value:
                return f"{point} read {values[point]!r} after {value!r} was written"
        return ""

    async def _ask(self, call: Any, *args: Any, **kwargs: Any) -> ModbusPDU:
        try:
            answer: ModbusPDU = await call(*args, device_id=self.device_id, **kwargs)
        except ConnectionException:
            raise _Trouble("the connection closed") from None
        except ModbusIOException:
            if self._malformed:
                raise _Trouble(f"malformed answer: {self._malformed}") from None
            raise _Trouble(f"no answer within {self.timeout:g} s") from None
        except (ModbusException, OSError) as problem:
            raise _Trouble(f"Modbus failure: {problem}") from None
        return answer

    def _refused(self, answer: ModbusPDU, doing: str) -> None:
        if answer.isError():
            code = getattr(answer, "exception_code", 0)
            meaning = EXCEPTIONS.get(code, "unknown exception")
            raise _Trouble(
                f"the device refused {doing}: {meaning} (Modbus exception {code})",
                reconnect=False,
            )

    def _values(self, request: ReadRequest, answer: ModbusPDU) -> dict[Point, Value]:
        if request.table.is_bit:
            words: list[Value] = list(answer.bits)
            expected = 8 * ((request.count + 7) // 8)
        else:
            words = list(answer.registers)
            expected = request.count
        if len(words) != expected:
            raise _Trouble(
                f"malformed answer to reading {request}: {len(words)} values, not {expected}"
            )
        wanted = {p.address for p in self.points if p.table is request.table}
        return {
            Point(request.table, a): words[a - request.address]
            for a in range(request.address, request.address + request.count)
            if a in wanted
        }

    def _store(self, values: dict[Point, Value], sent: float, received: float) -> None:
        with self._lock:
            if self.heartbeat is not None:
                beat = values[self.heartbeat]
                if self._beat is None or self._beat[0] != beat:
                    self._beat = (beat, received)
            changed = self._beat[1] if self._beat is not None else None
            self._latest = ModbusReading(MappingProxyType(values), received, changed)
            self._last_good = received
            self._latency_ms = (received - sent) * 1000.0
            self._error = ""

    def _trace(self, sending: bool, frame: bytes) -> bytes:
        """Every frame passes here (loop thread): a malformed answer is noted and dropped
        (pymodbus would log it, or fail inside its protocol); the request then times out."""
        if sending:
            self._sent = (frame[:2], frame[7] if len(frame) > 7 else 0)
            return frame
        if len(frame) < 8:
            return frame  # the rest is still coming
        tid, function = self._sent
        problem = ""
        if frame[2:4] != b"\x00\x00":
            problem = f"protocol id {int.from_bytes(frame[2:4], 'big')}, not Modbus"
        elif frame[:2] != tid:
            problem = "the answer to another transaction"
        elif frame[6] != self.device_id:
            problem = f"an answer from unit {frame[6]}, not {self.device_id}"
        elif frame[7] & 0x7F != function:
            problem = f"function code {frame[7]} answering a request with {function}"
        if problem:
            self._malformed = problem
            return b""
        return frame


def _reader(client: AsyncModbusTcpClient, table: Table) -> Any:
    if table is Table.COIL:
        return client.read_coils
    if table is Table.DISCRETE_INPUT:
        return client.read_discrete_inputs
    if table is Table.HOLDING_REGISTER:
        return client.read_holding_registers
    return client.read_input_registers
