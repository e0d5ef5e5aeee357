"""A disk cache of synthesised supervisors, so that repeated `sp` runs on a model skip synthesis.

Synthesis (the bad states of the specifications) and the sift after it are the slow part of
building a planner (half a second on the demo station, more on large models) and depend only
on the model's text.  The cache keeps, per model text, the BDD variable order and checksums
(JSON), the bad states (CUDD's DDDMP format) and the states bad for each specification
alone (`planner.bdd.data`'s JSON, which holds many named roots and reads fast), keyed by a
SHA-256 of the text, the `dd` version, this format's number and the planner's code
(`code_digest`): an entry stands for a build that checked the model's dynamics
and synthesised, which a restored planner does not do again.  Once the first plan has chosen
the order for search (`TransitionPlanner.tuned`), `remember_order` saves that order instead.
A tuned order is declared at once when the planner is built.  Anything missing, unreadable
or inconsistent falls back to synthesis; failing to write is not an error.

The cache lies outside the database, and whoever writes it could otherwise hand the station
a supervisor with no forbidden states.  Each entry is sealed: an HMAC, under a key of the
cache's own (`cache_key_path`, mode 0600, out of the cache folder), of the entry's name,
order and checksums.  An entry without a valid seal is not read: the supervisor is
synthesised again and the entry overwritten (with a warning in the log).  The key is the
cache's, not one station's, so the stations and `sp` commands of one account share entries.
"""

from __future__ import annotations

import functools
import hashlib
import hmac
import json
import logging
import os
import tempfile
from pathlib import Path
from typing import Any

import planner as planner_package
from planner.bdd.data import from_data, to_data
from planner.bdd.symbolic import Function, SymbolicModel
from planner.model.flat import Model
from planner.planning.transition_planner import TransitionPlanner

FORMAT = 4  # 2: the states bad for each specification are saved too; 3: as bdd_data; 4: sealed

log = logging.getLogger(__name__)
SEALED = ("order", "bad_sha256", "specs_sha256", "tuned")
PLANNER_SOURCES = Path(planner_package.__file__).resolve().parent


class Unsealed(ValueError):
    """An entry whose seal is missing or wrong: written by someone without the cache key."""


def default_directory() -> Path:
    if "SP_CACHE_DIR" in os.environ:
        return Path(os.environ["SP_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "sequence-planner"


def cache_key_path() -> Path:
    """`$SP_CACHE_KEY_FILE`, else `~/.config/sequence-planner/cache.key` (`$XDG_CONFIG_HOME`)."""
    if "SP_CACHE_KEY_FILE" in os.environ:
        return Path(os.environ["SP_CACHE_KEY_FILE"])
    base = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    return base / "sequence-planner" / "cache.key"


def cache_key(use: str = "supervisor cache") -> bytes | None:
    """The key that seals entries (one derived per `use`: the supervisors, the read models),
    created on first use; None when it cannot be had (then nothing is read from or written to
    the cache)."""
    from app.store.keys import KeyFileError, create_keys, read_keys

    path = cache_key_path()
    try:
        return read_keys(path).derived(use)
    except KeyFileError:
        pass
    try:
        return create_keys(path).derived(use)
    except (KeyFileError, OSError):  # another process made it meanwhile, or it cannot be
        try:
            return read_keys(path).derived(use)
        except KeyFileError as problem:
            log.warning("the %s is not used: %s", use, problem)
            return None


def seal(secret: bytes, name: str, entry: dict[str, Any]) -> str:
    fields = {"name": name, **{k: entry.get(k) for k in SEALED}}
    text = json.dumps(fields, sort_keys=True, separators=(",", ":"))
    return hmac.new(secret, text.encode(), hashlib.sha256).hexdigest()


def _read_entry(path: Path, secret: bytes, name: str) -> dict[str, Any]:
    entry = json.loads(path.read_text())
    if not isinstance(entry, dict):
        raise ValueError("the saved entry is not an object")
    if not hmac.compare_digest(str(entry.get("seal", "")), seal(secret, name, entry)):
        raise Unsealed(f"the cache entry {path} is not sealed with the cache key")
    return entry


@functools.cache
def code_digest() -> str:
    """A SHA-256 of every source file of `planner/` (read once per process, ~5 ms)."""
    root = PLANNER_SOURCES
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


def key(text: str) -> str:
    import dd

    digest = hashlib.sha256()
    header = f"sequence-planner supervisor {FORMAT} dd {dd.__version__} {code_digest()}\n"
    digest.update(header.encode())
    digest.update(text.encode())
    return digest.hexdigest()


def planner(model: Model, text: str, engine: str, directory: Path | None) -> TransitionPlanner:
    """A planner for `model` (read from `text`), with its supervisor from the cache if saved."""
    secret = None if directory is None else cache_key()
    if directory is None or secret is None:
        return TransitionPlanner(model, engine)
    name = key(text)
    order_path, bad_path = directory / f"{name}.json", directory / f"{name}.dddmp"
    specs_path = directory / f"{name}.specifications.json"
    if order_path.exists() and bad_path.exists() and specs_path.exists():
        try:
            entry = _read_entry(order_path, secret, name)
            # CUDD's DDDMP reader crashes the process on a damaged file: check it first
            if hashlib.sha256(bad_path.read_bytes()).hexdigest() != entry["bad_sha256"]:
                raise ValueError("the saved bad states do not match their checksum")

            if hashlib.sha256(specs_path.read_bytes()).hexdigest() != entry["specs_sha256"]:
                raise ValueError("the saved closures do not match their checksum")

            def restore(sym: SymbolicModel) -> tuple[Function, dict[str, Function]]:
                sym.reorder(entry["order"])
                (bad,) = sym.bdd.load(str(bad_path))
                names = {s.name for s in model.specifications}
                closures = from_data(sym.bdd, json.loads(specs_path.read_text()))
                if not isinstance(closures, dict) or set(closures) != names:
                    raise ValueError("the saved closures do not match the specifications")
                return bad, closures

            # a tuned order is the one search uses (`SymbolicPlanner.tune` is then skipped):
            # declared at once, rather than the static order computed and then replaced
            order = entry["order"] if entry.get("tuned") else None
            restored = TransitionPlanner(model, engine, restore=restore, order=order)
            restored.tuned = bool(entry.get("tuned", False))
            return restored
        except Unsealed as problem:
            log.warning("%s: the supervisor is synthesised again", problem)
        except (OSError, ValueError, RuntimeError, KeyError, TypeError):
            pass  # a damaged entry: synthesise again and overwrite it
    built = TransitionPlanner(model, engine)
    _save(built, secret, directory, name)
    return built


def remember_order(planner: TransitionPlanner, text: str, directory: Path | None) -> None:
    """Save the order a search tuned (`TransitionPlanner.tuned`) in the model's entry, so
    that the next run starts with it; the bad states keep their file (DDDMP loads into any
    variable order).  Nothing happens without a whole entry or when it is already tuned."""
    secret = None if directory is None else cache_key()
    if directory is None or secret is None or not planner.tuned:
        return
    name = key(text)
    order_path = directory / f"{name}.json"
    try:
        entry = _read_entry(order_path, secret, name)
        if entry.get("tuned"):
            return
        entry.update(order=planner.order(), tuned=True)
        entry["seal"] = seal(secret, name, entry)
        with tempfile.NamedTemporaryFile("w", dir=directory, delete=False) as tmp:
            tmp.write(json.dumps(entry))
        os.replace(tmp.name, order_path)
    except (OSError, ValueError, AttributeError):
        pass  # like saving: a read-only or damaged cache only costs the next run its time


def _save(built: TransitionPlanner, secret: bytes, directory: Path, name: str) -> None:
    order_path, bad_path = directory / f"{name}.json", directory / f"{name}.dddmp"
    specs_path = directory / f"{name}.specifications.json"
    try:
        directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=directory) as tmp:
            order_tmp, bad_tmp = Path(tmp) / "order.json", Path(tmp) / "bad.dddmp"
            specs_tmp = Path(tmp) / "specifications.json"
            built.sym.bdd.dump(str(bad_tmp), [built.bad])
            # few hundred nodes each, named (DDDMP holds one root)
            specs_tmp.write_text(json.dumps(to_data(built.bad_by_specification)))
            entry: dict[str, Any] = {
                "order": built.order(),
                "bad_sha256": hashlib.sha256(bad_tmp.read_bytes()).hexdigest(),
                "specs_sha256": hashlib.sha256(specs_tmp.read_bytes()).hexdigest(),
                "tuned": False,
            }
            entry["seal"] = seal(secret, name, entry)
            order_tmp.write_text(json.dumps(entry))
            for written in (bad_tmp, specs_tmp, order_tmp):  # CUDD's dump follows the umask
                written.chmod(0o600)
            os.replace(bad_tmp, bad_path)  # the JSON last: its presence marks a whole entry
            os.replace(specs_tmp, specs_path)
            os.replace(order_tmp, order_path)
    except (OSError, RuntimeError):
        pass  # a read-only home or a full disk only costs the next run its time
