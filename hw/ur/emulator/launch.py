"""Starting emulated UR controllers: a free loopback address each, since the ports are fixed.

ur_rtde always connects to 30004, 29999 and 30003, so every emulated robot needs its own
address (all of 127.0.0.0/8 is loopback on Linux).  `free_host` finds one whose three ports
nobody holds (a stale emulator from an earlier run must not break the next); `emulate` starts
`python -m hw.ur.emulator.server` there and stops it when the block ends, also on failure.
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterable, Iterator

from hw.emulator_kit.process import EmulatorProcess, start

CLIENT_PORTS = (30004, 29999, 30003)


def port_free(host: str, port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError:
            return False
    return True


def free_host(candidates: Iterable[str]) -> str:
    """The first address whose client ports are all free."""
    for host in candidates:
        if all(port_free(host, port) for port in CLIENT_PORTS):
            return host
    raise RuntimeError("no loopback address with free UR ports among the candidates")


def host_range(first: int, last: int, prefix: str = "127.0.1.") -> list[str]:
    return [f"{prefix}{n}" for n in range(first, last + 1)]


def free_block(blocks: Iterable[int], taken: set[int] | None = None) -> int:
    """A block 127.0.N.0/24 (N in `blocks`, not in `taken`; added to it) whose robot address
    127.0.N.2 has the UR client ports free: room for a device file moved there (`on_block`)."""
    for block in blocks:
        if taken is not None and block in taken:
            continue
        if all(port_free(f"127.0.{block}.2", port) for port in CLIENT_PORTS):
            if taken is not None:
                taken.add(block)
            return block
    raise RuntimeError("no free loopback block for the emulators")


def on_block(device_file_text: str, block: int) -> str:
    """A device file on 127.0.0.x (the demo's) moved to 127.0.N.x."""
    return device_file_text.replace("127.0.0.", f"127.0.{block}.")


@contextlib.contextmanager
def emulate(host: str, *args: str, timeout: float = 15.0) -> Iterator[EmulatorProcess]:
    """A running emulator on `host` for the duration of the block."""
    emulator = start("hw.ur.emulator.server", "--host", host, *args, timeout=timeout)
    try:
        yield emulator
    finally:
        emulator.stop()
