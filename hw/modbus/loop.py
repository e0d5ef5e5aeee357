"""The one background asyncio loop that every Modbus driver of a process shares.

A loop per driver would cost a thread and a wake-up per poll each; one loop serves all of
them, and costs nothing while no driver runs: the first `acquire` starts its thread, the
last `release` stops it and joins it.

Stopping is bounded: what the drivers left is cancelled again and again until it ends or
`STOP_WAIT` passes (Python 3.11's `asyncio.wait_for` can swallow a cancellation that meets
its inner future's completion, and pymodbus awaits through it), then the loop closes
whatever is left, says what it was, and its thread ends.  A close never hangs the station.
"""

from __future__ import annotations

import asyncio
import logging
import threading

STOP_WAIT = 3.0  # seconds for what the drivers left to end once cancelled
RECANCEL = 0.1  # seconds between cancellations of what has not ended yet

log = logging.getLogger(__name__)

_lock = threading.Lock()
_loop: asyncio.AbstractEventLoop | None = None
_thread: threading.Thread | None = None
_users = 0


def acquire() -> asyncio.AbstractEventLoop:
    """The shared loop, running; pair every call with `release`."""
    global _loop, _thread, _users
    with _lock:
        if _loop is None:
            _quiet_pymodbus()
            _loop = asyncio.new_event_loop()
            ready = threading.Event()
            _thread = threading.Thread(
                target=_run, args=(_loop, ready), name="modbus-drivers", daemon=True
            )
            _thread.start()
            ready.wait()
        _users += 1
        return _loop


def release() -> None:
    """One user fewer; the last one stops the loop and joins its thread."""
    global _loop, _thread, _users
    with _lock:
        _users -= 1
        if _users > 0 or _loop is None or _thread is None:
            return
        loop, thread = _loop, _thread
        _loop = _thread = None
        loop.call_soon_threadsafe(loop.stop)
        thread.join(STOP_WAIT + 2.0)
        if thread.is_alive():
            log.warning("the Modbus drivers' loop did not stop within %g s", STOP_WAIT + 2.0)


def running() -> bool:
    """Whether the shared loop's thread is alive (for tests: nothing left behind)."""
    with _lock:
        return _thread is not None and _thread.is_alive()


def _run(loop: asyncio.AbstractEventLoop, ready: threading.Event) -> None:
    asyncio.set_event_loop(loop)
    loop.call_soon(ready.set)
    try:
        loop.run_forever()
        # what the drivers left: cancel it until it ends, then close sockets and the loop
        left = loop.run_until_complete(end_all(STOP_WAIT))
        if left:
            log.warning("Modbus tasks that did not end when cancelled: %s", ", ".join(left))
        loop.run_until_complete(loop.shutdown_asyncgens())
    finally:
        loop.close()


async def end_all(within: float) -> list[str]:
    """Cancels every other task of the running loop until it ends or `within` seconds
    pass; the names of those that did not end."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + within
    pending = asyncio.all_tasks(loop) - {asyncio.current_task(loop)}
    while pending:
        for task in pending:
            task.cancel()
        wait = min(RECANCEL, deadline - loop.time())
        if wait <= 0:
            break
        _, pending = await asyncio.wait(pending, timeout=wait)
    return sorted(task.get_name() for task in pending)


def _quiet_pymodbus() -> None:
    """pymodbus logs every refused connection and time-out, up to 20 times a second per
    device; the drivers report them in their status instead.  An application that
    configured pymodbus's logger keeps its setting."""
    logger = logging.getLogger("pymodbus")
    if logger.level == logging.NOTSET:
        logger.setLevel(logging.CRITICAL)
