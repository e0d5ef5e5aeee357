"""The one background asyncio loop that every Modbus driver of a process shares.

A loop per driver would cost a thread and a wake-up per poll each; one loop serves all of
them, and costs nothing while no driver runs: the first `acquire` starts its thread, the
last `release` stops it and joins it.
"""

from __future__ import annotations

import asyncio
import logging
import threading

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
        thread.join()


def running() -> bool:
    """Whether the shared loop's thread is alive (for tests: nothing left behind)."""
    with _lock:
        return _thread is not None and _thread.is_alive()


def _run(loop: asyncio.AbstractEventLoop, ready: threading.Event) -> None:
    asyncio.set_event_loop(loop)
    loop.call_soon(ready.set)
    try:
        loop.run_forever()
        # what the drivers left: cancel it and let it end, then close sockets and the loop
        tasks = asyncio.all_tasks(loop)
        for task in tasks:
            task.cancel()
        if tasks:
            loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
        loop.run_until_complete(loop.shutdown_asyncgens())
    finally:
        loop.close()


def _quiet_pymodbus() -> None:
    """pymodbus logs every refused connection and time-out, up to 20 times a second per
    device; the drivers report them in their status instead.  An application that
    configured pymodbus's logger keeps its setting."""
    logger = logging.getLogger("pymodbus")
    if logger.level == logging.NOTSET:
        logger.setLevel(logging.CRITICAL)
