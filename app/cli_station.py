"""The `sp` subcommands that run a station: `run` (headless, on the simulated world or
emulated devices), `serve` (the web station), `emulate` (a device file's emulators) and
`audit`."""

from __future__ import annotations

import argparse
import contextlib
import json
import time
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from app.cli_common import UsageError, device_file, planner_for, read_station, remember_order
from planner.runner import Event, EventKind
from planner.runner.queries import QueryObserver
from planner.station import Station

if TYPE_CHECKING:
    from app.live_station import DeviceSetup
    from app.scenario import Scenario
    from hw.devices import Devices

STARTUP_TIMEOUT = 30.0  # seconds for emulated devices to answer (robots power on first)


def serve(args: argparse.Namespace) -> int:
    import uvicorn

    from app.serve import build, default_cache

    model = Path(args.model)
    if not model.exists():
        raise UsageError(f"{args.model}: no such model file")
    if args.period <= 0:
        raise UsageError("--period must be more than 0")
    if not 0 < args.speed <= 100:
        raise UsageError("--speed must be more than 0 and at most 100")
    with contextlib.ExitStack() as stack:
        devices = _serve_devices(args, model, stack)
        print(f"starting the station on http://{args.host}:{args.port} (store: {args.db})")
        built = build(
            model,
            args.db,
            cache=None if args.no_cache else default_cache(),
            period=args.period,
            speed=args.speed,
            secure_cookies=args.secure_cookies,
            devices=devices,
            simulated=devices is None or args.emulate,  # the simulation panel acts on emulators
        )
        if built.seeded:
            print("demo users (first-login passwords; each must be changed on first sign-in):")
            for name, role, password in built.seeded:
                print(f"  {name:<10} {role:<10} {password}")
        built.server.live.start()
        try:
            uvicorn.run(built.app, host=args.host, port=args.port, log_level="warning")
        finally:
            built.server.live.stop()
    return 0


def _serve_devices(
    args: argparse.Namespace, model: Path, stack: contextlib.ExitStack
) -> DeviceSetup | None:
    """`--devices FILE [--emulate]`: the station's devices (and their emulators)."""
    if args.emulate and not args.devices:
        raise UsageError("--emulate needs --devices FILE")
    if not args.devices:
        return None
    if args.speed != 1.0:
        raise UsageError("devices run in real time: leave out --speed")
    from app.emulated_station import start_values
    from app.serve import on_devices
    from hw.emulation.launch import launch
    from hw.emulation.process import EmulatorFailed
    from hw.emulation.world import EmulatedWorld

    station, _ = read_station(str(model))
    devices = device_file(args.devices, station)
    if not args.emulate:
        return on_devices(devices)
    print(f"starting the emulators of {args.devices}", flush=True)
    try:
        emulators = stack.enter_context(launch(devices, start_values(station, {})))
    except EmulatorFailed as exc:
        raise UsageError(f"{args.devices}: the emulators did not start: {exc}") from None
    world = EmulatedWorld(emulators.devices, emulators.controls, station)
    stack.callback(world.close)
    for name, process in sorted(emulators.processes.items()):
        print(f"  {name:<16} pid {process.process.pid}")
    return on_devices(emulators.devices, world)


def run(args: argparse.Namespace, observer: QueryObserver | None = None) -> int:
    from app.scenario import Planners, Scenario, ScenarioError, load_scenario, play
    from planner.operation_planner import OperationPlanner

    if args.speed < 0:
        raise UsageError("--speed must be 0 or more")
    station, text = read_station(args.model)
    if args.scenario:
        try:
            scenario_text = Path(args.scenario).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise UsageError(f"{args.scenario}: cannot read the scenario: {exc}") from None
        try:
            scenario = load_scenario(scenario_text, args.scenario, station)
        except ScenarioError as exc:
            raise UsageError(str(exc)) from None
    else:
        scenario = Scenario(file="(none)")
    planners = Planners(planner_for(args, station.model, text), OperationPlanner(station))
    planners.transition.prepare()  # before the clock starts, as a station does while it builds
    with contextlib.ExitStack() as stack:
        devices = _emulated(args, station, scenario, stack)
        playing = play(
            station,
            scenario,
            planners,
            speed=args.speed,
            stopwatch=time.perf_counter,
            observer=observer,
            devices=devices,
            clock=time.monotonic if devices is not None else None,
        )
        finished = _print_events(args, playing)
    remember_order(args, planners.transition, text)
    return 0 if finished else 1


def _emulated(
    args: argparse.Namespace, station: Station, scenario: Scenario, stack: contextlib.ExitStack
) -> Devices | None:
    """`--devices FILE`: the emulators of the device file, and the station's devices on them."""
    if not args.devices:
        return None
    from app.emulated_station import emulate, start_values
    from app.scenario import person_delay_of
    from hw.emulation.process import EmulatorFailed

    devices = device_file(args.devices, station)
    start = start_values(station, scenario.start)
    try:
        emulated = emulate(station, devices, start, answer_after=person_delay_of(scenario, station))
    except EmulatorFailed as exc:
        raise UsageError(f"{args.devices}: the emulators did not start: {exc}") from None
    stack.enter_context(emulated)
    silent = emulated.devices.wait_until_ready(STARTUP_TIMEOUT)
    if silent:
        raise UsageError(f"{args.devices}: no answer from {', '.join(silent)}")
    return emulated.devices


def _print_events(args: argparse.Namespace, playing: Iterable[Event]) -> bool:
    finished = False
    for event in playing:
        if args.quiet and event.kind in (EventKind.EFFECT, EventKind.TAKEN):
            continue
        print(json.dumps(event.as_json(), default=str) if args.json else event, flush=True)
        finished = event.kind is EventKind.DONE
    return finished


def audit(args: argparse.Namespace) -> int:
    from app.serve import audit_verify
    from app.store.db import open_store

    store = open_store(args.db)
    count, problems, head = audit_verify(store)
    for problem in problems:
        print(f"tampered: {problem}")
    if problems:
        print(f"audit log BROKEN: {len(problems)} problem(s) in {count} records")
        return 1
    print(f"audit log intact: {count} records, newest hash {head}")
    return 0


def emulate(args: argparse.Namespace) -> int:
    """`sp emulate FILE`: the device file's emulators on its addresses, until Ctrl-C; point a
    station at them with `sp serve --devices FILE`."""
    from app.emulated_station import start_values
    from hw.emulation.launch import launch
    from hw.emulation.process import EmulatorFailed

    station, _ = read_station(args.model)
    devices = device_file(args.devices, station)
    try:
        emulators = launch(devices, start_values(station, {}))
    except EmulatorFailed as exc:
        raise UsageError(f"{args.devices}: the emulators did not start: {exc}") from None
    with emulators:
        print(f"{'device':<16} {'address':<22} control", flush=True)
        for device in emulators.devices.devices:
            if device.name in emulators.controls:
                address = f"{device.host}:{device.port}" if device.port else device.host
                host, port = emulators.controls[device.name]
                print(f"{device.name:<16} {address:<22} {host}:{port}", flush=True)
        print("emulating; Ctrl-C to stop", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            while all(p.alive for p in emulators.processes.values()):
                time.sleep(0.5)
    stopped = [n for n, p in emulators.processes.items() if not p.alive]
    return 0 if len(stopped) == len(emulators.processes) else 1
