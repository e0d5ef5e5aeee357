"""Why a UR robot that answers cannot move, from the RTDE fields it reports (issue 28).

A protective stop, an emergency stop, a robot without power or with its brakes on, or a
program that is not playing are facts of the robot, not silence: the station names them and
what a person must do, and marks the robot's resource unavailable until it can move again.
Fields as RTDE reports them (`robot_mode`, `safety_status_bits`, `runtime_state`; see
HARDWARE.md and the UR RTDE guide).
"""

from __future__ import annotations

from enum import IntEnum

from hw.ur.sample import URReading


class Safety(IntEnum):
    """Bits of `safety_status_bits`."""

    PROTECTIVE_STOPPED = 2
    SAFEGUARD_STOPPED = 4
    SYSTEM_EMERGENCY_STOPPED = 5
    ROBOT_EMERGENCY_STOPPED = 6
    EMERGENCY_STOPPED = 7
    VIOLATION = 8
    FAULT = 9


class Mode(IntEnum):
    """`robot_mode`."""

    NO_CONTROLLER = -1
    DISCONNECTED = 0
    CONFIRM_SAFETY = 1
    BOOTING = 2
    POWER_OFF = 3
    POWER_ON = 4
    IDLE = 5
    BACKDRIVE = 6
    RUNNING = 7
    UPDATING_FIRMWARE = 8


class Runtime(IntEnum):
    """`runtime_state`."""

    STOPPING = 0
    STOPPED = 1
    PLAYING = 2
    PAUSING = 3
    PAUSED = 4
    RESUMING = 5


EMERGENCY = (
    Safety.SYSTEM_EMERGENCY_STOPPED,
    Safety.ROBOT_EMERGENCY_STOPPED,
    Safety.EMERGENCY_STOPPED,
)
UNPOWERED = (
    Mode.NO_CONTROLLER,
    Mode.DISCONNECTED,
    Mode.CONFIRM_SAFETY,
    Mode.BOOTING,
    Mode.POWER_OFF,
    Mode.POWER_ON,
    Mode.UPDATING_FIRMWARE,
)


def cannot_move(robot: str, reading: URReading) -> str:
    """What a person must do before `robot` can move ("" when it can), the most urgent
    first: an emergency stop before a protective stop before power, brakes and program."""
    bits = reading.safety_bits
    pendant = f"on {robot}'s teach pendant"
    if any(bits >> bit & 1 for bit in EMERGENCY):
        return f"{robot} is emergency-stopped: release the emergency stop, then reset it {pendant}"
    if bits >> Safety.SAFEGUARD_STOPPED & 1:
        guard = "close its guard (door, light curtain)"
        return f"{robot} is safeguard-stopped: {guard}, then reset it {pendant}"
    if bits >> Safety.VIOLATION & 1 or bits >> Safety.FAULT & 1:
        return f"{robot} stopped on a safety fault: clear it {pendant}"
    if reading.protective_stop:
        return f"{robot} is in a protective stop: release it {pendant}"
    mode = reading.robot_mode
    if mode in UNPOWERED:
        return f"{robot} has no power: power it on and release its brakes {pendant}"
    if mode == Mode.IDLE:
        return f"{robot}'s brakes are on: release them {pendant}"
    if mode == Mode.BACKDRIVE:
        return f"{robot} is in backdrive (moved by hand): leave backdrive {pendant}"
    if reading.runtime_state != Runtime.PLAYING:
        # the driver uploads its control script again by itself (hw.ur.driver_child): a
        # person is needed only when that cannot work, with the robot in local control
        state = Runtime(reading.runtime_state).name.lower()
        return (
            f"{robot}'s program is {state}: the station starts it again; if it stays so, "
            f"switch {robot} to remote control {pendant}"
        )
    return ""
