"""The emulators' control channel: one JSON object per line in, one per line out.

A request is `{"op": NAME, ...}`; the answer is `{"ok": true, ...}` or `{"ok": false,
"error": PLAIN_WORDS}`.  Operations are the emulator's own (a fault, a person's change, a
state query).  The channel stays up while the emulated device plays a network loss, so a
fault can always be ended.
"""

from __future__ import annotations

import asyncio
import json
import socket
from collections.abc import Awaitable, Callable
from typing import Any

Handler = Callable[[dict[str, Any]], Awaitable[dict[str, Any]]]

MAX_LINE = 1 << 16


class ControlError(RuntimeError):
    """The emulator refused a control request or could not be reached."""


async def serve_control(host: str, port: int, handler: Handler) -> asyncio.Server:
    """Listens on (host, port) (0: any free port) and answers each line with `handler`."""

    async def session(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while line := await reader.readline():
                writer.write(json.dumps(await _answer(handler, line)).encode() + b"\n")
                await writer.drain()
        except (ConnectionError, asyncio.IncompleteReadError, ValueError):
            pass
        except asyncio.CancelledError:
            # the emulator is ending: a cancelled session task would make Python 3.11's
            # stream callback log a traceback for it; the session simply ends
            return
        finally:
            writer.close()

    return await asyncio.start_server(session, host, port, limit=MAX_LINE)


async def _answer(handler: Handler, line: bytes) -> dict[str, Any]:
    try:
        request = json.loads(line)
    except ValueError:
        return {"ok": False, "error": "not a JSON line"}
    if not isinstance(request, dict) or not isinstance(request.get("op"), str):
        return {"ok": False, "error": "a request is an object with a text 'op'"}
    try:
        answer = await handler(request)
    except (KeyError, TypeError, ValueError) as problem:
        return {"ok": False, "error": str(problem) or type(problem).__name__}
    return {"ok": True, **answer}


def control(host: str, port: int, request: dict[str, Any], timeout: float = 2.0) -> dict[str, Any]:
    """Sends one request and returns the answer; raises `ControlError` on refusal or failure."""
    try:
        with socket.create_connection((host, port), timeout=timeout) as link:
            link.sendall(json.dumps(request).encode() + b"\n")
            answer = json.loads(link.makefile("rb").readline(MAX_LINE) or b"null")
    except (OSError, ValueError) as problem:
        raise ControlError(f"emulator at {host}:{port} did not answer: {problem}") from None
    if not isinstance(answer, dict):
        raise ControlError(f"emulator at {host}:{port} gave no answer")
    if not answer.get("ok"):
        raise ControlError(str(answer.get("error", "refused")))
    return answer
