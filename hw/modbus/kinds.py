"""The Modbus device kinds the station knows, by the name `--device KIND:...` uses."""

from __future__ import annotations

from collections.abc import Mapping

from hw.modbus.camera import Camera
from hw.modbus.connector import Connector
from hw.modbus.logic import DeviceLogic
from hw.modbus.nutrunner import Nutrunner
from hw.modbus.registers import RegisterMap
from hw.modbus.tracker import Tracker

KINDS: Mapping[str, type[DeviceLogic]] = {
    "nutrunner": Nutrunner,
    "connector": Connector,
    "camera": Camera,
    "tracker": Tracker,
}


def register_map(kind: str) -> RegisterMap:
    """The register map of device kind `kind` (`nutrunner`, `connector`, `camera`, `tracker`)."""
    if kind not in KINDS:
        raise KeyError(f"no Modbus device kind '{kind}'; known: {', '.join(KINDS)}")
    return KINDS[kind].register_map
