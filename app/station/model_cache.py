"""A disk cache of read models, so that `sp` commands and the station's processes skip
reading a large model they have read before.

Reading is parsing YAML and tens of thousands of expressions (4 s of the 6.7 s `sp plan` takes
at 10,000 transitions, bench/results/planning.md); what it gives depends only on the text, the
name problems would be reported under, and this program's code.  The cache keeps the read
`Station` pickled beside the supervisors (`supervisor_cache.default_directory`), under a
SHA-256 of the text, that name, the Python version and the sources of `planner/`: an entry
written by other code is never found, so a changed class never meets an old object.

Unpickling runs whatever code the bytes name, and whoever can write the cache folder is not
trusted with that.  An entry is read only when its seal, an HMAC of its name and bytes under
the cache's key (`supervisor_cache.cache_key`, derived for this use), is right; otherwise the
model is read from its text again and the entry rewritten, with a warning in the log.  Only
models read without problems are kept; failing to write costs the next run its time, nothing
else.
"""

from __future__ import annotations

import gc
import hashlib
import hmac
import logging
import os
import pickle
import sys
import tempfile
from pathlib import Path

from app.station.supervisor_cache import cache_key, code_digest
from planner.model.station import Station
from planner.reading import load_station

FORMAT = 1
SUFFIX = ".station.pickle"
SEAL = hashlib.sha256().digest_size

log = logging.getLogger(__name__)


def entry_name(text: str, file: str) -> str:
    digest = hashlib.sha256()
    python = ".".join(map(str, sys.version_info[:3]))
    digest.update(f"sequence-planner model {FORMAT} python {python} {code_digest()}\n".encode())
    digest.update(file.encode() + b"\0")
    digest.update(text.encode())
    return digest.hexdigest()


def load(text: str, file: str, directory: Path | None) -> Station:
    """The station `text` describes, from the cache when a sealed entry for it is there;
    `ModelError` (nothing kept) when the text has problems, as `load_station` says them."""
    secret = None if directory is None else cache_key("model cache")
    if directory is None or secret is None:
        return load_station(text, file)
    name = entry_name(text, file)
    path = directory / f"{name}{SUFFIX}"
    station = _read(path, secret, name)
    if station is None:
        station = load_station(text, file)
        _write(path, secret, name, station)
    return station


def _seal(secret: bytes, name: str, body: bytes) -> bytes:
    return hmac.new(secret, name.encode() + b"\0" + body, hashlib.sha256).digest()


def _read(path: Path, secret: bytes, name: str) -> Station | None:
    try:
        data = path.read_bytes()
    except OSError:
        return None  # not cached yet (or unreadable: read the text)
    seal, body = data[:SEAL], data[SEAL:]
    if not hmac.compare_digest(seal, _seal(secret, name, body)):
        log.warning("the model cache entry %s is not sealed with the cache key: not read", path)
        return None
    collecting = gc.isenabled()
    gc.disable()  # a graph of a million new objects: collections find nothing to free
    try:
        station = pickle.loads(body)
    except Exception:  # sealed by us, yet unreadable: another program's version; read again
        return None
    finally:
        if collecting:
            gc.enable()
    return station if isinstance(station, Station) else None


def _write(path: Path, secret: bytes, name: str, station: Station) -> None:
    try:
        body = pickle.dumps(station, protocol=pickle.HIGHEST_PROTOCOL)
    except (RecursionError, pickle.PicklingError, TypeError):
        return  # a model nested too deep to pickle is read from its text each time
    try:
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("wb", dir=path.parent, delete=False) as tmp:
            tmp.write(_seal(secret, name, body) + body)  # created 0600
        os.replace(tmp.name, path)
    except OSError:
        pass  # a read-only home or a full disk only costs the next run its time
