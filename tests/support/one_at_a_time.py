"""A lock across the suite's worker processes, for groups that must not run together.

The real-time plays on emulated devices (seed 000's experiments, the device faults) each keep
three `sp run` processes and their emulators busy; two such groups at once on a 2-core
machine made each play several times slower than real time.  They take turns instead.
"""

from __future__ import annotations

import fcntl
import hashlib
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.support.paths import REPOSITORY


@contextmanager
def one_at_a_time(name: str) -> Iterator[None]:
    """Holds the lock `name` (for this checkout) until the block ends."""
    tag = hashlib.sha256(str(REPOSITORY).encode()).hexdigest()[:12]  # the same in every process
    path = Path(tempfile.gettempdir()) / f"sp-tests-{name}-{tag}.lock"
    with path.open("a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
