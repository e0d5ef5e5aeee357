"""The dashboard server (port 29999): one line in, one line out.

`answer` is the pure part: what a CB3 answers to a command, and what it does to the robot.
The answers ur_rtde's `DashboardClient` compares literally are kept exact (`Starting
program`, `Stopped`, `Pausing program`, `Protective stop releasing`, `Loading program:`).
"""

from __future__ import annotations

from collections.abc import Callable

from hw.ur.emulator.controller import Controller, RobotMode, RuntimeState, SafetyMode

GREETING = "Connected: Universal Robots Dashboard Server"
PROGRAM = "rtde_control"
SERIAL = "2018300000"


def polyscope_version(controller: Controller) -> str:
    major, minor, bugfix, build = controller.version
    return f"URSoftware {major}.{minor}.{bugfix}.{build} (Nov 17 2021)"


def answer(controller: Controller, line: str, now: float) -> str:
    """The answer to one command line (without its newline)."""
    command = line.strip()
    lowered = command.lower()
    exact = _EXACT.get(lowered)
    if exact is not None:
        return exact(controller, now)
    if lowered.startswith("load "):
        name = command[5:].strip()
        return f"Loading program: {name}"
    if lowered.startswith("popup "):
        return "showing popup"
    if lowered.startswith("addtolog "):
        return "Added log message"
    if lowered.startswith("setuserrole "):
        return f"Setting user role: {command[12:].strip()}"
    return f"could not understand: '{command}'"


def _power_on(c: Controller, now: float) -> str:
    c.power_on(now)
    return "Powering on"


def _power_off(c: Controller, now: float) -> str:
    c.power_off()
    return "Powering off"


def _brake_release(c: Controller, now: float) -> str:
    c.brake_release(now)
    return "Brake releasing"


def _unlock(c: Controller, now: float) -> str:
    if c.unlock_protective_stop():
        return "Protective stop releasing"
    return "Cannot unlock protective stop: the robot is not protectively stopped"


def _play(c: Controller, now: float) -> str:
    return "Starting program" if c.play() else "Failed to execute: play"


def _stop(c: Controller, now: float) -> str:
    c.stop_program()
    return "Stopped"


def _pause(c: Controller, now: float) -> str:
    return "Pausing program" if c.pause() else "Failed to execute: pause"


def _running(c: Controller, now: float) -> str:
    return f"Program running: {'true' if c.runtime == RuntimeState.PLAYING else 'false'}"


def _program_state(c: Controller, now: float) -> str:
    names = {RuntimeState.PLAYING: "PLAYING", RuntimeState.PAUSED: "PAUSED"}
    return f"{names.get(c.runtime, 'STOPPED')} {PROGRAM}.urp"


def _safety(prefix: str) -> Callable[[Controller, float], str]:
    def respond(c: Controller, now: float) -> str:
        name = "PROTECTIVE_STOP" if c.safety_mode == SafetyMode.PROTECTIVE_STOP else "NORMAL"
        return f"{prefix}: {name}"

    return respond


def _constant(text: str) -> Callable[[Controller, float], str]:
    return lambda c, now: text


_EXACT: dict[str, Callable[[Controller, float], str]] = {
    "power on": _power_on,
    "power off": _power_off,
    "brake release": _brake_release,
    "unlock protective stop": _unlock,
    "play": _play,
    "stop": _stop,
    "pause": _pause,
    "running": _running,
    "programstate": _program_state,
    "robotmode": lambda c, now: f"Robotmode: {RobotMode(c.robot_mode).name}",
    "safetymode": _safety("Safetymode"),
    "safetystatus": _safety("Safetystatus"),
    "polyscopeversion": lambda c, now: polyscope_version(c),
    "get robot model": _constant("UR10"),
    "get serial number": _constant(SERIAL),
    "get loaded program": lambda c, now: (
        f"Loaded program: /programs/{PROGRAM}.urp" if c.program else "No program loaded"
    ),
    "isprogramsaved": _constant(f"true {PROGRAM}.urp"),
    "is in remote control": _constant("true"),
    "close popup": _constant("closing popup"),
    "close safety popup": _constant("closing safety popup"),
    "restart safety": _constant("Restarting safety"),
    "shutdown": _power_off,
    "quit": _constant("Disconnected"),
}
