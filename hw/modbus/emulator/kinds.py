"""The emulated Modbus devices' logic, by the kind `--device KIND:...` names (`hw.modbus.maps`)."""

from __future__ import annotations

from collections.abc import Mapping

from hw.modbus.emulator.camera import Camera
from hw.modbus.emulator.connector import Connector
from hw.modbus.emulator.logic import DeviceLogic
from hw.modbus.emulator.nutrunner import Nutrunner
from hw.modbus.emulator.tracker import Tracker

KINDS: Mapping[str, type[DeviceLogic]] = {
    "nutrunner": Nutrunner,
    "connector": Connector,
    "camera": Camera,
    "tracker": Tracker,
}
