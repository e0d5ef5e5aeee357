"""What an attacker who can write the station's files (not its key files) does to them."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station


def poison_cache(directory: Path, text: str) -> None:
    """The supervisor cache's entry for the model `text` rewritten to "no forbidden states":
    its bad states replaced by none, with the checksum recomputed so that it matches."""
    empty = TransitionPlanner(load_station(text, "model.yaml").model)
    (bad_path,) = directory.glob("*.dddmp")
    bad_path.unlink()
    empty.sym.bdd.dump(str(bad_path), [empty.sym.bdd.false])
    (saved,) = [p for p in directory.glob("*.json") if not p.name.endswith(".specifications.json")]
    entry = json.loads(saved.read_text())
    entry["bad_sha256"] = hashlib.sha256(bad_path.read_bytes()).hexdigest()
    saved.write_text(json.dumps(entry))
