"""The device layer on the demo's emulators: latency, the station loop's period, CPU per device.

    python -m bench.devices [--seconds 30] [--rounds 20] [--cuts 3] [--output ...devices.md]

Everything is real: the demo's device file moved to a free 127.0.N.x block, an emulator
process per device, and the station's drivers on them (`StationDevices`: ur_rtde in a child
process per robot, pymodbus clients on the shared loop).  Measured, in this order:

1. command to motion: from `StationDevices.write({"r1.ref": "scan"})` (after a first write of
   every start command, as the runner does) until the UR emulator's joints move, polled on a
   kept-open control connection from the bench's main thread, which has nothing else to do
   then (r1 and r2 in turn, home <-> scan); and from writing a coil command (r1_tc lock <->
   unlock, nr run <-> idle) until the Modbus emulator shows it;
2. measurement to runner: from asking the emulator to change (a robot jogged to a named pose,
   the PLC's bp1.state set) until `StationDevices.read()`, called every 10 ms, reports it;
   and a cut noticed: from cutting a device's network (its emulator goes silent) until its
   link says it is not connected, against the device's heartbeat time-out (the tests assert
   only that it happens and what it says: how soon depends on the machine's load);
3. the station loop: the demo's runner on the devices (`StationCycle`), planning in a
   worker process beside the loop as the live station plans
   (`app.station.planning_worker`), intention assemble_engine started and the watch
   answered after 1 s, a round every 0.1 s for `--seconds`: the period between round
   starts and each round's duration;
4. CPU over that loop's window, from /proc (utime + stime): each emulator, each ur_rtde child,
   and the station process's threads; the main thread's device calls (advance, read, write)
   by `time.thread_time()` around them.  The device layer is the station side only: the
   drivers' child processes, their threads and the device calls, not the emulators.

Prints a Markdown report and writes it to `--output` with the machine and the date.
"""

from __future__ import annotations

import argparse
import ipaddress
import itertools
import json
import math
import os
import random
import socket
import statistics
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.station.cycle import StationCycle
from app.station.emulated import EmulatedStation, emulate, start_values
from app.station.planning_worker import PlanningWorker
from bench.planning import machine
from bench.runner import revision
from hw.device_file import load_devices
from hw.device_file.spec import DeviceFile, DriverKind
from hw.devices import DeviceReport
from hw.emulator_kit.control import ControlError
from hw.faults import Fault, FaultKind
from hw.link import LinkStatus
from hw.ur import driver_child
from hw.ur.emulator.launch import free_block, on_block
from planner.model.expressions import Value
from planner.model.flat import VariableKind
from planner.model.station import Station
from planner.planning.operation_planner import OperationPlanner
from planner.planning.transition_planner import TransitionPlanner
from planner.reading import load_station
from planner.runner import Event, EventKind, Runner, RunnerConfig, StartIntention

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "demo_station.yaml"
DEVICES = ROOT / "models" / "demo_station.devices.yaml"
RESULTS = ROOT / "bench" / "results"
PERIOD = 0.1  # the station's round
READ_EVERY = 0.01  # how often the bench reads the devices while it waits for a change
LATENCY_TARGET_MS = 100.0  # under one station period
LATE_MS = 110.0  # a period longer than this is a missed one
CPU_TARGET = 20.0  # % of one core for the whole device layer (station side)
CONFIG = RunnerConfig(heartbeat_timeout=1.0, auto_intentions=frozenset())
TICKS = os.sysconf("SC_CLK_TCK")


# -- the station on its emulators ------------------------------------------------------------------


@dataclass
class Bench:
    station: Station
    devices: DeviceFile  # as the emulators serve it (the ports they bound)
    emulated: EmulatedStation
    start: dict[str, Value]


@contextmanager
def demo_station(answer_after: float = 1.0) -> Iterator[Bench]:
    """The demo station's emulators and devices, all connected; everything stopped after."""
    station = load_station(MODEL.read_text(), str(MODEL))
    # blocks 200-249: apart from the tests' (tests/hw/test_station_devices.py takes 120-199), so
    # that the benchmark's test and the tests may run at once (pytest -n)
    text = on_block(DEVICES.read_text(), free_block(range(200, 250)))
    devices = load_devices(text, "demo_station.devices.yaml", station)
    start = start_values(station, {})
    with emulate(station, devices, start, answer_after=answer_after) as emulated:
        silent = emulated.devices.wait_until_ready(30.0)
        if silent:
            raise RuntimeError(f"devices silent after 30 s: {', '.join(silent)}")
        commands = {
            v.name: start[v.name] for v in station.model.variables if v.kind is VariableKind.COMMAND
        }
        emulated.devices.write(commands)  # the first write: where the runner believes it is
        yield Bench(station, emulated.emulators.devices, emulated, start)


class ControlLink:
    """A kept-open control connection (`hw.emulator_kit.control.control` connects per request,
    too slow to poll with)."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.socket = socket.create_connection(address, timeout=2.0)
        self.file = self.socket.makefile("rb")

    def ask(self, request: dict[str, Any]) -> dict[str, Any]:
        self.socket.sendall(json.dumps(request).encode() + b"\n")
        answer = json.loads(self.file.readline() or b"null")
        if not isinstance(answer, dict) or not answer.get("ok"):
            raise ControlError(f"control request {request} refused: {answer}")
        return answer

    def close(self) -> None:
        self.file.close()
        self.socket.close()


@contextmanager
def control_links(bench: Bench, names: Sequence[str]) -> Iterator[dict[str, ControlLink]]:
    controls = bench.emulated.emulators.controls
    links: dict[str, ControlLink] = {}
    try:
        for name in names:
            links[name] = ControlLink(controls[name])
        yield links
    finally:
        for link in links.values():
            link.close()


def read_until(bench: Bench, found: Callable[[DeviceReport], bool], limit: float = 5.0) -> float:
    """Reads the devices every `READ_EVERY` s until `found(report)`; when it was found."""
    began = time.monotonic()
    next_read = began
    while True:
        now = time.monotonic()
        if found(bench.emulated.devices.read()):
            return now
        if now - began > limit:
            raise TimeoutError(f"the devices did not report it within {limit:g} s")
        next_read += READ_EVERY
        time.sleep(max(0.0, next_read - time.monotonic()))


# -- 1, 2: latencies -------------------------------------------------------------------------------


PAUSES = random.Random(2026)


def pause() -> None:
    """A random pause between samples, so that they do not lock onto a driver's poll phase
    (a fixed pause of two Modbus poll periods would wait a whole period every time)."""
    time.sleep(PAUSES.uniform(0.05, 0.15))


def measured_is(variable: str, value: Value) -> Callable[[DeviceReport], bool]:
    return lambda report: report.measured.get(variable) == value


def observed_is(variable: str, value: Value) -> Callable[[DeviceReport], bool]:
    return lambda report: report.observed.get(variable) == value


def command_to_motion(bench: Bench, rounds: int) -> list[float]:
    """Seconds from writing a robot's new ref until its emulator's joints move."""
    samples = []
    with control_links(bench, ["r1", "r2"]) as links:
        for k in range(rounds):
            robot, pose = ("r1", "r2")[k % 2], ("scan", "home")[k // 2 % 2]
            link = links[robot]
            before = link.ask({"op": "state"})["joints"]
            began = time.monotonic()
            bench.emulated.devices.write({f"{robot}.ref": pose})
            while True:
                joints = link.ask({"op": "state"})["joints"]
                now = time.monotonic()
                if any(abs(a - b) > 1e-9 for a, b in zip(joints, before, strict=True)):
                    samples.append(now - began)
                    break
                if now - began > 5.0:
                    raise TimeoutError(f"{robot} did not start moving to {pose} within 5 s")
                time.sleep(0.0005)
            read_until(bench, measured_is(f"{robot}.pos", pose))
            pause()
        for robot in ("r1", "r2"):  # back home, if an odd number of rounds left one away
            bench.emulated.devices.write({f"{robot}.ref": "home"})
            read_until(bench, measured_is(f"{robot}.pos", "home"))
    return samples


COIL_COMMANDS: dict[str, tuple[dict[str, Value], dict[str, Value], str]] = {
    # device: (command on, command off, the coil that tells them apart)
    "r1_tc": ({"r1_tc.lock": True, "r1_tc.unlock": False}, {"r1_tc.lock": False, "r1_tc.unlock": True}, "lock"),  # noqa: E501
    "nr": ({"nr.set_idle": False, "nr.run_forward": True}, {"nr.set_idle": True, "nr.run_forward": False}, "run_forward"),  # noqa: E501
}  # fmt: skip


def command_to_coil(bench: Bench, rounds: int) -> list[float]:
    """Seconds from writing a Modbus command until its emulator's coil shows it."""
    samples = []
    with control_links(bench, list(COIL_COMMANDS)) as links:
        for k in range(rounds):
            device = list(COIL_COMMANDS)[k % 2]
            on, off, coil = COIL_COMMANDS[device]
            wanted = k // 2 % 2 == 0
            state = {"op": "state", "device": device}
            began = time.monotonic()
            bench.emulated.devices.write(on if wanted else off)
            while links[device].ask(state)["values"][coil] is not wanted:
                if time.monotonic() - began > 5.0:
                    raise TimeoutError(f"{device}.{coil} did not become {wanted} within 5 s")
                time.sleep(0.0005)
            samples.append(time.monotonic() - began)
            pause()
        for _on, off, _coil in COIL_COMMANDS.values():
            bench.emulated.devices.write(off)
    return samples


def robot_to_runner(bench: Bench, rounds: int) -> list[float]:
    """Seconds from jogging a robot's emulator to a named pose until `read` reports it."""
    samples = []
    with control_links(bench, ["r1", "r2"]) as links:
        for k in range(rounds + rounds % 4):  # whole cycles: both robots end at home
            robot, pose = ("r1", "r2")[k % 2], ("scan", "home")[k // 2 % 2]
            programs = bench.devices.device(robot).programs
            assert programs is not None
            began = time.monotonic()
            links[robot].ask({"op": "jog", "joints": list(programs.poses.poses[pose])})
            seen = read_until(bench, measured_is(f"{robot}.pos", pose))
            if k < rounds:
                samples.append(seen - began)
            pause()
    return samples


def plc_to_runner(bench: Bench, rounds: int) -> list[float]:
    """Seconds from setting the PLC's bp1.state until `read` reports it (an observed state)."""
    samples = []
    with control_links(bench, ["plc"]) as links:
        for k in range(rounds + rounds % 2):  # whole cycles: bp1 ends empty
            value = ("placed", "empty")[k % 2]
            began = time.monotonic()
            links["plc"].ask({"op": "set", "device": "plc", "values": {"bp1.state": value}})
            seen = read_until(bench, observed_is("bp1.state", value))
            if k < rounds:
                samples.append(seen - began)
            pause()
    return samples


CUT = ("r1", "r2", "r1_tc", "r2_tc", "r1_cam", "r2_cam", "nr")


def cut_to_unavailable(bench: Bench, rounds: int) -> dict[str, list[float]]:
    """Per device, seconds from cutting its network until its link says it is not connected;
    each cut is mended and the link back before the next."""
    devices = bench.emulated.devices
    samples: dict[str, list[float]] = {name: [] for name in CUT}

    def wait(connected: bool, name: str, began: float) -> float:
        while devices.links()[name].connected is not connected:
            if time.monotonic() - began > 60.0:
                raise TimeoutError(f"{name} not {'back' if connected else 'cut'} within 60 s")
            time.sleep(0.005)
        return time.monotonic()

    for _ in range(rounds):
        for name in CUT:
            began = time.monotonic()
            devices.inject(Fault(FaultKind.DISCONNECT, resource=name))
            samples[name].append(wait(False, name, began) - began)
            devices.inject(Fault(FaultKind.RECONNECT, resource=name))
            wait(True, name, time.monotonic())
            pause()
    return samples


def time_out_of(bench: Bench, name: str) -> float:
    return max(d.heartbeat_timeout for d in bench.devices.devices if d.resource == name)


# -- 3, 4: the station loop, and CPU ---------------------------------------------------------------


class Metered:
    """The station's devices with the main thread's time in their calls counted."""

    def __init__(self, devices: Any) -> None:
        self.devices = devices
        self.cpu = 0.0  # thread CPU seconds in advance, read and write
        self.wall = 0.0

    @contextmanager
    def _count(self) -> Iterator[None]:
        cpu, wall = time.thread_time(), time.perf_counter()
        try:
            yield
        finally:
            self.cpu += time.thread_time() - cpu
            self.wall += time.perf_counter() - wall

    def advance(self, now: float) -> None:
        with self._count():
            self.devices.advance(now)

    def read(self) -> DeviceReport:
        with self._count():
            report: DeviceReport = self.devices.read()
            return report

    def write(self, commands: Mapping[str, Value]) -> None:
        with self._count():
            self.devices.write(commands)

    def maintenance_done(self, transition: str) -> None:
        self.devices.maintenance_done(transition)

    def perform(self, effect: str) -> bool:
        return bool(self.devices.perform(effect))

    def links(self) -> Mapping[str, LinkStatus]:
        links: Mapping[str, LinkStatus] = self.devices.links()
        return links

    def dump(self, now: float) -> dict[str, object]:
        dump: dict[str, object] = self.devices.dump(now)
        return dump

    def close(self) -> None:
        self.devices.close()

    def __getattr__(self, name: str) -> Any:
        """What the loop asks besides (kind, inject, restart, restore, for_model): uncounted."""
        return getattr(self.devices, name)


def cpu_seconds(path: str) -> float:
    """utime + stime of /proc/PID/stat or /proc/PID/task/TID/stat, in seconds (0 when gone)."""
    try:
        text = Path(path).read_text()
    except OSError:
        return 0.0
    fields = text[text.rindex(")") + 2 :].split()  # fields from the 3rd (state) on
    return (int(fields[11]) + int(fields[12])) / TICKS


def children(pid: int) -> dict[int, str]:
    """The processes whose parent is `pid`, with their command lines."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            text = (entry / "stat").read_text()
            if int(text[text.rindex(")") + 2 :].split()[1]) == pid:
                found[int(entry.name)] = (entry / "cmdline").read_bytes().replace(b"\0", b" ")
        except (OSError, ValueError):
            continue
    return {pid: cmdline.decode(errors="replace") for pid, cmdline in found.items()}


def peers(pid: int) -> set[str]:
    """The remote hosts of a process's TCP connections (to tell the robots' children apart)."""
    inodes = set()
    try:
        for fd in Path(f"/proc/{pid}/fd").iterdir():
            with_link = os.readlink(fd)
            if with_link.startswith("socket:["):
                inodes.add(with_link[8:-1])
        lines = Path(f"/proc/{pid}/net/tcp").read_text().splitlines()[1:]
    except OSError:
        return set()
    hosts = set()
    for line in lines:
        parts = line.split()
        if parts[9] in inodes:
            address = bytes.fromhex(parts[2].split(":")[0])[::-1]
            hosts.add(str(ipaddress.IPv4Address(address)))
    return hosts


@dataclass
class Usage:
    """Where CPU goes: (what, role) -> CPU seconds; and each ur_rtde child's threads."""

    seconds: dict[tuple[str, str], float] = field(default_factory=dict)
    threads: dict[str, dict[int, float]] = field(default_factory=dict)  # robot -> tid -> s


DEVICE_LAYER, RUNNER, EMULATION, TOTAL = "device layer", "runner", "emulation", "total"


def usage(bench: Bench, metered: Metered, planning_pid: int) -> Usage:
    """A snapshot of every CPU counter the report needs (`planning_pid`: the planning worker)."""
    found = Usage()
    emulators = bench.emulated.emulators.processes
    for name, process in emulators.items():
        found.seconds[(f"emulator {name}", EMULATION)] = cpu_seconds(
            f"/proc/{process.process.pid}/stat"
        )
    emulator_pids = {p.process.pid for p in emulators.values()}
    hosts = {d.host: d.name for d in bench.devices.devices if d.driver is DriverKind.UR}
    for pid, cmdline in children(os.getpid()).items():
        if pid in emulator_pids:
            continue
        if pid == planning_pid:
            found.seconds[("planning worker (process)", RUNNER)] = cpu_seconds(f"/proc/{pid}/stat")
            continue
        if "resource_tracker" in cmdline:
            what = "multiprocessing resource tracker (process)"
        elif "multiprocessing" in cmdline:
            robot = next((hosts[h] for h in peers(pid) if h in hosts), f"pid {pid}")
            what = f"ur_rtde child {robot} (process)"
            found.threads[robot] = {
                int(task.name): cpu_seconds(f"{task}/stat")
                for task in Path(f"/proc/{pid}/task").iterdir()
            }
        else:
            what = f"other child {pid}: {cmdline[:40]}"
        found.seconds[(what, DEVICE_LAYER)] = cpu_seconds(f"/proc/{pid}/stat")
    # the thread running the loop: this one (under pytest-xdist it is not the main thread)
    loop_thread = threading.get_native_id()
    for thread in threading.enumerate():
        seconds = cpu_seconds(f"/proc/self/task/{thread.native_id}/stat")
        if thread.native_id == loop_thread:
            found.seconds[("station main thread: device calls", DEVICE_LAYER)] = metered.cpu
            # /proc counts in clock ticks (10 ms), thread_time() finer: never below zero
            found.seconds[("station main thread: runner tick, the rest", RUNNER)] = max(
                seconds - metered.cpu, 0.0
            )
        elif thread.name.startswith(("ur-driver", "modbus-drivers")):
            found.seconds[(f"station thread {thread.name}", DEVICE_LAYER)] = seconds
        elif thread.name.startswith("emulated-"):
            found.seconds[(f"station thread {thread.name}", EMULATION)] = seconds
        else:
            found.seconds[(f"station thread {thread.name}", RUNNER)] = seconds
    found.seconds[("station process", TOTAL)] = cpu_seconds("/proc/self/stat")
    return found


@dataclass
class LoopResult:
    periods: list[float]
    durations: list[float]
    device_calls: list[float]
    window: float
    cpu: dict[tuple[str, str], float]  # % of one core over the window
    threads: dict[str, list[float]]  # % of one core: each ur_rtde child's threads, by start
    slowest: tuple[float, float, str]  # the longest round: when (s into the loop), ms, events
    events: dict[str, int]
    intention: str
    restarts: dict[str, int]


def summary(events: Sequence[Event]) -> str:
    """A round's events in a few words: kinds, and the planning time of its plans."""
    kinds: dict[str, int] = {}
    for event in events:
        kinds[event.kind.value] = kinds.get(event.kind.value, 0) + 1
    text = ", ".join(f"{kind} {n}" for kind, n in kinds.items()) or "no events"
    plans = [e.millis for e in events if e.kind is EventKind.PLAN and e.millis is not None]
    return text + (f"; planning {sum(plans):.0f} ms" if plans else "")


@contextmanager
def planning_worker() -> Iterator[PlanningWorker]:
    """The live station's planning process for the demo model, ready to answer."""
    worker = PlanningWorker(MODEL.read_text(), str(MODEL), None)
    try:
        deadline = time.monotonic() + 60.0
        while not worker.ready:
            if time.monotonic() > deadline:
                raise RuntimeError("the planning worker did not start within 60 s")
            worker.collect()
            time.sleep(0.05)
        yield worker
    finally:
        worker.close()


def station_loop(bench: Bench, seconds: float) -> LoopResult:
    """The demo's runner on the devices, a round every `PERIOD`, for `seconds`."""
    with planning_worker() as worker:
        return run_loop(bench, seconds, worker)


def run_loop(bench: Bench, seconds: float, worker: PlanningWorker) -> LoopResult:
    station = bench.station
    runner = Runner(
        station,
        TransitionPlanner(station.model),
        OperationPlanner(station),
        CONFIG,
        time.perf_counter,
        planning=worker,
    )
    metered = Metered(bench.emulated.devices)
    cycle = StationCycle(runner, metered, runner.initial(time.monotonic()))
    actions = [StartIntention(user="bench", name="assemble_engine")]
    starts, durations, device_calls = [], [], []
    events: dict[str, int] = {}
    intention = "not started"
    slowest = (0.0, 0.0, "")
    planning_pid = worker.process.pid or -1
    before, began = usage(bench, metered, planning_pid), time.monotonic()
    next_round, end = began, began + seconds
    while (now := time.monotonic()) < end:
        wall = metered.wall
        result = cycle.step(now, actions)
        durations.append(time.monotonic() - now)
        device_calls.append(metered.wall - wall)
        starts.append(now)
        actions = []
        for event in result.events:
            events[event.kind.value] = events.get(event.kind.value, 0) + 1
            if event.kind is EventKind.INTENTION and event.subject == "assemble_engine":
                intention = str(event.detail.get("after", "?"))
        if durations[-1] > slowest[1] / 1000.0:
            slowest = (now - began, durations[-1] * 1000.0, summary(result.events))
        next_round += PERIOD
        delay = next_round - time.monotonic()
        if delay < 0:  # as the live station does: a late round does not make the next ones early
            next_round = time.monotonic()
        time.sleep(max(0.0, delay))
    window = time.monotonic() - began
    after = usage(bench, metered, planning_pid)
    # the main thread's "rest" is a difference of counters of different resolution (10 ms
    # clock ticks against thread_time()): its change over the window may come out below zero
    cpu = {
        key: 100.0 * max(after.seconds[key] - before.seconds.get(key, 0.0), 0.0) / window
        for key in after.seconds
    }
    threads = {}
    for robot, tasks in after.threads.items():
        earlier = before.threads.get(robot, {})
        threads[robot] = [
            100.0 * (tasks[tid] - earlier.get(tid, 0.0)) / window for tid in sorted(tasks)
        ]
    restarts = {name: link.restarts for name, link in bench.emulated.devices.links().items()}
    periods = [b - a for a, b in itertools.pairwise(starts)]
    return LoopResult(
        periods,
        durations,
        device_calls,
        window,
        cpu,
        threads,
        slowest,
        events,
        intention,
        restarts,
    )


# -- the report ------------------------------------------------------------------------------------


def percentile(values: Sequence[float], share: float) -> float:
    """The nearest-rank percentile (share 0..1)."""
    ordered = sorted(values)
    return ordered[max(0, math.ceil(share * len(ordered)) - 1)]


def row(what: str, samples: Sequence[float], target: str, met: bool) -> str:
    ms = [s * 1000.0 for s in samples]
    numbers = [statistics.median(ms), percentile(ms, 0.95), percentile(ms, 0.99), max(ms)]
    cells = " | ".join(f"{n:.1f}" for n in numbers)
    return f"| {what} | {len(ms)} | {cells} | {target} | {'yes' if met else '**no**'} |"


@dataclass
class Measured:
    motion: list[float]
    coil: list[float]
    robot_read: list[float]
    plc_read: list[float]
    cut: dict[str, list[float]]  # device -> seconds until its cut was noticed
    time_outs: dict[str, float]  # device -> its heartbeat time-out
    loop: LoopResult


def measure(seconds: float, rounds: int, cuts: int = 3) -> Measured:
    with demo_station(answer_after=1.0) as bench:
        motion = command_to_motion(bench, rounds)
        coil = command_to_coil(bench, rounds)
        robot_read = robot_to_runner(bench, rounds)
        plc_read = plc_to_runner(bench, rounds)
        cut = cut_to_unavailable(bench, cuts)
        time_outs = {name: time_out_of(bench, name) for name in CUT}
        loop = station_loop(bench, seconds)
    return Measured(motion, coil, robot_read, plc_read, cut, time_outs, loop)


def cut_rows(measured: Measured) -> list[str]:
    """A cut is noticed when the driver's own time-out runs out: the heartbeat for a robot
    (its timestamp stops), the request time-out or the heartbeat for a Modbus device."""
    lines = []
    for name, samples in measured.cut.items():
        limit = measured.time_outs[name]
        slack = 0.5  # a poll period and a supervisor wake-up or two
        met = max(samples) <= limit + slack
        lines.append(row(f"cut noticed, {name}", samples, f"<= {limit:g} s + {slack:g} s", met))
    return lines


def report(measured: Measured, seconds: float, rounds: int, cuts: int = 3) -> str:
    lines = [
        f"# Device layer benchmark\n\n`python -m bench.devices --seconds {seconds:g} "
        f"--rounds {rounds} --cuts {cuts}`, {time.strftime('%Y-%m-%d')}, {revision()}. "
        f"Machine: {machine()}",
        "",
        "## Latency (emulated demo station on 127.0.N.x)",
        "",
        "| path | samples | median ms | p95 ms | p99 ms | max ms | target | met |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    target = f"< {LATENCY_TARGET_MS:.0f} ms"
    for what, samples in (
        ("command to motion, UR (`r1.ref`/`r2.ref` home <-> scan)", measured.motion),
        ("command to coil, Modbus (r1_tc lock <-> unlock, nr run <-> idle)", measured.coil),
        ("measurement to `read()`, UR (emulator jogged to a named pose)", measured.robot_read),
        ("measurement to `read()`, Modbus (PLC `bp1.state` set)", measured.plc_read),
    ):
        met = max(samples) * 1000.0 < LATENCY_TARGET_MS
        lines.append(row(what, samples, target, met))
    lines += cut_rows(measured)
    loop = measured.loop
    late = sum(1 for p in loop.periods if p * 1000.0 > LATE_MS)
    over = sum(1 for d in loop.durations if d >= PERIOD)
    lines += [
        "",
        f"## Station loop: demo runner on all devices, a round every {PERIOD * 1000:.0f} ms, "
        f"{loop.window:.0f} s",
        "",
        "| what | rounds | median ms | p95 ms | p99 ms | max ms | target | met |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
        row(
            "period between round starts",
            loop.periods,
            f"{PERIOD * 1000:.0f} ms, none over {LATE_MS:.0f} ms",
            late == 0,
        ),
        row("round (advance + read + tick + write)", loop.durations, target, over == 0),
        row("of which device calls (advance, read, write)", loop.device_calls, target, True),
        "",
        f"Periods over {LATE_MS:.0f} ms: {late} of {len(loop.periods)}; rounds of "
        f"{PERIOD * 1000:.0f} ms or more: {over}; the longest, {loop.slowest[1]:.0f} ms at "
        f"{loop.slowest[0]:.1f} s: {loop.slowest[2]}.  "
        f"Intention assemble_engine: {loop.intention}; "
        "events: " + ", ".join(f"{k} {n}" for k, n in sorted(loop.events.items())) + ".  "
        "Driver restarts: "
        + (", ".join(f"{k} {n}" for k, n in loop.restarts.items() if n) or "none")
        + ".",
        "",
        f"## CPU over the station loop's {loop.window:.0f} s (% of one core)",
        "",
        "| process or thread | counts as | CPU % |",
        "| --- | --- | --- |",
    ]
    for role in (DEVICE_LAYER, RUNNER, EMULATION):
        for (what, kind), percent in sorted(loop.cpu.items()):
            if kind == role:
                lines.append(f"| {what} | {role} | {percent:.1f} |")
    device_layer = sum(p for (_, kind), p in loop.cpu.items() if kind == DEVICE_LAYER)
    emulators = sum(p for (what, kind), p in loop.cpu.items() if what.startswith("emulator "))
    verdict = "yes" if device_layer < CPU_TARGET else "**no**"
    lines += [
        f"| **device layer, station side (all rows above marked so)** | target < "
        f"{CPU_TARGET:.0f} %: {verdict} | **{device_layer:.1f}** |",
        f"| station process, all threads | total | {loop.cpu[('station process', TOTAL)]:.1f} |",
        f"| the emulators together | emulation | {emulators:.1f} |",
        "",
        "Threads of each ur_rtde child, in the order they started (% of one core): "
        + "; ".join(
            f"{robot}: " + ", ".join(f"{p:.1f}" for p in shares)
            for robot, shares in sorted(loop.threads.items())
        )
        + ".",
    ]
    children = sum(p for (what, _), p in loop.cpu.items() if what.startswith("ur_rtde child"))
    lines += [
        "",
        "Notes.  Latencies are quantized by polling: the bench reads every "
        f"{READ_EVERY * 1000:.0f} ms, the Modbus drivers poll every 50 ms (`poll_period`), the "
        "UR driver's supervisor looks at its command queue at least every 20 ms "
        "(`hw.ur.driver.POLL`, it waits on the child's pipe), the receive interface streams at "
        f"{driver_child.RECEIVE_RATE:.0f} Hz and the emulated controller steps at 125 Hz.  "
        "Planning is in the worker process, as in the live station; the loop's rounds wait for "
        f"nothing.  Of the device layer's {device_layer:.1f} %, the ur_rtde children take "
        f"{children:.1f} %: ur_rtde's receive threads (one per RTDE connection) poll their "
        "socket with a 100 us sleep, and are started with a "
        f"{driver_child.TIMER_SLACK * 1000:.0f} ms timer slack "
        "(`hw.ur.driver_child.relaxed_timers`) so that they wake a few hundred times a second "
        "instead of thousands.",
    ]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="station loop (%(default)s)")
    parser.add_argument("--rounds", type=int, default=20, help="latency samples (%(default)s)")
    parser.add_argument("--cuts", type=int, default=3, help="cuts per device (%(default)s)")
    parser.add_argument("--output", type=Path, default=RESULTS / "devices.md", help="%(default)s")
    args = parser.parse_args()
    text = report(
        measure(args.seconds, args.rounds, args.cuts), args.seconds, args.rounds, args.cuts
    )
    print(text)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)


if __name__ == "__main__":
    main()
