"""Reading models: YAML text in, a checked model out, every problem named at its line and column.

`load_model` and `load_station` are the entry points; `yaml_reader` is the located-error
walker under every reader, `flat` reads DESIGN.md section 8's three lists, `station` the
station form in order: its resources with their `abilities`, then the `operations` and
intentions; `parameters` is a template's parameter, `watch` a person's watch and `display`
the words for people.
"""

from __future__ import annotations

from planner.model.flat import Model
from planner.model.station import Station
from planner.reading.flat import read_flat, read_top
from planner.reading.station import STATION_KEYS, read_station


def load_station(text: str, file: str = "<model>") -> Station:
    """Parse a model file of either form; a flat model becomes a station with no extras."""
    reader, top = read_top(text, file, STATION_KEYS)
    if any(key in top for key in STATION_KEYS):
        return read_station(reader, top)
    return Station(read_flat(reader, top))


def load_model(text: str, file: str = "<model>") -> Model:
    """Parse a model file's text (flat or station form) into a checked flat `Model`.

    Raises `ModelError` listing every problem with its location.
    """
    return load_station(text, file).model
