"""The station's PLC: the product tracker and the logistics inputs.

Nothing here changes by itself: people (placing bolts, mounting filters) and faults change
the values through the control channel's `set`; the device only counts its heartbeat.
The states are enumerations, coded 0, 1, 2 ... in the order of the model's domains.
"""

from __future__ import annotations

from hw.modbus.emulator.logic import DeviceLogic
from hw.modbus.maps import TRACKER


class Tracker(DeviceLogic):
    register_map = TRACKER
