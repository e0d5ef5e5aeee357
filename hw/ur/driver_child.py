"""The driver's child process: the only place where ur_rtde objects live.

ur_rtde's constructors hold the GIL while they block and its automatic reconnect can crash the
process, so `URDriver` runs this in a spawned process and restarts it when anything goes
wrong.  Life cycle: connect the dashboard; start the receive interface (so the station sees the
robot's mode during start-up); `power on`, wait for IDLE; `brake release`, wait for RUNNING;
start the control interface; report `ready`; then, until the parent says stop or a connection
is lost, execute the parent's commands on this (main) thread and stream samples (at most
`SAMPLE_RATE`, newest only) from a second thread.  A command the robot refuses (ur_rtde returns
False) is reported as an error and the process goes on.

Messages to the parent: `("phase", text)`, `("ready",)`, `("reading", dict)`, `("error",
text)`, `("fatal", text)` (then the process ends).  From the parent: `("move_j", q, speed,
acceleration)`, `("set_tool", tcp, payload_kg)`, `("stop_j",)`, `("close",)`.
"""

from __future__ import annotations

import contextlib
import ctypes
import sys
import threading
import time
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
from typing import Any

SAMPLE_RATE = 50.0
# What ur_rtde's threads are asked for; see `relaxed_timers` for why not its defaults.
RECEIVE_RATE = 50.0  # Hz of the receive interface's data (the station reads at 10 Hz)
# Hz of the control interface's handshake data: the controller's own (125, e-series 500); at
# 25 Hz a moveJ now and then took 150 ms to start, since each handshake step waits for a sample
CONTROL_RATE = -1.0
TIMER_SLACK = 0.005  # s the kernel may defer the wake-ups of ur_rtde's threads
PR_SET_TIMERSLACK, PR_GET_TIMERSLACK = 29, 30  # prctl(2)
STOP_DECELERATION = 2.0
RESUME_EVERY = 1.0
VARIABLES = [
    "timestamp",
    "actual_q",
    "actual_qd",
    "robot_mode",
    "safety_status_bits",
    "runtime_state",
]


class StartupFailed(RuntimeError):
    """The robot did not come up (a mode not reached, a client that would not connect)."""


class Link:
    """The child's end of the pipe, shared by its two threads."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self.lock = threading.Lock()

    def send(self, *message: Any) -> None:
        with self.lock:
            self.conn.send(message)


def wait_for_mode(dashboard: Any, mode: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    answer = ""
    while time.monotonic() < deadline:
        answer = str(dashboard.robotmode())
        if answer.strip().endswith(mode):
            return
        time.sleep(0.05)
    raise StartupFailed(f"robot did not reach {mode} within {timeout:.0f} s ({answer})")


@contextlib.contextmanager
def relaxed_timers(slack: float = TIMER_SLACK) -> Iterator[None]:
    """Threads started inside get a coarse timer slack (Linux; elsewhere nothing changes).

    ur_rtde's receive threads (one per RTDE connection) poll their socket with a 100 µs sleep
    between polls: about 2,700 wake-ups a second each, 2-5 % of a core per thread, whatever the
    data rate.  A thread inherits its timer slack from the thread that starts it, so the
    constructors run with `slack`: their threads then wake every few ms, which is far inside
    the station's 100 ms round.  The calling thread gets its own slack back, so that the
    commands it sends keep their handshake timing.
    """
    prctl = None
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            prctl = ctypes.CDLL(None, use_errno=True).prctl
    before = prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0) if prctl is not None else -1
    if prctl is not None and before >= 0:
        prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(round(slack * 1e9)), 0, 0, 0)
    try:
        yield
    finally:
        if prctl is not None and before >= 0:
            prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(before), 0, 0, 0)


def start_robot(host: str, link: Link, mode_timeout: float) -> tuple[Any, Any, Any]:
    """The real start-up order; returns (dashboard, receive, control)."""
    import dashboard_client
    import rtde_control
    import rtde_receive

    link.send("phase", "connecting to the dashboard")
    dashboard = dashboard_client.DashboardClient(host)
    dashboard.connect()
    link.send("phase", "starting the receive interface")
    with relaxed_timers():
        receive = rtde_receive.RTDEReceiveInterface(host, RECEIVE_RATE, VARIABLES)
    if not str(dashboard.robotmode()).endswith(("IDLE", "RUNNING")):
        link.send("phase", "powering on")
        dashboard.powerOn()
        wait_for_mode(dashboard, "IDLE", mode_timeout)
    if not str(dashboard.robotmode()).endswith("RUNNING"):
        link.send("phase", "releasing the brakes")
        dashboard.brakeRelease()
        wait_for_mode(dashboard, "RUNNING", mode_timeout)
    link.send("phase", "starting the control interface")
    with relaxed_timers():
        control = rtde_control.RTDEControlInterface(host, CONTROL_RATE)
    return dashboard, receive, control


def sample(receive: Any) -> dict[str, Any]:
    return {
        "stamp": receive.getTimestamp(),
        "q": list(receive.getActualQ()),
        "qd": list(receive.getActualQd()),
        "robot_mode": receive.getRobotMode(),
        "safety_bits": receive.getSafetyStatusBits(),
        "runtime_state": receive.getRuntimeState(),
        "sampled": time.monotonic(),
    }


def stream(receive: Any, link: Link, stop: threading.Event) -> None:
    period = 1.0 / SAMPLE_RATE
    while not stop.is_set():
        started = time.monotonic()
        try:
            link.send("reading", sample(receive))
        except (OSError, RuntimeError) as problem:
            link.send("fatal", f"reading the robot failed: {problem}")
            stop.set()
            return
        stop.wait(max(period - (time.monotonic() - started), 0.0))


def execute(control: Any, command: tuple[Any, ...]) -> str:
    """Runs one command; returns "" or why it failed."""
    name = command[0]
    if name == "move_j":
        _, q, speed, acceleration = command
        ok = control.moveJ(list(q), speed, acceleration, True)
        return "" if ok else "the robot refused moveJ (not running or protective stop)"
    if name == "set_tool":
        _, tcp, payload = command
        if not control.setTcp(list(tcp)):
            return "the robot refused set TCP"
        if not control.setPayload(payload, []):
            return "the robot refused set payload"
        return ""
    if name == "stop_j":
        control.stopJ(STOP_DECELERATION, True)
        return ""
    return f"unknown command {name!r}"


def keep_script_running(dashboard: Any, control: Any, receive: Any) -> None:
    """After someone cleared a protective stop or powered the robot back on, resume the script."""
    if receive.getRobotMode() != 7 or receive.getSafetyStatusBits() & 0b100:
        return
    state = receive.getRuntimeState()
    if state == 4:  # paused by a protective stop that has been unlocked
        dashboard.play()
    elif state == 1:  # stopped: powered off and on, or the script failed
        control.reuploadScript()


def serve(conn: Connection, dashboard: Any, receive: Any, control: Any, link: Link) -> None:
    stop = threading.Event()
    reader = threading.Thread(target=stream, args=(receive, link, stop), daemon=True)
    reader.start()
    link.send("ready")
    resumed = 0.0
    while not stop.is_set():
        if not (control.isConnected() and receive.isConnected()):
            raise ConnectionError("the connection to the robot is lost")
        if conn.poll(0.02):
            command = conn.recv()
            if command[0] == "close":
                break
            problem = execute(control, command)
            if problem:
                link.send("error", problem)
        if time.monotonic() - resumed > RESUME_EVERY:
            resumed = time.monotonic()
            keep_script_running(dashboard, control, receive)
    stop.set()


def main(host: str, conn: Connection, mode_timeout: float = 10.0) -> None:
    """The child's entry point (must be importable for the spawn start method)."""
    link = Link(conn)
    closers: list[Callable[[], Any]] = []
    try:
        dashboard, receive, control = start_robot(host, link, mode_timeout)
        closers = [control.disconnect, receive.disconnect]
        serve(conn, dashboard, receive, control, link)
    except (EOFError, BrokenPipeError):
        return  # the parent is gone
    except Exception as problem:  # any ur_rtde failure: report it, the parent restarts us
        link.send("fatal", f"{type(problem).__name__}: {problem}")
        return
    for close in closers:
        close()
