"""An emulated UR10 controller (CB3, PolyScope 3.15.7) as its own process.

    python -m hw.ur.emulator.server --host 127.0.0.2 [--control-port 30100]
        [--joints q1,...,q6] [--version 3.15.7]

It listens on the client's fixed ports on `--host`: RTDE 30004, dashboard 29999, script 30003,
plus the control channel (`hw.emulator_kit.control`; `--control-port 0` takes any free port),
prints `{"ready": true, "ports": {...}}` once everything listens, and ends on SIGTERM.  The
controller cycle runs at 125 Hz (500 Hz for a version ≥ 5) while a client streams or the arm
moves, and slower when nothing happens.  The faults it plays on demand are in
`hw.ur.emulator.faults`.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import logging
import signal
import sys
import time
from collections.abc import Sequence
from typing import Any

from hw.emulator_kit.control import serve_control
from hw.emulator_kit.process import exit_with_parent
from hw.ur.emulator import dashboard
from hw.ur.emulator.arm import Arm
from hw.ur.emulator.controller import Controller
from hw.ur.emulator.faults import handle
from hw.ur.emulator.rtde_server import RtdeSession
from hw.ur.emulator.script_server import Programs

log = logging.getLogger(__name__)

PORTS = {"rtde": 30004, "dashboard": 29999, "script": 30003}
IDLE_PERIOD = 0.05
HOME = (0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0)


class Emulator:
    """The controller's servers, connections and network faults around one `Controller`."""

    def __init__(self, host: str, controller: Controller, ports: dict[str, int]) -> None:
        self.host = host
        self.controller = controller
        self.ports = dict(ports)
        self.servers: dict[str, asyncio.Server] = {}
        self.connections: dict[asyncio.StreamWriter, str] = {}
        self.sessions: set[RtdeSession] = set()
        self.owners: dict[str, RtdeSession] = {}
        self.network = ""  # "", "silent" or "refuse"
        self.frozen: dict[str, Any] | None = None
        self.wanted: list[str] = []
        self.cycle_rate = 500 if controller.version[0] >= 5 else 125

    @property
    def silent(self) -> bool:
        return self.network == "silent"

    async def listen(self) -> None:
        sessions = {"rtde": self._rtde, "dashboard": self._dashboard, "script": self._script}
        for name, serve in sessions.items():
            server = await asyncio.start_server(
                self._tracked(name, serve), self.host, self.ports[name], reuse_address=True
            )
            self.servers[name] = server
            self.ports[name] = server.sockets[0].getsockname()[1]

    async def unlisten(self) -> None:
        for server in self.servers.values():
            server.close()
        for writer in list(self.connections):
            writer.close()
        for server in self.servers.values():
            with contextlib.suppress(Exception):
                await asyncio.wait_for(server.wait_closed(), 1.0)
        self.servers.clear()

    def _tracked(self, name: str, serve: Any) -> Any:
        async def session(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            self.connections[writer] = name
            try:
                await serve(reader, writer)
            except (ConnectionError, asyncio.IncompleteReadError) as problem:
                log.info("%s connection ends: %s", name, problem)
            finally:
                self.connections.pop(writer, None)
                writer.close()

        return session

    def connection_counts(self) -> dict[str, int]:
        counts = dict.fromkeys(PORTS, 0)
        for name in self.connections.values():
            counts[name] += 1
        return counts

    async def _rtde(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        session = RtdeSession(self, writer)
        self.sessions.add(session)
        try:
            await session.serve(reader)
        finally:
            self.sessions.discard(session)
            self.recipes_changed()

    async def _dashboard(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if not self.silent:
            writer.write(dashboard.GREETING.encode() + b"\n")
        while line := await reader.readline():
            if self.silent:
                continue
            text = line.decode("utf-8", "replace").strip()
            now = time.monotonic()
            writer.write(dashboard.answer(self.controller, text, now).encode() + b"\n")
            await writer.drain()
            if text.lower() == "quit":
                break

    async def _script(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        programs = Programs()
        while data := await reader.read(1 << 16):
            if self.silent:
                continue
            for program in programs.feed(data.decode("utf-8", "replace")):
                self.controller.load_program(program)

    def inputs_taken(self, session: RtdeSession, names: Sequence[str]) -> set[str]:
        return {n for n in names if self.owners.get(n, session) is not session}

    def claim_inputs(self, session: RtdeSession, names: Sequence[str]) -> None:
        for name in names:
            self.owners[name] = session

    def release_inputs(self, session: RtdeSession) -> None:
        for name in [n for n, owner in self.owners.items() if owner is session]:
            del self.owners[name]

    def recipes_changed(self) -> None:
        names = {n for s in self.sessions if s.started and s.output for n in s.output.names}
        self.wanted = sorted(names)

    def busy(self) -> bool:
        c = self.controller
        return bool(self.wanted) or not c.arm.steady or bool(c.pending)

    async def run_cycles(self) -> None:
        period = 1.0 / self.cycle_rate
        deadline = time.monotonic()
        while True:
            now = time.monotonic()
            self.controller.tick(now)
            self.stream()
            deadline = max(deadline + (period if self.busy() else IDLE_PERIOD), now - period)
            await asyncio.sleep(max(deadline - time.monotonic(), 0.0))

    def stream(self) -> None:
        if not self.wanted or self.network:
            return
        if self.frozen is None:
            values = self.controller.outputs(self.wanted)
        else:
            missing = [n for n in self.wanted if n not in self.frozen]
            self.frozen.update(self.controller.outputs(missing))
            values = self.frozen
        for session in list(self.sessions):
            session.push(values)

    def freeze(self, on: bool) -> None:
        self.frozen = self.controller.outputs(self.wanted) if on else None

    async def set_network(self, down: bool, mode: str = "silent") -> None:
        if not down:
            restore = self.network == "refuse"
            self.network = ""
            if restore:
                await self.listen()
            return
        if mode not in ("silent", "refuse"):
            raise ValueError(f"network mode is 'silent' or 'refuse', not {mode!r}")
        if mode == "refuse" and self.network != "refuse":
            self.network = "refuse"
            await self.unlisten()
        else:
            self.network = mode


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m hw.ur.emulator.server", description=__doc__)
    parser.add_argument("--host", default="127.0.0.2")
    parser.add_argument("--control-port", type=int, default=0)
    parser.add_argument("--joints", default=",".join(str(q) for q in HOME))
    parser.add_argument("--version", default="3.15.7")
    return parser.parse_args(argv)


def controller_from(args: argparse.Namespace) -> Controller:
    joints = [float(x) for x in args.joints.split(",")]
    if len(joints) != 6:
        raise SystemExit(f"--joints needs 6 values, not {len(joints)}")
    numbers = [int(x) for x in args.version.split(".")]
    if len(numbers) not in (3, 4):
        raise SystemExit(f"--version is MAJOR.MINOR.BUGFIX, not {args.version}")
    version = (numbers[0], numbers[1], numbers[2], numbers[3] if len(numbers) == 4 else 106331)
    now = time.monotonic()
    return Controller(Arm(joints), version=version, boot=now - 1000.0, clock=now)


async def serve(args: argparse.Namespace) -> None:
    emulator = Emulator(args.host, controller_from(args), PORTS)
    await emulator.listen()

    async def on_request(request: dict[str, Any]) -> dict[str, Any]:
        return await handle(emulator, request)

    control = await serve_control(args.host, args.control_port, on_request)
    ports = {**emulator.ports, "control": control.sockets[0].getsockname()[1]}
    print(json.dumps({"ready": True, "ports": ports}), flush=True)
    stopping = asyncio.Event()
    loop = asyncio.get_running_loop()
    for number in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(number, stopping.set)
    cycles = asyncio.create_task(emulator.run_cycles())
    await stopping.wait()
    cycles.cancel()
    control.close()
    await emulator.unlisten()


def main(argv: Sequence[str] | None = None) -> None:
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    exit_with_parent()
    asyncio.run(serve(parse_args(argv)))


if __name__ == "__main__":
    main()
