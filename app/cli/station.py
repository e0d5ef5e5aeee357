"""The `sp` subcommands that run a station: `run` (headless, on the simulated world or
emulated devices), `serve` (the web station), `emulate` (a device file's emulators) and
`audit`."""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import logging
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from app.cli.common import UsageError, device_file, planner_for, read_station, remember_order
from app.station.model_budget import ModelBudget, ModelChecks
from planner.model.station import Station
from planner.runner import Event, EventKind, QueryObserver

if TYPE_CHECKING:
    from app.serve import Built
    from app.station.running import DeviceSetup
    from app.station.scenario import Scenario
    from hw.devices import Devices

STARTUP_TIMEOUT = 30.0  # seconds for emulated devices to answer (robots power on first)


def serve(args: argparse.Namespace) -> int:
    from app.web import http_server

    model = Path(args.model)
    if not model.exists():
        raise UsageError(f"{args.model}: no such model file")
    if args.period <= 0:
        raise UsageError("--period must be more than 0")
    if not 0 < args.speed <= 100:
        raise UsageError("--speed must be more than 0 and at most 100")
    from app.station.tampering import StoreTampered
    from app.store.keys import KeyFileError
    from app.web.server import parse_networks

    try:
        parse_networks(args.trusted_proxy)
    except ValueError as exc:
        raise UsageError(f"--trusted-proxy: {exc}") from None
    # warnings and errors on stderr, and the audit checkpoints: the station's own log
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(levelname)s %(message)s")
    logging.getLogger("app.store.checkpoints").setLevel(logging.INFO)
    say = progress_printer()
    with contextlib.ExitStack() as stack:
        devices = _serve_devices(args, model, stack)
        print(f"starting the station on http://{args.host}:{args.port} (store: {args.db})")
        try:
            built = _build(args, model, devices, say)
            budget = ModelBudget(seconds=args.model_seconds, memory=args.model_memory * 2**20)
            built.server.models = ModelChecks(budget)
        except KeyFileError as exc:
            raise UsageError(str(exc)) from None
        except StoreTampered as exc:
            print(str(exc), file=sys.stderr)
            return 3
        if built.seeded:
            print("demo users (first-login passwords; each must be changed on first sign-in):")
            for name, role, password in built.seeded:
                print(f"  {name:<10} {role:<10} {password}")
        say("starting the station loop")
        built.server.start()
        freeze_what_start_up_built()
        say(f"starting the web server on {args.host}:{args.port}")
        say_when_listening(args.host, args.port, say)
        try:
            http_server.run(built.app, args.host, args.port)
        finally:
            built.server.stop()
    return 0


def progress_printer(clock: Callable[[], float] = time.monotonic) -> Callable[[str], None]:
    """Prints each start-up step at once, with the seconds since start-up began."""
    start = clock()

    def say(line: str) -> None:
        print(f"[{clock() - start:5.1f} s] {line}", flush=True)

    return say


def say_when_listening(
    host: str, port: int, say: Callable[[str], None], seconds: float = 60.0
) -> threading.Thread:
    """Say "listening on http://host:port" once the port takes connections (uvicorn is
    quiet below warnings), from a daemon thread; nothing if it never does."""
    target = "127.0.0.1" if host in ("0.0.0.0", "") else "::1" if host == "::" else host
    shown = f"[{host}]" if ":" in host else host

    def watch() -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                socket.create_connection((target, port), timeout=0.5).close()
            except OSError:
                time.sleep(0.1)
                continue
            say(f"listening on http://{shown}:{port} (Ctrl-C to stop)")
            return

    thread = threading.Thread(target=watch, name="say-when-listening", daemon=True)
    thread.start()
    return thread


def freeze_what_start_up_built() -> None:
    """What start-up built (the model, its planners, the templates: ~150,000 objects) is never
    garbage: kept out of the collector's full collections, those take ~10 ms instead of
    60-540 ms during which the GIL is held and the station loop cannot run (found with
    `python -m bench.web_load`).  Model activation thaws and freezes again."""
    gc.collect()
    gc.freeze()


def _build(
    args: argparse.Namespace,
    model: Path,
    devices: DeviceSetup | None,
    say: Callable[[str], None] | None = None,
) -> Built:
    from app.serve import build, default_cache

    return build(
        model,
        args.db,
        cache=None if args.no_cache else default_cache(),
        period=args.period,
        speed=args.speed,
        secure_cookies=args.secure_cookies,
        devices=devices,
        keys=Path(args.keys) if args.keys else None,
        trusted_proxies=tuple(args.trusted_proxy),
        api_docs=args.api_docs,
        sequential=args.sequential,
        progress=say,
    )


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
    from app.serve import on_devices
    from app.station.emulated import start_values
    from hw.emulation.launch import launch
    from hw.emulation.world import EmulatedWorld
    from hw.emulator_kit.process import EmulatorFailed

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
    from app.station.player import Planners, play
    from app.station.scenario import Scenario, ScenarioError, load_scenario
    from planner.planning.operation_planner import OperationPlanner

    if args.devices and args.speed is not None:
        raise UsageError("--speed: emulated devices run in real time; leave it out with --devices")
    args.speed = 1.0 if args.speed is None else args.speed
    if args.speed < 0:
        raise UsageError("--speed must be 0 or more")
    station, text = read_station(args.model, cache=not args.no_cache)
    if args.scenario:
        try:
            scenario_text = Path(args.scenario).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise UsageError(f"{args.scenario}: cannot read the scenario: {exc}") from None
        try:
            scenario = load_scenario(
                scenario_text, args.scenario, station, devices=bool(args.devices)
            )
        except ScenarioError as exc:
            raise UsageError(str(exc)) from None
    else:
        scenario = Scenario(file="(none)")
    if args.sequential:
        scenario = replace(scenario, config=replace(scenario.config, sequential=True))
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
        if args.running_emulators:
            raise UsageError("--running-emulators needs --devices FILE")
        return None
    from app.station.emulated import attach_to, emulate, start_values
    from app.station.scenario import person_delay_of
    from hw.emulator_kit.control import ControlError
    from hw.emulator_kit.process import EmulatorFailed

    devices = device_file(args.devices, station)
    start = start_values(station, scenario.start)
    answer_after = person_delay_of(scenario, station)
    if args.running_emulators:
        try:
            emulated = attach_to(station, devices, start, answer_after=answer_after)
        except (EmulatorFailed, ControlError) as exc:
            raise UsageError(
                f"{args.devices}: no running emulators to use ({exc}); start them with "
                f"'sp emulate {args.devices}' or leave out --running-emulators"
            ) from None
    else:
        try:
            emulated = emulate(station, devices, start, answer_after=answer_after)
        except EmulatorFailed as exc:
            raise UsageError(
                f"{args.devices}: the emulators did not start: {exc} (if they already "
                "serve, from 'sp emulate', add --running-emulators)"
            ) from None
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
    """`sp audit verify`: exit 0 when intact, 1 when not (or not checkable), 2 when the store
    cannot be read; the findings in plain words, never a traceback."""
    from sqlalchemy.exc import SQLAlchemyError

    from app.store.db import open_store
    from app.store.keys import KeyFileError, default_key_path, read_keys
    from app.store.verification import describe, verify

    try:
        path = Path(args.keys) if args.keys else default_key_path(args.db)
        keys = read_keys(path) if path is not None and path.exists() else None
        store = open_store(args.db)
        try:
            report = verify(store, keys)
        finally:
            store.close()
    except KeyFileError as exc:
        print(f"cannot verify: {exc}")
        return 2
    except (SQLAlchemyError, OSError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"cannot verify: the store at {args.db} cannot be read ({reason})")
        return 2
    if keys is None and path is not None:
        report.notes.append(f"there is no key file at {path}")
    for line in describe(report, keys.path if keys is not None else None):
        print(line)
    return 0 if report.intact else 1


def store(args: argparse.Namespace) -> int:
    """`sp store accept`: exit 0 when accepted (or nothing to accept), 2 when it cannot be."""
    from sqlalchemy import select
    from sqlalchemy.exc import SQLAlchemyError

    from app.store.acceptance import accept
    from app.store.db import open_store
    from app.store.keys import KeyFileError, default_key_path, read_keys
    from app.store.tables import StationRecord

    try:
        path = Path(args.keys) if args.keys else default_key_path(args.db)
        if path is None:
            raise KeyFileError("an in-memory store has no key file")
        keys = read_keys(path)
        opened = open_store(args.db)
        opened.keys = keys
        try:
            station = args.station
            if not station:
                with opened.sessions() as session:
                    names = list(session.scalars(select(StationRecord.name)))
                if len(names) != 1:
                    raise ValueError(f"the store holds {len(names)} stations: name one (--station)")
                station = names[0]
            accepted = accept(opened, station, args.by, args.why)
        finally:
            opened.close()
    except KeyFileError as exc:
        print(f"cannot accept: {exc}")
        return 2
    except (SQLAlchemyError, OSError, ValueError, TypeError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"cannot accept: {reason}")
        return 2
    if not accepted.problems:
        print("nothing to accept: every sealed row is as the station wrote it")
        return 0
    for problem in accepted.problems:
        print(f"accepted: {problem}")
    print(f"{len(accepted.problems)} row(s) sealed again as they are, by {args.by}; audited")
    return 0


def emulate(args: argparse.Namespace) -> int:
    """`sp emulate FILE`: the device file's emulators on its addresses, until Ctrl-C; point a
    station at them with `sp serve --devices FILE`."""
    from app.station.emulated import start_values
    from hw.emulation.launch import launch
    from hw.emulator_kit.process import EmulatorFailed

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
