"""One RTDE connection (port 30004): handshake, recipes, the data stream and input packages.

Per connection: the negotiated protocol, one output recipe (with its rate as a divisor of the
controller cycle) and the input recipes, numbered 1, 2, 3 ... in set-up order.  An input
variable belongs to the first connection that set it up; another connection asking for it gets
`IN_USE` until that one closes.  Never a text message (`M`): a client in the middle of its
set-up would take it for the answer it waits for.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Sequence
from typing import Any, Protocol

from hw.ur.emulator import rtde_wire as wire
from hw.ur.emulator.controller import Controller

log = logging.getLogger(__name__)

MAX_BUFFERED = 1 << 16
"""Bytes queued for a client that does not read, beyond which data packages are dropped."""


class RtdeHost(Protocol):
    """What a connection uses of the emulator that accepted it (`server.Emulator` is one):
    the controller, its cycle rate, the network fault, who owns which input variable."""

    @property
    def controller(self) -> Controller: ...

    @property
    def silent(self) -> bool: ...

    @property
    def cycle_rate(self) -> int: ...

    def inputs_taken(self, session: RtdeSession, names: Sequence[str]) -> set[str]: ...

    def claim_inputs(self, session: RtdeSession, names: Sequence[str]) -> None: ...

    def release_inputs(self, session: RtdeSession) -> None: ...

    def recipes_changed(self) -> None: ...


class RtdeSession:
    def __init__(self, emulator: RtdeHost, writer: asyncio.StreamWriter) -> None:
        self.emulator = emulator
        self.writer = writer
        self.protocol = 0
        self.output: wire.Recipe | None = None
        self.divisor = 1
        self.countdown = 0
        self.inputs: dict[int, wire.Recipe] = {}
        self.started = False

    async def serve(self, reader: asyncio.StreamReader) -> None:
        buffer = bytearray()
        try:
            while data := await reader.read(1 << 16):
                if self.emulator.silent:
                    continue
                buffer += data
                for message in wire.split(buffer):
                    self.handle(message)
        except (ConnectionError, wire.WireError) as problem:
            log.info("RTDE connection ends: %s", problem)
        finally:
            self.close()

    def close(self) -> None:
        self.started = False
        self.emulator.release_inputs(self)
        self.writer.close()

    def handle(self, message: wire.Message) -> None:
        kind, payload = message.kind, message.payload
        if kind == wire.REQUEST_PROTOCOL_VERSION:
            self.protocol = wire.protocol_version(payload)
            self.send(wire.version_answer(self.protocol == wire.PROTOCOL_VERSION))
        elif kind == wire.GET_URCONTROL_VERSION:
            self.send(wire.controller_version_answer(*self.emulator.controller.version))
        elif kind == wire.SETUP_OUTPUTS:
            self._setup_outputs(payload)
        elif kind == wire.SETUP_INPUTS:
            self._setup_inputs(payload)
        elif kind == wire.START:
            self.started = self.output is not None
            self.countdown = 0
            self.send(wire.success_answer(wire.START, self.started or bool(self.inputs)))
            self.emulator.recipes_changed()
        elif kind == wire.PAUSE:
            self.started = False
            self.send(wire.success_answer(wire.PAUSE))
            self.emulator.recipes_changed()
        elif kind == wire.DATA_PACKAGE:
            self._input_package(payload)
        else:
            log.info("RTDE message type %d ignored", kind)

    def _setup_outputs(self, payload: bytes) -> None:
        frequency, names = wire.output_setup(payload)
        types = wire.output_types(names)
        if wire.NOT_FOUND in types or not names:
            self.send(wire.setup_answer(wire.SETUP_OUTPUTS, 0, types))
            return
        rate = self.emulator.cycle_rate
        self.divisor = max(1, round(rate / min(max(frequency, 1.0), rate)))
        self.output = wire.Recipe.of(1, names, wire.OUTPUTS)
        self.send(wire.setup_answer(wire.SETUP_OUTPUTS, 1, types))
        self.emulator.recipes_changed()

    def _setup_inputs(self, payload: bytes) -> None:
        names = wire.input_setup(payload)
        types = [wire.INPUTS.get(name, wire.NOT_FOUND) for name in names]
        taken = self.emulator.inputs_taken(self, names)
        types = [wire.IN_USE if name in taken else t for name, t in zip(names, types, strict=True)]
        if wire.NOT_FOUND in types or wire.IN_USE in types or not names:
            self.send(wire.setup_answer(wire.SETUP_INPUTS, 0, types))
            return
        self.emulator.claim_inputs(self, names)
        recipe_id = len(self.inputs) + 1
        self.inputs[recipe_id] = wire.Recipe.of(recipe_id, names, wire.INPUTS)
        self.send(wire.setup_answer(wire.SETUP_INPUTS, recipe_id, types))

    def _input_package(self, payload: bytes) -> None:
        recipe = self.inputs.get(wire.package_recipe_id(payload))
        if recipe is None:
            log.info("a data package for an unknown input recipe is dropped")
            return
        values = recipe.unpack(payload)
        controller = self.emulator.controller
        controller.write_inputs(values, controller.clock)

    def push(self, values: dict[str, Any]) -> None:
        """Sends a data package if this cycle is one of the connection's rate."""
        if not self.started or self.output is None:
            return
        self.countdown -= 1
        if self.countdown > 0:
            return
        self.countdown = self.divisor
        transport = self.writer.transport
        if transport.is_closing() or transport.get_write_buffer_size() > MAX_BUFFERED:
            return
        self.writer.write(self.output.pack(values))

    def send(self, data: bytes) -> None:
        if not self.writer.transport.is_closing():
            self.writer.write(data)
