"""The station's PLC: the product tracker and the logistics inputs.

Nothing here changes by itself: people (placing bolts, mounting filters) and faults change
the values through the control channel's `set`; the device only counts its heartbeat.
The states are enumerations, coded 0, 1, 2 ... in the order of the model's domains.
"""

from __future__ import annotations

from hw.modbus.logic import DeviceLogic
from hw.modbus.registers import Kind, Point, Register, RegisterMap, Table, heartbeat

BOLT_PAIR = ("empty", "placed", "tightened")
OIL_FILTER = ("none", "mounted", "tightened")
FRAME = ("on_mir", "on_engine")


def _states() -> tuple[Register, ...]:
    registers = [
        Register(
            "frame.state",
            Point(Table.INPUT_REGISTER, 1),
            Kind.ENUMERATION,
            "the ladder frame",
            "on_mir",
            codes=FRAME,
        )
    ]
    for k in range(4):
        registers.append(
            Register(
                f"bp{k + 1}.state",
                Point(Table.INPUT_REGISTER, 2 + k),
                Kind.ENUMERATION,
                f"bolt pair {k + 1}",
                "empty",
                codes=BOLT_PAIR,
            )
        )
    for k in range(3):
        registers.append(
            Register(
                f"oil_filter{k + 1}.state",
                Point(Table.INPUT_REGISTER, 6 + k),
                Kind.ENUMERATION,
                f"oil filter {k + 1}",
                "none",
                codes=OIL_FILTER,
            )
        )
    return tuple(registers)


TRACKER = RegisterMap(
    "tracker",
    "station PLC: product states and logistics inputs",
    (
        Register(
            "agv.engine",
            Point(Table.DISCRETE_INPUT, 0),
            Kind.BOOL,
            "an engine on its AGV is in the station",
            True,
        ),
        Register(
            "mir.docked",
            Point(Table.DISCRETE_INPUT, 1),
            Kind.BOOL,
            "the kitting MiR is docked",
            True,
        ),
        heartbeat(),
        *_states(),
    ),
)


class Tracker(DeviceLogic):
    register_map = TRACKER
