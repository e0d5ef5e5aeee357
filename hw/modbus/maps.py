"""The register maps of the Modbus devices the station knows, by kind (docs/modbus_devices.md).

A map is the device's protocol: which coil, discrete input, holding or input register holds
what, in which unit and range.  The station's driver and the device file read it; the
emulated devices (`hw.modbus.emulator.server`) serve it.
"""

from __future__ import annotations

from collections.abc import Mapping

from hw.modbus.registers import Kind, Point, Register, RegisterMap, Table, heartbeat, status_word

NUTRUNNER_STATUS_BITS = ("is_idle", "is_running", "torque_reached", "nok")

NUTRUNNER = RegisterMap(
    "nutrunner",
    "smart nutrunner: run and idle commands, tightening result, torque",
    (
        Register("set_idle", Point(Table.COIL, 0), Kind.BOOL, "command: stop and idle", True),
        Register("run_forward", Point(Table.COIL, 1), Kind.BOOL, "command: run (tighten)", False),
        Register("is_idle", Point(Table.DISCRETE_INPUT, 0), Kind.BOOL, "idle", True),
        Register("is_running", Point(Table.DISCRETE_INPUT, 1), Kind.BOOL, "spinning", False),
        Register(
            "torque_reached",
            Point(Table.DISCRETE_INPUT, 2),
            Kind.BOOL,
            "the tightening reached the target torque",
            False,
        ),
        Register(
            "nok",
            Point(Table.DISCRETE_INPUT, 3),
            Kind.BOOL,
            "the tightening ended without reaching the target torque",
            False,
        ),
        Register(
            "target_torque",
            Point(Table.HOLDING_REGISTER, 0),
            Kind.UNSIGNED,
            "torque to tighten to",
            25.0,
            scale=0.1,
            unit="Nm",
            low=0.0,
            high=100.0,
        ),
        heartbeat(),
        status_word(NUTRUNNER_STATUS_BITS, 1),
        Register(
            "torque",
            Point(Table.INPUT_REGISTER, 2),
            Kind.UNSIGNED,
            "measured torque",
            0.0,
            scale=0.1,
            unit="Nm",
            low=0.0,
            high=100.0,
        ),
    ),
)


CONNECTOR_STATUS_BITS = ("connected", "not_connected", "failure")

CONNECTOR = RegisterMap(
    "connector",
    "tool-changer connector: lock and unlock commands, connection sensors, failure",
    (
        Register("lock", Point(Table.COIL, 0), Kind.BOOL, "command: lock onto the tool", False),
        Register("unlock", Point(Table.COIL, 1), Kind.BOOL, "command: let the tool go", True),
        Register(
            "reset", Point(Table.COIL, 2), Kind.BOOL, "rising edge: clear the failure bit", False
        ),
        Register(
            "connected", Point(Table.DISCRETE_INPUT, 0), Kind.BOOL, "a tool is locked on", False
        ),
        Register(
            "not_connected", Point(Table.DISCRETE_INPUT, 1), Kind.BOOL, "no tool locked on", True
        ),
        Register(
            "failure",
            Point(Table.DISCRETE_INPUT, 2),
            Kind.BOOL,
            "a lock failed; locking is blocked until a reset",
            False,
        ),
        heartbeat(),
        status_word(CONNECTOR_STATUS_BITS, 2),
    ),
)


CAMERA_STATUS_BITS = ("located", "missed", "busy")
CAMERA_POSE = ("x", "y", "z", "rx", "ry", "rz")


def _camera_pose_registers() -> tuple[Register, ...]:
    registers = []
    for k, name in enumerate(CAMERA_POSE):
        linear = k < 3
        registers.append(
            Register(
                name,
                Point(Table.INPUT_REGISTER, 2 + k),
                Kind.SIGNED,
                f"located tool pose: {'position' if linear else 'rotation vector'} {name}",
                0.0,
                scale=0.1 if linear else 0.001,
                unit="mm" if linear else "rad",
            )
        )
    return tuple(registers)


CAMERA = RegisterMap(
    "camera",
    "3D camera: trigger, located or missed, the located tool's pose",
    (
        Register("trigger", Point(Table.COIL, 0), Kind.BOOL, "command: scan (level)", False),
        Register(
            "located", Point(Table.DISCRETE_INPUT, 0), Kind.BOOL, "the scan found the tool", False
        ),
        Register(
            "missed", Point(Table.DISCRETE_INPUT, 1), Kind.BOOL, "the scan found nothing", False
        ),
        Register("busy", Point(Table.DISCRETE_INPUT, 2), Kind.BOOL, "scanning", False),
        heartbeat(),
        status_word(CAMERA_STATUS_BITS, 0),
        *_camera_pose_registers(),
        Register(
            "scans", Point(Table.INPUT_REGISTER, 8), Kind.COUNTER, "scans finished since power-on"
        ),
    ),
)


TRACKER_BOLT_PAIR = ("empty", "placed", "tightened")
TRACKER_OIL_FILTER = ("none", "mounted", "tightened")
TRACKER_FRAME = ("on_mir", "on_engine")


def _tracker_states() -> tuple[Register, ...]:
    registers = [
        Register(
            "frame.state",
            Point(Table.INPUT_REGISTER, 1),
            Kind.ENUMERATION,
            "the ladder frame",
            "on_mir",
            codes=TRACKER_FRAME,
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
                codes=TRACKER_BOLT_PAIR,
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
                codes=TRACKER_OIL_FILTER,
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
        *_tracker_states(),
    ),
)


MAPS: Mapping[str, RegisterMap] = {
    "nutrunner": NUTRUNNER,
    "connector": CONNECTOR,
    "camera": CAMERA,
    "tracker": TRACKER,
}


def register_map(kind: str) -> RegisterMap:
    """The register map of device kind `kind` (`nutrunner`, `connector`, `camera`, `tracker`)."""
    if kind not in MAPS:
        raise KeyError(f"no Modbus device kind '{kind}'; known: {', '.join(MAPS)}")
    return MAPS[kind]
