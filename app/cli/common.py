"""What the `sp` subcommands share: usage errors, reading a model or a device file, the
planner with its cached supervisor."""

from __future__ import annotations

import argparse
import gc
from pathlib import Path
from typing import Any

from hw.device_file.spec import DeviceFile
from planner.model.flat import Model
from planner.model.station import Station


class UsageError(Exception):
    """Bad arguments or inputs other than the model: exit 2 with this message."""


def read_station(path: str, cache: bool = True) -> tuple[Station, str]:
    """The model file at `path` read (from the model cache when `cache` and read before), and
    its text."""
    from app.station import model_cache, supervisor_cache

    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{path}: cannot read the model: {exc}") from None
    directory = supervisor_cache.default_directory() if cache else None
    station = model_cache.load(text, path, directory)
    gc.freeze()  # the model lives as long as the command: no collection need walk it again
    return station, text


def planner_for(args: argparse.Namespace, model: Model, text: str, engine: str = "bdd") -> Any:
    from app.station import supervisor_cache

    directory = None if args.no_cache else supervisor_cache.default_directory()
    return supervisor_cache.planner(model, text, engine, directory)


def remember_order(args: argparse.Namespace, planner: Any, text: str) -> None:
    from app.station import supervisor_cache

    directory = None if args.no_cache else supervisor_cache.default_directory()
    supervisor_cache.remember_order(planner, text, directory)


def device_file(path: str, station: Station) -> DeviceFile:
    from app.station.emulated import read_device_file

    try:
        return read_device_file(path, station)
    except OSError as exc:
        raise UsageError(f"{path}: cannot read the device file: {exc}") from None
